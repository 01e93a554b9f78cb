"""Fuzz the real CLI with malformed inputs and absurd flags: no traceback, no hang, no numpy warning.

A fixed-seed corpus (about 220 cases) of hand-picked malformations in every category of issue 14 plus
random mutations (byte flips, truncations, extreme tokens) of valid CSV, NPY, OBJ, OFF, PLY, STL, XYZ and
result.json files. Each case runs the CLI's ``main`` in a process of its own with a timeout, in its own
directory (forked from one that has imported gsr_cad: ``cli_subprocess.gsr_forked``; the other tests here run
``python -m gsr_cad`` itself). Bad input must give exit 2 with exactly one ``error:`` line; inputs that may be
fine (random mutations) must either succeed with nothing but ``warning:`` lines on stderr, or fail that same
clean way.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import stat
import struct
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from cli_subprocess import TINY_CURVE, TINY_SURFACE, assert_clean, assert_clean_error, gsr, gsr_as_nobody, gsr_forked

from gsr_cad.reconstruct.meshio import obj_text
from gsr_cad.reconstruct.samples import get_sample

SEED = 20261201
ERROR, ANY, OK = "error", "any", "ok"

# --- valid seeds of the mutations -----------------------------------------------------------------------------


def _curve_csv() -> str:
    t = np.linspace(0, 3, 40)
    return "x,y\n" + "".join(f"{a:.6g},{b:.6g}\n" for a, b in zip(t, np.sin(t)))


def _cube_obj() -> str:
    return obj_text(get_sample("extended").target)


def _cube_cloud() -> np.ndarray:
    return np.asarray(get_sample("extended").target.vertices, dtype=float)


def _ascii_ply(vertices: np.ndarray, faces: list[list[int]]) -> str:
    head = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}", "property float x", "property float y",
            "property float z", f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    return "\n".join(head + [" ".join(map(str, v)) for v in vertices.tolist()]
                     + [f"{len(f)} " + " ".join(map(str, f)) for f in faces]) + "\n"


def _tetra() -> tuple[np.ndarray, list[list[int]]]:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    return v, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def _off(v: np.ndarray, faces: list[list[int]]) -> str:
    return "OFF\n" + f"{len(v)} {len(faces)} 0\n" + "".join(" ".join(map(str, r)) + "\n" for r in v.tolist()) + \
        "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces)


def _obj(v: np.ndarray, faces: list[list[int]]) -> str:
    return "".join("v " + " ".join(map(str, r)) + "\n" for r in v.tolist()) + \
        "".join("f " + " ".join(str(i + 1) for i in f) + "\n" for f in faces)


def _binary_ply(v: np.ndarray, faces: list[list[int]], scalar_index: bool = False, count_type: str = "B") -> bytes:
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(faces)}\n")
    head += ("property int vertex_indices\n" if scalar_index else
             f"property list {'uchar' if count_type == 'B' else 'char'} int vertex_indices\n")
    body = b"".join(struct.pack("<3f", *r) for r in v.tolist())
    for f in faces:
        body += struct.pack("<i", f[0]) if scalar_index else struct.pack("<" + count_type, len(f)) + \
            struct.pack(f"<{len(f)}i", *f)
    return (head + "end_header\n").encode() + body


def _stl(v: np.ndarray, faces: list[list[int]]) -> bytes:
    body = b"".join(struct.pack("<12fH", 0, 0, 0, *v[f[0]], *v[f[1]], *v[f[2]], 0) for f in faces)
    return b"\0" * 80 + struct.pack("<I", len(faces)) + body


def _npy(array: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=True)
    return buf.getvalue()


def _npy_header(shape: tuple, descr: str = "<f8") -> bytes:
    header = repr({"descr": descr, "fortran_order": False, "shape": shape}).encode()
    header += b" " * (63 - (len(header) + 10) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header


def _result_json() -> dict:
    return {"kind": "curve", "version": 1, "config": {"scheme": "bspline"}, "seed": 1, "genome": [],
            "control_points": [[0, 0], [1, 1], [2, 0], [3, 1]], "metrics": {}, "history": []}


# --- the corpus -----------------------------------------------------------------------------------------------

Writer = Callable[[Path], list]
CASES: list[tuple[str, str, Writer]] = []


def case(name: str, expect: str = ERROR):
    def register(fn: Writer) -> Writer:
        CASES.append((name, expect, fn))
        return fn

    return register


def _file(d: Path, name: str, data: str | bytes) -> Path:
    p = d / name
    p.write_bytes(data.encode() if isinstance(data, str) else data)
    return p


def curve_file(name: str, data: str | bytes, expect: str = ERROR, extra: tuple = ()) -> None:
    case(f"curve-{name}", expect)(lambda d: ["curve", _file(d, name, data), "-o", d / "out", *TINY_CURVE, *extra])


def surface_file(name: str, data: str | bytes, expect: str = ERROR, extra: tuple = ()) -> None:
    case(f"surface-{name}", expect)(lambda d: ["surface", _file(d, name, data), "-o", d / "out", *TINY_SURFACE,
                                                *extra])


def flag_case(kind: str, flags: tuple, expect: str = ERROR) -> None:
    def write(d: Path) -> list:
        if kind == "curve":
            return ["curve", _file(d, "c.csv", _curve_csv()), "-o", d / "out", *TINY_CURVE, *flags]
        return ["surface", _file(d, "t.obj", _cube_obj()), "-o", d / "out", *TINY_SURFACE, *flags]

    case(f"{kind}-flags{''.join(flags)}", expect)(write)


# curves: text tables
curve_file("empty.csv", "")
curve_file("header-only.csv", "x,y\n")
curve_file("one-column.csv", "1\n2\n3\n4\n5\n")
curve_file("three-points.csv", "0,0\n1,1\n2,0\n")
curve_file("ragged.csv", "0,0\n1,1,1\n2,0\n3,3\n")
curve_file("nan.csv", "0,0\n1,nan\n2,0\n3,1\n")
curve_file("inf.csv", "0,0\n1,1e400\n2,0\n3,1\n")
curve_file("huge-coords.csv", "".join(f"{i}e200,{(-1) ** i}e200\n" for i in range(1, 30)))
curve_file("tiny-extent.csv", "".join(f"{i}e-300,{(-1) ** i}e-300\n" for i in range(1, 30)))
curve_file("equal.csv", "1,1\n" * 10)
curve_file("duplicates.csv", "0,0\n1,1\n1,1\n2,0\n3,1\n")
curve_file("text.csv", "0,0\n1,one\n2,0\n3,1\n")
curve_file("complex.csv", "0,0\n1,1+2j\n2,0\n3,1\n")
curve_file("binary.csv", bytes(range(256)) * 8)
curve_file("latin1.csv", "0,0\n1,1\n2,\xe9\n".encode("latin-1"))
curve_file("long-int.csv", "0," + "9" * 5000 + "\n1,1\n2,0\n3,1\n")
curve_file("4d.csv", "0,0,0,0\n1,1,1,1\n2,0,0,0\n3,1,1,1\n")
curve_file("bom.csv", "\ufeff" + _curve_csv(), OK)
curve_file("wrong.suffix", _curve_csv())
curve_file("npy-complex.npy", _npy(np.ones((10, 2), dtype=complex)))
curve_file("npy-object.npy", _npy(np.array([[1, "a"]] * 5, dtype=object)))
curve_file("npy-bool.npy", _npy(np.ones((10, 2), dtype=bool)))
curve_file("npy-str.npy", _npy(np.array([["1", "2"]] * 5)))
curve_file("npy-3d.npy", _npy(np.ones((3, 4, 2))))
curve_file("npy-1d.npy", _npy(np.ones(10)))
curve_file("npy-huge-header.npy", _npy_header((10**11, 2)) + b"\0" * 64)
curve_file("npy-truncated.npy", _npy(np.random.default_rng(0).random((100, 2)))[:-50])
curve_file("npy-bad-magic.npy", b"\x93NUMPX" + b"\0" * 100)
curve_file("npy-bad-header.npy", b"\x93NUMPY\x01\x00\x10\x00{'descr': oops}\n" + b"\0" * 64)
curve_file("npy-structured.npy", _npy(np.zeros(5, dtype=[("x", "f8"), ("y", "f8")])))
curve_file("npy-nan.npy", _npy(np.array([[0, 0], [1, np.nan], [2, 0], [3, 1.0]])))
curve_file("npy-int.npy", _npy(np.array([[0, 0], [1, 3], [2, 0], [3, 1], [4, 5], [5, 2]])), OK)

# surfaces: clouds and meshes
V, F = _tetra()
BIG = "99999999999999999999999"
surface_file("flat.xyz", "".join(f"{i} {j} 0\n" for i in range(5) for j in range(5)))
surface_file("line.xyz", "".join(f"{i} {i} {i}\n" for i in range(10)))
surface_file("2d.xyz", "0 0\n1 1\n2 0\n3 1\n")
surface_file("nan.xyz", "0 0 0\n1 nan 0\n0 1 0\n0 0 1\n1 1 1\n")
surface_file("huge.xyz", "".join(f"{x}e200 {y}e200 {z}e200\n" for x, y, z in np.random.default_rng(1).random((30, 3))))
surface_file("cloud-complex.npy", _npy(np.ones((10, 3), dtype=complex)))
surface_file("cloud-huge-header.npy", _npy_header((10**11, 3)) + b"\0" * 64)
surface_file("cloud-bom.xyz", "\ufeff" + "".join(f"{x} {y} {z}\n" for x, y, z in _cube_cloud()), OK)
surface_file("index-int64.obj", _obj(V, F[:3]) + f"f 1 2 {BIG}\n")
surface_file("index-range.obj", _obj(V, F[:3]) + "f 1 2 9\n")
surface_file("index-zero.obj", _obj(V, F[:3]) + "f 0 1 2\n")
surface_file("index-negative.obj", _obj(V, F[:3]) + "f -1 -2 -9\n")
surface_file("index-text.obj", _obj(V, F[:3]) + "f 1 2 x\n")
surface_file("vertex-text.obj", "v 0 0 zero\n" + _obj(V, F)[0:])
surface_file("two-coords.obj", "v 0 0\n" + _obj(V, F))
surface_file("index-int64.off", _off(V, F[:3] + [[0, 1, BIG]]))
surface_file("counts-negative.off", "OFF\n-4 -4 0\n")
surface_file("counts-huge.off", f"OFF\n{BIG} 4 0\n0 0 0\n")
surface_file("no-header.off", "4 4 0\n" + _off(V, F)[4:])
surface_file("truncated.off", _off(V, F)[:-12])
surface_file("ply-scalar-index.ply", _binary_ply(V, F, scalar_index=True))
surface_file("ply-truncated.ply", _binary_ply(V, F)[:-7])
surface_file("ply-negative-count.ply", _binary_ply(V, [[0, 2, 1]] * 0 + F[:1], count_type="b")[:-13]
             + struct.pack("<b", -3) + struct.pack("<3i", 0, 2, 1))
surface_file("ply-ascii-truncated.ply", _ascii_ply(V, F)[:-10])
surface_file("ply-cloud-truncated.ply", _ascii_ply(_cube_cloud(), [])[:-40])
surface_file("ply-huge-count.ply", _ascii_ply(V, F).replace("element vertex 4", f"element vertex {BIG}"))
surface_file("ply-bad-type.ply", _ascii_ply(V, F).replace("property float x", "property quad x"))
surface_file("ply-no-header.ply", "plx\n0 0 0\n")
surface_file("ply-format.ply", _ascii_ply(V, F).replace("ascii", "binary_middle_endian"))
surface_file("ply-index-int64.ply", _ascii_ply(V, F[:3]) .replace("element face 3", "element face 4") + f"3 0 1 {BIG}\n")
surface_file("stl-truncated.stl", _stl(V, F)[:-20])
surface_file("stl-garbage.stl", b"solid x\n" + bytes(range(256)) * 4)
surface_file("stl-zero-area.stl", _stl(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 1.0]]), [[0, 1, 2]] * 4))
surface_file("nonmanifold.obj", _obj(np.vstack([V, [[1, 1, 1]]]), F + [[1, 2, 4]]))
surface_file("flipped.obj", _obj(V, [F[0][::-1]] + F[1:]))
surface_file("zero-area.obj", _obj(np.vstack([V, [[0.5, 0.5, 0]]]), F + [[1, 2, 4]]), ANY)
surface_file("mesh.unknown", _cube_obj())
surface_file("duplicate-face.obj", _obj(V, F + [F[0]]))
surface_file("stray-vertex.obj", _obj(np.vstack([V, [[50.0, 50.0, 50.0]]]), F), OK)
surface_file("index-float.obj", _obj(V, F[:3]) + "f 1 2 1e3\n")
surface_file("random.xyz", "".join(f"{x} {y} {z}\n" for x, y, z in np.random.default_rng(4).random((200, 3))), OK)
# extreme scales: a result holds coordinates up to 1e12, so the data may not come near it; tiny ones are fine
surface_file("scale-9e8.xyz", "".join(f"{x} {y} {z}\n" for x, y, z in 9e8 * _cube_cloud() / np.abs(_cube_cloud()).max()),
             OK)
surface_file("scale-1e40.xyz", "".join(f"{x}e40 {y}e40 {z}e40\n" for x, y, z in _cube_cloud()))
curve_file("scale-9e8.csv", "".join(f"{9e8 + i * 1e6},{9e8 + 1e6 * (i % 3)}\n" for i in range(20)), OK,
           ("--bounds-margin", "100"))
curve_file("scale-2e9.csv", "".join(f"{2e9 + i * 1e6},{2e9 + 1e6 * (i % 3)}\n" for i in range(20)))
curve_file("scale-1e-40.csv", "".join(f"{i}e-40,{i % 3}e-40\n" for i in range(20)), OK)

# flags
for flags in (("--tolerance", "1e300"), ("--tolerance", "nan"), ("--max-distance", "-1"), ("--population", "1e8"),
              ("--min-ops", "1000000"), ("--population", "1.5"), ("--generations", "0"), ("--seed", "-1"),
              ("--seed", "1e30"), ("--max-seconds", "inf"), ("--max-seconds", "1e300"), ("--fit-iterations", "1e9"),
              ("--bounds-margin", "1e308"), ("--move-scale", "1e300"), ("--initial-population", "99999999"),
              ("--max-control-points", "2"), ("--formats", "nosuch"), ("--preset", "nosuch")):
    flag_case("curve", flags)
for flags in (("--move-range", "1e300"), ("--extrude-range", "1e308"), ("--levels", "1000000"),
              ("--population", "100000000"), ("--min-ops", "1000000"), ("--face-move-range", "inf"),
              ("--max-target-points", "1e12"), ("--workers", "0"), ("--workers", "100000"),
              ("--template", "/dev/zero"), ("--template", "."), ("--op-kinds", "XYZ"), ("--threshold", "1e300")):
    flag_case("surface", flags)


@case("out-empty")
def _(d):
    return ["curve", _file(d, "c.csv", _curve_csv()), "-o", "", *TINY_CURVE]


@case("out-is-file")
def _(d):
    return ["curve", _file(d, "c.csv", _curve_csv()), "-o", _file(d, "f", "x"), *TINY_CURVE]


@case("out-result-json-is-dir")
def _(d):
    (d / "out" / "result.json").mkdir(parents=True)
    return ["curve", _file(d, "c.csv", _curve_csv()), "-o", d / "out", *TINY_CURVE]


@case("out-result-json-is-fifo", ANY)
def _(d):
    (d / "out").mkdir()
    os.mkfifo(d / "out" / "result.json")
    return ["curve", _file(d, "c.csv", _curve_csv()), "-o", d / "out", *TINY_CURVE]


for kind in ("surface", "replay", "batch", "subdivide"):
    @case(f"{kind}-out-empty")
    def _(d, kind=kind):
        src = {"surface": ("t.obj", _cube_obj()), "subdivide": ("t.obj", _cube_obj()),
               "replay": ("result.json", json.dumps(_result_json())), "batch": ("c.csv", _curve_csv())}[kind]
        extra = {"surface": TINY_SURFACE, "batch": ("--workers", "1")}.get(kind, ())
        return [kind, _file(d, *src), "-o", "", *extra]


for flag in ("--truth", "--clean"):
    @case(f"sample{flag}-is-dir")
    def _(d, flag=flag):
        (d / "exists").mkdir()
        return ["sample", "bspline_05", "-o", d / "c.csv", flag, d / "exists"]


@case("sample-cloud-empty")
def _(d):
    return ["sample", "extended", "-o", d / "t.obj", "--cloud", ""]


@case("surface-template-fifo")
def _(d):
    os.mkfifo(d / "pipe.obj")
    return ["surface", _file(d, "t.obj", _cube_obj()), "-o", d / "out", "--template", d / "pipe.obj", *TINY_SURFACE]


@case("curve-checkpoint-fifo")
def _(d):
    os.mkfifo(d / "pipe.ckpt")
    return ["curve", _file(d, "c.csv", _curve_csv()), "-o", d / "out", "--checkpoint", d / "pipe.ckpt", *TINY_CURVE]


@case("resume-run-json-fifo")
def _(d):
    os.mkfifo(d / "run.json")
    return ["resume", d]


@case("batch-workers-absurd")
def _(d):
    return ["batch", _file(d, "c.csv", _curve_csv()), "-o", d / "out", "--workers", "1e9"]


@case("tex-name", OK)
def _(d):
    return ["curve", _file(d, "$\\x$_^{a}.csv", _curve_csv()), "-o", d / "out", *TINY_CURVE]


@case("tex-name-surface", OK)
def _(d):
    return ["surface", _file(d, "$\\frac{a$.obj", _cube_obj()), "-o", d / "out", *TINY_SURFACE]


for special in ("/dev/zero", "/dev/null", "."):
    case(f"curve-special-{special}")(lambda d, s=special: ["curve", s, "-o", d / "out", *TINY_CURVE])
    case(f"surface-special-{special}")(lambda d, s=special: ["surface", s, "-o", d / "out", *TINY_SURFACE])
    case(f"replay-special-{special}")(lambda d, s=special: ["replay", s, "-o", d / "out"])


@case("curve-sparse-2GiB")
def _(d):
    with open(d / "big.csv", "wb") as fh:
        fh.truncate(2 << 30)  # sparse: costs no disk
    return ["curve", d / "big.csv", "-o", d / "out", *TINY_CURVE]


@case("curve-offset-rounding")
def _(d):
    return ["curve", _file(d, "o.csv", "".join(f"{1e15 + i * 1e-4},{1e15 - i * 1e-4}\n" for i in range(20))), "-o",
            d / "out", *TINY_CURVE]


for ck in ("", ".", "/dev/zero", "nodir/x.ckpt", "garbage.ckpt"):
    @case(f"curve-checkpoint-{ck or 'empty'}")
    def _(d, ck=ck):
        if ck == "garbage.ckpt":
            _file(d, ck, b"\x80\x04garbage")
        return ["curve", _file(d, "c.csv", _curve_csv()), "-o", d / "out", "--checkpoint", ck, *TINY_CURVE]


@case("curve-symlink-loop")
def _(d):
    os.symlink(d / "loop.csv", d / "loop.csv")
    return ["curve", d / "loop.csv", "-o", d / "out", *TINY_CURVE]


@case("curve-name-too-long")
def _(d):
    return ["curve", "x" * 5000 + ".csv", "-o", d / "out", *TINY_CURVE]


@case("curve-fifo")
def _(d):
    os.mkfifo(d / "pipe.csv")
    return ["curve", d / "pipe.csv", "-o", d / "out", *TINY_CURVE]


@case("replay-fifo")
def _(d):
    os.mkfifo(d / "result.json")
    return ["replay", d / "result.json", "-o", d / "out"]


@case("sample-out-dir")
def _(d):
    (d / "exists").mkdir()
    return ["sample", "bspline_05", "-o", d / "exists"]


@case("sample-out-empty")
def _(d):
    return ["sample", "bspline_05", "-o", ""]


@case("subdivide-levels")
def _(d):
    return ["subdivide", _file(d, "t.obj", _cube_obj()), "-o", d / "o.obj", "--levels", "1000000"]


@case("subdivide-out-dir")
def _(d):
    (d / "o.obj").mkdir()
    return ["subdivide", _file(d, "t.obj", _cube_obj()), "-o", d / "o.obj"]


@case("resume-nothing")
def _(d):
    return ["resume", d]


@case("resume-bad-run-json")
def _(d):
    _file(d, "run.json", '{"command": "curve", "checkpoint": "x", "bogus": 1}')
    return ["resume", d]


@case("batch-missing-input")
def _(d):
    return ["batch", d / "missing.csv", "-o", d / "out"]


@case("batch-bad-set")
def _(d):
    return ["batch", _file(d, "c.csv", _curve_csv()), "-o", d / "out", "--set", "nonsense"]


def json_case(name: str, text: str | bytes) -> None:
    case(f"replay-{name}")(lambda d: ["replay", _file(d, "result.json", text), "-o", d / "out", "--formats", "none"])


json_case("int-5000-digits", json.dumps(_result_json()).replace('"seed": 1', '"seed": ' + "7" * 5000))
json_case("nested-50000", "[" * 50000 + "]" * 50000)
json_case("nested-in-object", json.dumps(_result_json()).replace('"history": []', '"history": ' + "[" * 50000 + "]" * 50000))
json_case("bounds-malformed", json.dumps({**_result_json(), "config": {"bounds": [[0, "a"], [1]]}}))
json_case("bounds-nan", json.dumps({**_result_json(), "config": {"bounds": [[0, 0], [1, float("nan")]]}}))
json_case("not-object", "[1, 2, 3]")
json_case("version", json.dumps({**_result_json(), "version": 99}))
json_case("kind", json.dumps({**_result_json(), "kind": "blob"}))
json_case("points-nan", json.dumps({**_result_json(), "control_points": [[0, "NaN"]]}))
json_case("genome-garbage", json.dumps({**_result_json(), "genome": [{"op": "nope"}]}))
json_case("binary", bytes(range(256)))
json_case("truncated", json.dumps(_result_json())[:-20])
json_case("float-overflow", json.dumps(_result_json()).replace('"seed": 1', '"seed": 1e5000'))
json_case("nested-objects-50000", '{"a": ' * 50000 + "1" + "}" * 50000)
json_case("points-1e5000", json.dumps({**_result_json(), "control_points": [[0, 0], [1, 1], [2, 0], [3, 1]]})
          .replace("[1, 1]", "[1e5000, 1]"))
json_case("bom-ok-but-empty-genome", "\ufeff" + json.dumps({**_result_json(), "control_points": "x"}))


# random mutations of valid files
def _mutations(rng: np.random.Generator, data: bytes, count: int) -> list[bytes]:
    tokens = [b"nan", b"inf", b"-1", b"0", b"1e308", b"1e-320", BIG.encode(), b"\xff\xfe", b"", b"#", b"\n\n", b"-0"]
    out = []
    for _ in range(count):
        b = bytearray(data)
        kind = rng.integers(3)
        if kind == 0:  # truncate
            b = b[:int(rng.integers(1, max(2, len(b))))]
        elif kind == 1:  # flip bytes
            for i in rng.integers(0, len(b), size=int(rng.integers(1, 6))):
                b[i] = int(rng.integers(256))
        else:  # replace a token
            at = int(rng.integers(len(b)))
            tok = tokens[int(rng.integers(len(tokens)))]
            end = b.find(b" ", at)
            end = at + 3 if end < 0 else end
            b[at:end] = tok
        out.append(bytes(b))
    return out


_rng = np.random.default_rng(SEED)
_tri_v, _tri_f = _tetra()
for i, blob in enumerate(_mutations(_rng, _curve_csv().encode(), 8)):
    curve_file(f"mut{i}.csv", blob, ANY)
for i, blob in enumerate(_mutations(_rng, _npy(np.random.default_rng(2).random((30, 2))), 5)):
    curve_file(f"mut{i}.npy", blob, ANY)
for suffix, data in (("obj", _cube_obj().encode()), ("off", _off(_tri_v, _tri_f).encode()),
                     ("ply", _ascii_ply(_tri_v, _tri_f).encode()), ("ply", _binary_ply(_tri_v, _tri_f)),
                     ("stl", _stl(_tri_v, _tri_f)),
                     ("xyz", "".join(f"{x} {y} {z}\n" for x, y, z in _cube_cloud()).encode())):
    for i, blob in enumerate(_mutations(_rng, data, 4)):
        surface_file(f"mut{i}-{len(data)}.{suffix}", blob, ANY)
for i, blob in enumerate(_mutations(_rng, json.dumps(_result_json()).encode(), 6)):
    case(f"replay-mut{i}", ANY)(lambda d, b=blob: ["replay", _file(d, "result.json", b), "-o", d / "out",
                                                    "--formats", "none"])


@pytest.mark.parametrize("name,expect,write", CASES, ids=[c[0] for c in CASES])
def test_fuzz(tmp_path, name, expect, write):
    argv = write(tmp_path)
    run = gsr_forked(argv, tmp_path, timeout=120)
    if expect == ERROR:
        assert_clean_error(run)
    elif expect == OK:
        assert_clean(run)
        assert run.code == 0, run.describe()
    else:
        assert_clean(run)


def test_corpus_is_bounded():
    assert 190 <= len(CASES) <= 240
    assert len({c[0] for c in CASES}) == len(CASES)


@pytest.fixture
def shared_dir():
    """A directory any user may enter (pytest's own tmp_path is private to its user)."""
    d = Path(tempfile.mkdtemp(prefix="gsr-fuzz-"))
    os.chmod(d, 0o777)
    yield d
    for root, dirs, _ in os.walk(d):
        for name in dirs:
            os.chmod(os.path.join(root, name), 0o755)
    shutil.rmtree(d, ignore_errors=True)


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to switch to another user")
def test_unreadable_file_as_other_user(shared_dir):
    """A file the user may not read: one error line (run as 'nobody' in a world-writable directory)."""
    tmp_path = shared_dir
    src = _file(tmp_path, "c.csv", _curve_csv())
    os.chmod(src, 0o600)
    run = gsr_as_nobody(["curve", src, "-o", tmp_path / "out", *TINY_CURVE], tmp_path)
    assert_clean_error(run)
    assert "permission denied" in run.err.lower()


def test_read_only_out(shared_dir):
    """An output directory inside a read-only one: one error line, nothing written."""
    tmp_path = shared_dir
    src = _file(tmp_path, "c.csv", _curve_csv())
    os.chmod(src, 0o644)
    (tmp_path / "ro").mkdir()
    os.chmod(tmp_path / "ro", 0o555)
    argv = ["curve", src, "-o", tmp_path / "ro" / "sub", *TINY_CURVE]
    run = gsr_as_nobody(argv, tmp_path) if os.geteuid() == 0 else gsr(argv, tmp_path)
    assert_clean_error(run)
    assert not (tmp_path / "ro" / "sub").exists()


def test_unreadable_file_without_root(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root reads every file")
    src = _file(tmp_path, "c.csv", _curve_csv())
    os.chmod(src, 0)
    assert_clean_error(gsr(["curve", src, "-o", tmp_path / "out", *TINY_CURVE], tmp_path))


def _small_files() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes past the limit fail with EFBIG instead of killing
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))


