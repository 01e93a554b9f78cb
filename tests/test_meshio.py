"""Mesh files: exact round trips keeping n-gons, trimesh as an independent reader and writer, hand-written
files in the formats' variants, and a typed one-line error for every bad file."""

from __future__ import annotations

import struct

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from conftest import pentaprism
from hypothesis.extra import numpy as hnp

from gsr_cad.errors import ExportError, InputError, TopologyError
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.reconstruct.meshio import load_mesh, save_mesh, save_obj, triangulate


def strip() -> PolyMesh:
    """Open: a pentagon, a quad and a triangle."""
    v = [[0, 0, 0], [1, 0, 0], [1.3, 0.8, 0], [0.5, 1.3, 0], [-0.3, 0.8, 0], [2, 0, 0], [2.2, 0.9, 0], [3, 0.2, 0]]
    return PolyMesh.from_faces(v, [[0, 1, 2, 3, 4], [1, 5, 6, 2], [5, 7, 6]])


MESHES = {"cube": unit_cube(), "pentaprism": pentaprism(), "strip": strip()}


@pytest.mark.parametrize("fmt", ["obj", "off", "ply"])
@pytest.mark.parametrize("name", sorted(MESHES))
def test_polygon_formats_round_trip_exactly(tmp_path, fmt, name):
    mesh = MESHES[name]
    path = save_mesh(mesh, tmp_path / f"m.{fmt}")
    got = load_mesh(path)
    assert got.faces == mesh.faces
    np.testing.assert_array_equal(got.vertices, mesh.vertices)
    assert [p.name for p in tmp_path.iterdir()] == [f"m.{fmt}"]  # no temp file left behind


@pytest.mark.parametrize("fmt", ["obj", "off", "ply"])
@settings(max_examples=15, deadline=None)
@given(v=hnp.arrays(np.float64, (10, 3), elements=st.floats(allow_nan=False, allow_infinity=False, width=64)))
def test_every_double_survives(tmp_path_factory, fmt, v):
    path = tmp_path_factory.mktemp("rt") / f"m.{fmt}"
    save_mesh(PolyMesh(v, pentaprism().corners, pentaprism().offsets), path)
    np.testing.assert_array_equal(load_mesh(path, validate=False).vertices, v)


# trimesh 4.x's OFF reader fails on pentagons under numpy 2 (string ufunc in triangulate_quads): cube only there
@pytest.mark.parametrize("fmt,name", [("obj", "cube"), ("obj", "pentaprism"), ("ply", "cube"),
                                      ("ply", "pentaprism"), ("off", "cube")])
def test_trimesh_reads_what_we_write(tmp_path, fmt, name):
    mesh = MESHES[name]
    path = save_mesh(mesh, tmp_path / f"m.{fmt}")
    other = trimesh.load_mesh(path, process=False)
    assert np.unique(np.round(other.vertices, 12), axis=0).shape == np.unique(mesh.vertices, axis=0).shape
    assert other.area == pytest.approx(mesh.face_areas.sum(), rel=1e-12)  # planar faces: same area
    assert len(other.faces) == int(np.sum(mesh.face_sizes - 2))


def test_stl_is_triangulated_and_merged(tmp_path):
    mesh = pentaprism()
    path = save_mesh(mesh, tmp_path / "m.stl")
    other = trimesh.load_mesh(path)  # trimesh merges the facets' corners
    assert other.is_watertight and other.volume == pytest.approx(trimesh.Trimesh(
        mesh.vertices, triangulate(mesh)).volume, rel=1e-6)
    got = load_mesh(path)
    assert got.n_faces == int(np.sum(mesh.face_sizes - 2)) and np.all(got.face_sizes == 3)
    assert got.n_vertices == mesh.n_vertices and got.topology.is_closed
    assert got.face_areas.sum() == pytest.approx(mesh.face_areas.sum(), rel=1e-6)


