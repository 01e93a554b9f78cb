"""Polygon mesh files: OBJ, OFF and PLY keep quads and n-gons; STL is triangles.

trimesh 4 triangulates OBJ and OFF polygons on load and its binary PLY reader rejects faces of
mixed sizes, so the polygon formats go through the small readers here, which keep every face as
written. STL goes through trimesh (facets merged on exactly equal coordinates). Every loaded mesh
is checked by :func:`~gsr_cad.geometry.validation.validate_mesh`; every file is written atomically.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..atomic import write_bytes, write_text
from ..errors import ExportError, InputError, TopologyError
from ..geometry.polymesh import PolyMesh
from ..geometry.surface_distance import triangulate as fan_triangles
from ..geometry.validation import validate_mesh
from .inputs import read_input

READ_FORMATS = ("obj", "off", "ply", "stl")
WRITE_FORMATS = ("obj", "off", "ply", "stl")


def _mesh(vertices: list | np.ndarray, faces: list[list[int]] | np.ndarray, what: str) -> PolyMesh:
    """PolyMesh from parsed vertices and faces (a list of index lists or an ``(m, k)`` array)."""
    if not len(faces):
        raise InputError(f"{what}: no faces (a mesh file is needed, not a point cloud)")
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    try:
        if isinstance(faces, np.ndarray):
            sizes = np.full(len(faces), faces.shape[1], dtype=np.int64)
            corners = faces.astype(np.int64).ravel()
        else:
            sizes = np.fromiter((len(f) for f in faces), dtype=np.int64, count=len(faces))
            corners = np.fromiter((i for f in faces for i in f), dtype=np.int64, count=int(sizes.sum()))
    except OverflowError:
        raise InputError(f"{what}: a face refers to a vertex index beyond 64 bits, but there are "
                         f"{len(v)} vertices") from None
    if np.any(sizes < 3):
        raise InputError(f"{what}: face {int(np.argmax(sizes < 3))} has fewer than 3 corners")
    bad = corners[(corners < 0) | (corners >= len(v))]
    if bad.size:
        raise InputError(f"{what}: a face refers to vertex {bad[0]}, but there are {len(v)} vertices")
    return PolyMesh(v, corners, np.concatenate([[0], np.cumsum(sizes)]))


def _read_obj(data: bytes, what: str) -> PolyMesh:
    verts: list[list[float]] = []
    faces: list[list[int]] = []
    for lineno, raw in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
        parts = raw.split("#", 1)[0].split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                if len(parts) < 4:
                    raise ValueError("a vertex needs x y z")
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                n = len(verts)
                idx = [int(p.split("/", 1)[0]) for p in parts[1:]]
                if any(i == 0 or i < -n for i in idx):
                    raise ValueError("face index 0 or before the first vertex")
                faces.append([i - 1 if i > 0 else n + i for i in idx])
        except ValueError as exc:
            raise InputError(f"{what}: line {lineno}: {exc}") from None
    return _mesh(verts, faces, what)


def _read_off(data: bytes, what: str) -> PolyMesh:
    lines = [ln.split("#", 1)[0].split() for ln in data.decode("utf-8", errors="replace").splitlines()]
    lines = [ln for ln in lines if ln]
    if not lines or not re.fullmatch(r"(ST)?C?N?OFF", lines[0][0]):
        raise InputError(f"{what}: not an OFF file (no OFF header)")
    lines = lines[1:] if len(lines[0]) == 1 else [lines[0][1:], *lines[1:]]  # counts on the header line or next
    try:
        nv, nf = int(lines[0][0]), int(lines[0][1])
        if nv < 0 or nf < 0:
            raise ValueError(f"negative counts ({nv} vertices, {nf} faces)")
        body = lines[1:]
        if len(body) < nv + nf:
            raise ValueError(f"{nv} vertices and {nf} faces announced, the file ends early")
        verts = [[float(x) for x in ln[:3]] for ln in body[:nv]]
        faces = []
        for ln in body[nv:nv + nf]:
            k = int(ln[0])
            if len(ln) < k + 1:
                raise ValueError(f"a face announces {k} corners but lists {len(ln) - 1}")
            faces.append([int(i) for i in ln[1:k + 1]])
    except (ValueError, IndexError) as exc:
        raise InputError(f"{what}: malformed OFF ({exc})") from None
    return _mesh(verts, faces, what)


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _ply_header(data: bytes, what: str) -> tuple[str, list, bytes]:
    """``(format, [(element, count, [(name, type) or (name, count type, item type)])], body)``."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError(f"{what}: not a PLY file (no ply header)")
    newline = data.find(b"\n", end)
    body = data[newline + 1:] if newline >= 0 else b""
    fmt, elements = "", []
    try:
        for line in data[:end].decode("ascii", errors="replace").splitlines()[1:]:
            p = line.split()
            if p and p[0] == "format":
                fmt = p[1]
            elif p and p[0] == "element":
                elements.append((p[1], int(p[2]), []))
            elif p and p[0] == "property":
                elements[-1][2].append((p[4], _PLY_TYPES[p[2]], _PLY_TYPES[p[3]]) if p[1] == "list"
                                       else (p[2], _PLY_TYPES[p[1]]))
    except (IndexError, KeyError, ValueError) as exc:
        raise InputError(f"{what}: malformed PLY header ({exc})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"{what}: unsupported PLY format {fmt or '(none)'!r}")
    for name, count, props in elements:
        if count < 0:
            raise InputError(f"{what}: malformed PLY header (element {name} has a negative count {count})")
        least = 2 if fmt == "ascii" else sum(np.dtype(p[1]).itemsize for p in props)
        if count * least > len(body):
            raise InputError(f"{what}: truncated PLY (the header announces {count} {name} elements, "
                             f"the data holds {len(body)} bytes)")
    return fmt, elements, body


def _ply_binary(body: bytes, pos: int, count: int, props: list, order: str) -> tuple[dict, int]:
    """Columns of one binary element and the position after it (vectorized unless lists vary)."""
    if all(len(p) == 2 for p in props):
        dtype = np.dtype([(p[0], order + p[1]) for p in props])
        table = np.frombuffer(body, dtype=dtype, count=count, offset=pos)
        return {p[0]: table[p[0]] for p in props}, pos + count * dtype.itemsize
    if len(props) == 1 and count:
        name, ct, it = props[0]
        n = int(np.frombuffer(body, order + ct, 1, pos)[0])
        if n < 0:
            raise ValueError(f"a list of {n} items")
        dtype = np.dtype([("n", order + ct), ("i", order + it, (n,))])
        if len(body) - pos >= count * dtype.itemsize:
            table = np.frombuffer(body, dtype=dtype, count=count, offset=pos)
            if np.all(table["n"] == n):
                return {name: table["i"].astype(np.int64)}, pos + count * dtype.itemsize
    cols: dict[str, list] = {p[0]: [] for p in props}
    for _ in range(count):
        for p in props:
            t = np.dtype(order + p[1])
            value = np.frombuffer(body, t, 1, pos)[0]
            pos += t.itemsize
            if len(p) == 3:
                it = np.dtype(order + p[2])
                if int(value) < 0:
                    raise ValueError(f"a list of {int(value)} items")
                value = np.frombuffer(body, it, int(value), pos)
                pos += value.nbytes
            cols[p[0]].append(value)
    return cols, pos


def _ply_ascii(tokens, count: int, props: list) -> dict:
    cols: dict[str, list] = {p[0]: [] for p in props}
    for _ in range(count):
        for p in props:
            if len(p) == 3:
                cols[p[0]].append([int(next(tokens)) for _ in range(int(next(tokens)))])
            else:
                cols[p[0]].append(float(next(tokens)))
    return cols


def _read_ply(data: bytes, what: str) -> PolyMesh:
    verts, faces = read_ply_vertices(data, what)
    return _mesh(verts, [] if faces is None else faces, what)


def read_ply_vertices(data: bytes, what: str) -> tuple[np.ndarray, list | np.ndarray | None]:
    """``(vertices (n, 3), faces or None)`` of a PLY file (None when it has no face element or 0 faces);
    a truncated or malformed file raises InputError."""
    fmt, elements, body = _ply_header(data, what)
    tokens = iter(body.split()) if fmt == "ascii" else iter(())
    order = ">" if fmt == "binary_big_endian" else "<"
    pos, verts, faces, has_faces = 0, None, [], False
    try:
        for name, count, props in elements:
            if fmt == "ascii":
                cols = _ply_ascii(tokens, count, props)
            else:
                cols, pos = _ply_binary(body, pos, count, props, order)
            if name == "vertex":
                verts = np.stack([np.asarray(cols[c], dtype=np.float64) for c in "xyz"], axis=1)
            elif name == "face":
                key = next((k for k in ("vertex_indices", "vertex_index") if k in cols), None)
                if key is None or next(len(p) for p in props if p[0] == key) != 3:
                    raise ValueError("the face element has no vertex_indices list")
                faces = cols[key] if isinstance(cols[key], np.ndarray) else [list(map(int, f)) for f in cols[key]]
                has_faces = count > 0
    except (StopIteration, ValueError, KeyError, TypeError, OverflowError) as exc:
        raise InputError(f"{what}: malformed or truncated PLY ({exc or 'it ends early'})") from None
    if verts is None or not len(verts):
        raise InputError(f"{what}: no vertices")
    return verts, faces if has_faces else None


def _read_stl(data: bytes, what: str) -> PolyMesh:
    import trimesh

    try:
        loaded = trimesh.load_mesh(io.BytesIO(data), file_type="stl", process=False)
    except Exception as exc:  # trimesh raises many types on malformed files
        raise InputError(f"{what}: cannot read STL ({exc})") from None
    tri = np.asarray(loaded.faces, dtype=np.int64)
    if not len(tri):
        raise InputError(f"{what}: no faces (a mesh file is needed, not a point cloud)")
    points = np.asarray(loaded.vertices, dtype=np.float64)
    unique, inverse = np.unique(points, axis=0, return_inverse=True)
    return _mesh(unique, inverse.ravel()[tri], what)


_READERS: dict[str, Callable[[bytes, str], PolyMesh]] = {
    "obj": _read_obj, "off": _read_off, "ply": _read_ply, "stl": _read_stl}


def load_mesh(path: str | os.PathLike[str], validate: bool = True) -> PolyMesh:
    """Read a polygon mesh (OBJ, OFF, PLY, STL) and check it with validate_mesh.

    Raises InputError (missing or empty file, unsupported or malformed format, no faces) and
    TopologyError (what validate_mesh rejects); messages start with the file name.
    """
    p = Path(path)
    fmt = p.suffix.lower().lstrip(".")
    if fmt not in _READERS:
        raise InputError(f"{p.name}: unsupported mesh format {p.suffix or '(no suffix)'!r} "
                         f"(use {', '.join('.' + f for f in READ_FORMATS)})")
    mesh = read_mesh_bytes(read_input(p, "mesh file", label=p.name), fmt, p.name)
    if validate:
        try:
            validate_mesh(mesh)
        except TopologyError as exc:
            raise TopologyError(f"{p.name}: {exc}") from None
    return mesh


def read_mesh_bytes(data: bytes, fmt: str, what: str) -> PolyMesh:
    """Parse the bytes of a mesh file in format ``fmt`` (obj, off, ply, stl); InputError if malformed."""
    if not data.strip():
        raise InputError(f"{what}: file is empty")
    try:
        mesh = _READERS[fmt](data, what)
    except TopologyError as exc:
        raise TopologyError(f"{what}: {exc}") from None
    return mesh


def _floats(v: np.ndarray) -> list[str]:
    """Shortest exact text of each row (round-trips every double)."""
    return [" ".join(map(repr, row)) for row in v.tolist()]


def obj_text(mesh: PolyMesh) -> str:
    """The OBJ text of ``mesh`` (1-based ``f`` lines, n-gons kept)."""
    lines = [f"# gsr_cad: {mesh.n_vertices} vertices, {mesh.n_faces} faces"]
    lines += ["v " + s for s in _floats(mesh.vertices)]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in mesh.faces]
    return "\n".join(lines) + "\n"