@pytest.mark.parametrize("kind", ["curve", "surface"])
def test_full_disk_is_one_error_line(tmp_path, kind):
    """Writes that fail (a file-size limit stands in for a full disk): one ``error:`` line, exit 2."""
    if kind == "curve":
        argv = ["curve", _file(tmp_path, "c.csv", _curve_csv()), "-o", tmp_path / "out", *TINY_CURVE]
    else:
        argv = ["surface", _file(tmp_path, "t.obj", _cube_obj()), "-o", tmp_path / "out", *TINY_SURFACE]
    run = gsr(argv, tmp_path, preexec=_small_files)
    assert_clean_error(run)
    leftovers = [p.name for p in (tmp_path / "out").iterdir() if p.name.startswith(".")] \
        if (tmp_path / "out").exists() else []
    assert leftovers == []


def test_bom_keeps_the_first_point(tmp_path):
    from gsr_cad.reconstruct.inputs import load_curve_points

    plain = load_curve_points(_file(tmp_path, "a.csv", "0,0\n1,1\n2,0\n3,1\n"))
    bom = load_curve_points(_file(tmp_path, "b.csv", "\ufeff0,0\n1,1\n2,0\n3,1\n"))
    assert np.array_equal(plain, bom) and len(bom) == 4


def test_zero_area_target_faces_are_dropped_with_a_warning(tmp_path):
    from gsr_cad.errors import GsrWarning
    from gsr_cad.reconstruct.inputs import surface_target

    v, f = _tetra()
    path = _file(tmp_path, "z.obj", _obj(np.vstack([v, [[0.5, 0.5, 0]]]), f + [[1, 2, 4]]))
    with pytest.warns(GsrWarning) as caught:
        target = surface_target(path)
    messages = [str(w.message) for w in caught]
    assert any("zero-area" in m for m in messages) and any("ignored 1 vertex" in m for m in messages), messages
    assert len(target.faces) == 4 and len(target.points) == 4


