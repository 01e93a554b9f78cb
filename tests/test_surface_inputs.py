"""Surface targets and templates: every supported file kind loads, every bad input is a one-line typed error,
and the default cube template's limit surface spans the target's bounding box."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import trimesh

from gsr_cad.errors import InputError, TopologyError
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import (SurfaceTarget, load_surface_target, load_template, surface_target,
                                        validate_surface_points)
from gsr_cad.reconstruct.meshio import save_mesh
from gsr_cad.reconstruct.surface import box_template, make_template

RNG = np.random.default_rng(11)
CLOUD = RNG.normal(size=(40, 3)) * [1.0, 2.0, 0.5] + [3.0, -1.0, 7.0]


def write(path, text: str):
    path.write_text(text)
    return path


def as_rows(points: np.ndarray, sep: str = " ") -> str:
    return "\n".join(sep.join(f"{x:.17g}" for x in row) for row in points) + "\n"


@pytest.mark.parametrize("suffix", ["obj", "off", "ply", "stl"])
def test_mesh_files_load_as_triangulated_meshes(tmp_path, suffix):
    mesh = limit_mesh(unit_cube(), 1)  # 24 quads
    path = save_mesh(mesh, tmp_path / f"m.{suffix}")
    target = load_surface_target(path)
    assert target.kind == "mesh" and target.name == "m"
    assert target.faces.shape == (48, 3)
    np.testing.assert_allclose(np.sort(target.points, axis=0), np.sort(mesh.vertices, axis=0), atol=1e-6)
    np.testing.assert_allclose(target.bbox, mesh.bbox, atol=1e-6)
    assert target.diagonal == pytest.approx(mesh.diagonal, abs=1e-6)


@pytest.mark.parametrize("name, text", [
    ("c.xyz", as_rows(CLOUD)),
    ("c.txt", as_rows(CLOUD, "\t")),
    ("c.pts", as_rows(CLOUD)),
    ("c.csv", "x,y,z\n" + as_rows(CLOUD, ",")),
    ("n.xyz", as_rows(np.hstack([CLOUD, np.ones_like(CLOUD)]))),  # x y z nx ny nz: normals ignored
    ("v.obj", "# only vertices\n" + "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in CLOUD.tolist())),
])
def test_point_cloud_text_files(tmp_path, name, text):
    target = load_surface_target(write(tmp_path / name, text))
    assert target.kind == "cloud" and target.faces is None
    np.testing.assert_allclose(target.points, CLOUD, rtol=1e-15)


@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_ply_without_faces_and_npy_are_clouds(tmp_path, encoding):
    ply = tmp_path / "c.ply"
    ply.write_bytes(trimesh.PointCloud(CLOUD).export(file_type="ply", encoding=encoding))
    np.testing.assert_allclose(load_surface_target(ply).points, CLOUD, rtol=1e-6)  # PLY stores float32
    np.save(tmp_path / "c.npy", CLOUD)
    target = load_surface_target(tmp_path / "c.npy")
    assert target.kind == "cloud"
    np.testing.assert_array_equal(target.points, CLOUD)


def test_targets_from_arrays_meshes_and_targets():
    t = surface_target(CLOUD)
    assert t.kind == "cloud" and t.name == "points"
    cube = unit_cube()
    m = surface_target(cube, name="cube")
    assert m.kind == "mesh" and m.faces.shape == (12, 3) and m.name == "cube"
    assert surface_target(m) is m


@pytest.mark.parametrize("name, text, error, message", [
    ("e.xyz", "", InputError, "empty"),
    ("h.xyz", "x y z\n", InputError, "no data rows"),
    ("nan.xyz", "0 0 0\n1 nan 0\n0 1 0\n0 0 1\n", InputError, "NaN"),
    ("inf.xyz", "0 0 0\n1 inf 0\n0 1 0\n0 0 1\n", InputError, "NaN or infinite"),
    ("few.xyz", "0 0 0\n1 0 0\n0 1 1\n", InputError, "at least 4 points"),
    ("flat2d.csv", "0,0\n1,0\n0,1\n1,1\n", InputError, "2D data"),
    ("four.xyz", "0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n", InputError, "3 columns"),
    ("same.xyz", "1 2 3\n1 2 3\n1 2 3\n1 2 3\n", InputError, "single point"),
    ("line.xyz", "0 0 0\n1 1 1\n2 2 2\n5 5 5\n", InputError, "on a line"),
    ("plane.xyz", "0 0 1\n1 0 1\n0 1 1\n3 4 1\n2 7 1\n", InputError, "one plane"),
    ("word.xyz", "0 0 0\n1 0 a\n0 1 0\n0 0 1\n", InputError, "non-numeric"),
    ("ragged.xyz", "0 0 0\n1 0\n0 1 0\n0 0 1\n", InputError, "different numbers of columns"),
    ("cloud.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", InputError, "at least 4 points"),
    ("flat.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", InputError, "one plane"),
    ("nanmesh.obj", "v 0 0 0\nv 1 0 nan\nv 1 1 0\nv 0 1 1\nf 1 2 3 4\n", InputError, "NaN"),
    ("badface.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\nf 1 2 9\n", InputError, "vertex"),
    ("x.dae", "<xml/>", InputError, "unsupported"),
])
def test_bad_targets_raise_one_line_errors(tmp_path, name, text, error, message):
    with pytest.raises(error, match=message) as info:
        load_surface_target(write(tmp_path / name, text))
    assert "\n" not in str(info.value)


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_surface_target(tmp_path / "nope.obj")
    with pytest.raises(InputError, match="directory"):
        load_surface_target(tmp_path)
    with pytest.raises(InputError, match="shape"):
        validate_surface_points(np.zeros(5))


def test_templates_must_be_valid_quad_meshes(tmp_path):
    cube = unit_cube()
    assert load_template(save_mesh(cube, tmp_path / "cube.obj")).n_faces == 6
    tri = trimesh.creation.box()
    save_mesh(PolyMesh.from_faces(tri.vertices, tri.faces), tmp_path / "tri.obj")
    with pytest.raises(TopologyError, match="not a valid quad mesh: face 0 has 3 corners") as info:
        load_template(tmp_path / "tri.obj")
    assert "\n" not in str(info.value)
    # two cubes sharing one edge (the second cube's vertices 0 and 4 welded onto the first's 3 and 7)
    v = np.vstack([cube.vertices, cube.vertices + [1.0, 1.0, 0.0]])
    weld = {8: 3, 12: 7}
    faces = cube.faces + [tuple(weld.get(i + 8, i + 8) for i in f) for f in cube.faces]
    used = sorted({i for f in faces for i in f})
    remap = {old: new for new, old in enumerate(used)}
    write(tmp_path / "bowtie.obj", "".join(f"v {x} {y} {z}\n" for x, y, z in v[used])
          + "".join("f " + " ".join(str(remap[i] + 1) for i in f) + "\n" for f in faces))
    with pytest.raises(TopologyError, match="not a valid quad mesh"):
        load_template(tmp_path / "bowtie.obj")
    with pytest.raises(InputError, match="no such file"):
        load_template(tmp_path / "missing.obj")
    with pytest.raises(InputError, match="template must be"):
        make_template(42, surface_target(CLOUD), SurfaceConfig())


@pytest.mark.parametrize("fit", ["box", "cube"])
def test_cube_template_limit_surface_spans_the_target_box(fit):
    target = SurfaceTarget(CLOUD)
    template = box_template(target, fit)
    assert template.n_faces == 6 and template.topology.is_closed
    lim = limit_mesh(template, 2)  # holds the face centres' limit points, the extremes
    if fit == "box":
        np.testing.assert_allclose(lim.bbox, target.bbox, atol=1e-12)
    else:
        extent = np.ptp(lim.bbox, axis=0)
        np.testing.assert_allclose(extent, np.ptp(target.bbox, axis=0).max(), rtol=1e-12)
        np.testing.assert_allclose(lim.bbox.mean(axis=0), target.bbox.mean(axis=0), atol=1e-12)


def test_target_pickles_without_its_caches():
    target = SurfaceTarget(CLOUD, None, "c")
    _ = target.kdtree, target.sampling_radius
    copy = pickle.loads(pickle.dumps(target))
    assert "kdtree" not in copy.__dict__ and copy.name == "c"
    np.testing.assert_array_equal(copy.sampling_radius, target.sampling_radius)


def test_closest_points_on_a_mesh_and_on_a_cloud():
    mesh = surface_target(unit_cube(), name="cube")
    x = np.array([[0.0, 0.0, 1.5], [0.2, -0.1, 0.1], [2.0, 2.0, 2.0]])
    d, point = mesh.closest(x)
    np.testing.assert_allclose(point, [[0.0, 0.0, 0.5], [0.5, -0.1, 0.1], [0.5, 0.5, 0.5]], atol=1e-12)
    np.testing.assert_allclose(d, np.linalg.norm(x - point, axis=1), atol=1e-12)
    cloud = SurfaceTarget(CLOUD, None, "c")
    d, point = cloud.closest(CLOUD + 1e-9)  # each sample is within its own sampling radius
    np.testing.assert_array_equal(point, CLOUD)
    np.testing.assert_array_equal(d, 0.0)
    far = CLOUD[0] + [100.0, 0.0, 0.0]
    d, point = cloud.closest(far[None])
    nearest = int(np.argmin(np.linalg.norm(CLOUD - far, axis=1)))
    np.testing.assert_array_equal(point[0], CLOUD[nearest])
    assert d[0] == pytest.approx(np.linalg.norm(far - CLOUD[nearest]) - cloud.sampling_radius[nearest])