def test_triangulate_fans():
    tri = triangulate(strip())
    assert tri.tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4], [1, 5, 6], [1, 6, 2], [5, 7, 6]]


@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_we_read_what_trimesh_writes(tmp_path, encoding):
    box = trimesh.creation.box(extents=(1, 2, 3))
    for fmt, data in (("ply", trimesh.exchange.ply.export_ply(box, encoding=encoding)),
                      ("stl", trimesh.exchange.stl.export_stl(box) if encoding == "binary"
                       else trimesh.exchange.stl.export_stl_ascii(box)),
                      ("obj", trimesh.exchange.obj.export_obj(box)), ("off", trimesh.exchange.off.export_off(box))):
        path = tmp_path / f"box.{fmt}"
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        got = load_mesh(path)
        assert got.n_faces == 12 and got.n_vertices == 8 and got.topology.is_closed
        assert got.face_areas.sum() == pytest.approx(box.area, rel=1e-6)
        if fmt != "stl":
            np.testing.assert_allclose(got.vertices, box.vertices, rtol=1e-6)
            assert got.faces == [tuple(f) for f in box.faces.tolist()]


def test_obj_variants(tmp_path):
    text = """# exported by hand
mtllib x.mtl
o strip
v 0 0 0
v 1 0 0 1.0
v 1.3 0.8 0
vt 0 0
vn 0 0 1
v 0.5 1.3 0
v -0.3 0.8 0   # trailing comment
g part
usemtl red
s off
f 1/1/1 2/1/1 3//1 4 5
v 2 0 0
v 2.2 0.9 0
v 3 0.2 0
f -7 -3 -2 -6
l 1 2
f 6 8 7
"""
    path = tmp_path / "s.obj"
    path.write_text(text)
    got = load_mesh(path)
    assert got.faces == strip().faces
    np.testing.assert_array_equal(got.vertices, strip().vertices)


def test_off_variants(tmp_path):
    mesh = strip()
    body = "\n".join(" ".join(map(str, v)) + " 255 0 0" for v in mesh.vertices.tolist())
    faces = "\n".join(f"{len(f)} " + " ".join(map(str, f)) + " 0.5 0.5 0.5" for f in mesh.faces)
    counts = f"{mesh.n_vertices} {mesh.n_faces} 0"
    for header in (f"COFF\n# comment\n{counts}\n", f"OFF {counts}\n"):
        path = tmp_path / "s.off"
        path.write_text(header + body + "\n" + faces + "\n")
        got = load_mesh(path)
        assert got.faces == mesh.faces
        np.testing.assert_array_equal(got.vertices, mesh.vertices)


def _binary_ply(mesh: PolyMesh, order: str, extra: bool) -> bytes:
    """A binary PLY with float vertices (plus normals and a face flag when ``extra``)."""
    name = {"<": "binary_little_endian", ">": "binary_big_endian"}[order]
    head = ["ply", f"format {name} 1.0", f"element vertex {mesh.n_vertices}", "property float x",
            "property float y", "property float z"]
    head += ["property float nx", "property float ny", "property float nz"] if extra else []
    head += [f"element face {mesh.n_faces}", "property list uchar int vertex_indices"]
    head += ["property uchar flags"] if extra else []
    out = ("\n".join(head) + "\nend_header\n").encode()
    for v in mesh.vertices:
        out += struct.pack(order + ("6f" if extra else "3f"), *v, *((0.0, 0.0, 1.0) if extra else ()))
    for f in mesh.faces:
        out += struct.pack(f"{order}B{len(f)}i", len(f), *f) + (struct.pack("B", 7) if extra else b"")
    return out


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("extra", [False, True])
@pytest.mark.parametrize("name", ["strip", "cube"])
def test_binary_ply_mixed_and_uniform_faces(tmp_path, order, extra, name):
    mesh = MESHES[name]
    path = tmp_path / "m.ply"
    path.write_bytes(_binary_ply(mesh, order, extra))
    got = load_mesh(path)
    assert got.faces == mesh.faces
    np.testing.assert_array_equal(got.vertices, mesh.vertices.astype(np.float32))