def test_stale_staging_folders_are_removed(tmp_path):
    out = tmp_path / "out"
    (out / ".gsr-export-abc123" / "x").mkdir(parents=True)
    _file(out, ".result.json.x1y2.tmp", "{")
    run = gsr(["curve", _file(tmp_path, "c.csv", _curve_csv()), "-o", out, *TINY_CURVE], tmp_path)
    assert_clean(run)
    assert run.code == 0
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []
    assert stat.S_ISREG(os.stat(out / "result.json").st_mode)


@pytest.mark.parametrize("command", ["curve", "surface", "sample", "subdivide"])
def test_no_space_left_is_one_error_line(tmp_path, monkeypatch, capsys, command):
    """ENOSPC (a full disk) when a finished file is moved into place: one ``error:`` line, exit 2, no temp file
    left (in-process: a non-root user cannot fill a real disk for a test)."""
    import errno

    from gsr_cad import atomic
    from gsr_cad.cli import main

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    argv = {"curve": ["curve", _file(tmp_path, "c.csv", _curve_csv()), "-o", tmp_path / "out", *TINY_CURVE],
            "surface": ["surface", _file(tmp_path, "t.obj", _cube_obj()), "-o", tmp_path / "out", *TINY_SURFACE],
            "sample": ["sample", "bspline_05", "-o", tmp_path / "out" / "c.csv"],
            "subdivide": ["subdivide", _file(tmp_path, "t.obj", _cube_obj()), "-o", tmp_path / "out" / "s.obj"]}
    monkeypatch.setattr(atomic.os, "replace", full)
    code = main([str(a) for a in argv[command]])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: ") and "No space left on device" in lines[0], err
    left = [p.name for p in (tmp_path / "out").rglob("*")] if (tmp_path / "out").exists() else []
    assert not [n for n in left if n.endswith(".tmp")], left
