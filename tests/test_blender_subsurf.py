"""Our Catmull-Clark against Blender's Subdivision Surface modifier (OpenSubdiv inside), one Blender run.

Every hand-made mesh of test_subdivision.py and Blender's own Suzanne go through the modifier at levels 1-3,
with ``use_limit_surface`` off (plain refinement) and on (quality 10), boundary ALL and, for open meshes,
PRESERVE_CORNERS. Ours must give the same points (within 1e-5 of the diagonal; Blender stores float32)
and the same faces, matched one to one through nearest neighbours.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from gsr_cad.exporters.hosts import find_host, run_blender
from test_subdivision import MESHES, OPEN, match_meshes

from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import get_catmull_clark
from gsr_cad.geometry.validation import mesh_report, validate_mesh

pytestmark = [pytest.mark.blender, pytest.mark.xdist_group("blender")]  # one Blender run under --dist loadgroup

SCRIPT = Path(__file__).parent / "blender" / "subsurf_cases.py"
BOUNDARY = {"ALL": "all", "PRESERVE_CORNERS": "corners"}
NAMES = [*MESHES, "suzanne"]
RUNS = [(name, levels, limit, boundary) for name in NAMES for levels in (1, 2, 3) for limit in (False, True)
        for boundary in (("ALL", "PRESERVE_CORNERS") if name in OPEN or name == "suzanne" else ("ALL",))]


@pytest.fixture(scope="module")
def blender(tmp_path_factory) -> dict[str, np.ndarray]:
    if find_host("blender") is None:
        pytest.skip("Blender is not installed (Debian: apt-get install blender)")
    work = tmp_path_factory.mktemp("blender")
    meshes = {name: {"vertices": m.vertices.tolist(), "faces": [list(f) for f in m.faces]}
              for name, m in MESHES.items()}
    meshes["suzanne"] = {}
    (work / "cases.json").write_text(json.dumps({"meshes": meshes, "runs": RUNS}))
    run_blender(SCRIPT, [work / "cases.json", work / "out.npz"], timeout=300)
    with np.load(work / "out.npz") as data:
        return dict(data)


def blender_mesh(data: dict[str, np.ndarray], prefix: str) -> PolyMesh:
    sizes = data[f"{prefix}/sizes"]
    return PolyMesh(data[f"{prefix}/vertices"], data[f"{prefix}/corners"], np.concatenate([[0], np.cumsum(sizes)]))


def test_blender_received_our_control_meshes(blender):
    for name, mesh in MESHES.items():
        got = blender_mesh(blender, f"{name}/control")
        assert got.faces == mesh.faces
        np.testing.assert_allclose(got.vertices, mesh.vertices, atol=1e-6 * mesh.diagonal)


def test_suzanne_is_a_usable_control_mesh(blender):
    suzanne = validate_mesh(blender_mesh(blender, "suzanne/control"))
    report = mesh_report(suzanne)
    assert (report["vertices"], report["faces"]) == (507, 500)
    assert report["triangles"] > 0 and report["quads"] > 0 and report["boundary_edges"] > 0


@pytest.mark.parametrize("name,levels,limit,boundary", RUNS)
def test_matches_blender(blender, name, levels, limit, boundary):
    control = MESHES[name] if name in MESHES else blender_mesh(blender, f"{name}/control")
    cc = get_catmull_clark(control, levels, BOUNDARY[boundary])
    ours = cc.limit(control.vertices) if limit else cc.refine(control.vertices)
    theirs = blender_mesh(blender, f"{name}/{levels}/{int(limit)}/{boundary}")
    err = match_meshes(ours, theirs, control.diagonal)
    assert err < 1e-5, err


@pytest.mark.parametrize("name", ["grid", "mixed_open", "single_quad"])
def test_blender_boundary_modes_differ(blender, name):
    """The boundary check has teeth: where a mesh has corners, Blender's two modes give different surfaces."""
    a = blender[f"{name}/2/1/ALL/vertices"]
    b = blender[f"{name}/2/1/PRESERVE_CORNERS/vertices"]
    assert np.abs(a - b).max() > 1e-2 * MESHES[name].diagonal