def save_obj(mesh: PolyMesh, path: str | os.PathLike[str]) -> Path:
    """Write ``mesh`` as OBJ, atomically."""
    return write_text(path, obj_text(mesh))


def _off_text(mesh: PolyMesh) -> str:
    lines = ["OFF", f"{mesh.n_vertices} {mesh.n_faces} 0"] + _floats(mesh.vertices)
    lines += [f"{len(f)} " + " ".join(map(str, f)) for f in mesh.faces]
    return "\n".join(lines) + "\n"


def _ply_text(mesh: PolyMesh) -> str:
    count = "uchar" if mesh.face_sizes.max(initial=0) < 256 else "int"
    lines = ["ply", "format ascii 1.0", "comment gsr_cad", f"element vertex {mesh.n_vertices}",
             "property double x", "property double y", "property double z", f"element face {mesh.n_faces}",
             f"property list {count} int vertex_indices", "end_header"] + _floats(mesh.vertices)
    lines += [f"{len(f)} " + " ".join(map(str, f)) for f in mesh.faces]
    return "\n".join(lines) + "\n"


def triangulate(mesh: PolyMesh) -> np.ndarray:
    """Fan triangles ``(m, 3)`` from each face's first corner (exact for convex faces)."""
    return fan_triangles(mesh.corners, mesh.offsets)


def _stl_bytes(mesh: PolyMesh) -> bytes:
    import trimesh

    tri = trimesh.Trimesh(vertices=np.asarray(mesh.vertices), faces=triangulate(mesh), process=False)
    return trimesh.exchange.stl.export_stl(tri)


def save_mesh(mesh: PolyMesh, path: str | os.PathLike[str]) -> Path:
    """Write ``mesh`` in the format its suffix names (obj, off, ply keep n-gons; stl is triangulated)."""
    p = Path(path)
    fmt = p.suffix.lower().lstrip(".")
    if fmt == "obj":
        return save_obj(mesh, p)
    if fmt == "off":
        return write_text(p, _off_text(mesh))
    if fmt == "ply":
        return write_text(p, _ply_text(mesh))
    if fmt == "stl":
        return write_bytes(p, _stl_bytes(mesh))
    raise ExportError(f"{p.name}: cannot write format {p.suffix or '(no suffix)'!r} "
                      f"(use {', '.join('.' + f for f in WRITE_FORMATS)})")