# --- bad files ----------------------------------------------------------------------------------------

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
PLY_HEAD = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
BAD_FILES = [
    ("empty.obj", "", InputError, "file is empty"),
    ("blank.off", "  \n\n", InputError, "file is empty"),
    ("points.xyz", "0 0 0\n", InputError, "unsupported mesh format '.xyz'"),
    ("nosuffix", TRIANGLE, InputError, "unsupported mesh format"),
    ("points.obj", TRIANGLE, InputError, "no faces"),
    ("badfloat.obj", "v 0 x 0\n", InputError, "line 1"),
    ("short.obj", "v 0 0 0\nv 1 0 0\n", InputError, "no faces"),
    ("twocorners.obj", TRIANGLE + "f 1 2\n", InputError, "fewer than 3 corners"),
    ("range.obj", TRIANGLE + "f 1 2 9\n", InputError, "refers to vertex 8"),
    ("zero.obj", TRIANGLE + "f 0 1 2\n", InputError, "line 4"),
    ("noheader.off", "3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", InputError, "not an OFF file"),
    ("truncated.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n", InputError, "ends early"),
    ("badcount.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", InputError, "announces 4 corners"),
    ("nofaces.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", InputError, "no faces"),
    ("noheader.ply", "0 0 0\n", InputError, "not a PLY file"),
    ("format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", InputError, "unsupported PLY format"),
    ("badtype.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", InputError,
     "malformed PLY header"),
    ("truncated.ply", PLY_HEAD + "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n",
     InputError, "truncated"),
    ("vertsonly.ply", PLY_HEAD + "end_header\n0 0 0\n1 0 0\n0 1 0\n", InputError, "no faces"),
    ("garbage.stl", "this is not an stl file at all", InputError, "no faces"),
    ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", TopologyError, "vertex 1 has a NaN"),
    ("repeat.obj", TRIANGLE + "v 1 1 0\nf 1 2 4 2 3\n", TopologyError, "face 0 repeats vertex 1"),
    ("unused.obj", TRIANGLE + "v 5 5 5\nf 1 2 3\n", TopologyError, "vertex 3 is not used"),
    ("fin.obj", TRIANGLE + "v 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n", TopologyError, "non-manifold edge"),
    ("flat.obj", TRIANGLE + "v 2 0 0\nf 1 2 3\nf 1 4 2\n", TopologyError, "zero area"),
]


@pytest.mark.parametrize("name,content,error,reason", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_files(tmp_path, name, content, error, reason):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(error) as info:
        load_mesh(path)
    message = str(info.value)
    assert reason in message and "\n" not in message
    assert message.startswith(name)


def test_truncated_binary_ply(tmp_path):
    data = _binary_ply(strip(), "<", False)
    for cut in (10, 40):
        path = tmp_path / "cut.ply"
        path.write_bytes(data[:-cut])
        with pytest.raises(InputError, match="truncated"):
            load_mesh(path)


def test_missing_and_unreadable(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_mesh(tmp_path / "nope.obj")
    (tmp_path / "dir.obj").mkdir()
    with pytest.raises(InputError, match="cannot read"):
        load_mesh(tmp_path / "dir.obj")


def test_writing_errors_leave_nothing(tmp_path):
    mesh = unit_cube()
    with pytest.raises(ExportError, match=r"cannot write format '\.step'"):
        save_mesh(mesh, tmp_path / "m.step")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="cannot write"):
        save_obj(mesh, tmp_path / "file" / "m.obj")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_save_replaces_existing_file(tmp_path):
    path = tmp_path / "m.obj"
    path.write_text("old\n")
    save_obj(strip(), path)
    assert load_mesh(path).faces == strip().faces
    assert [p.name for p in tmp_path.iterdir()] == ["m.obj"]
