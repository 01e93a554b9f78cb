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
from scipy.spatial import cKDTree
import pytest
from gsr_cad.exporters.blender import CREASE_QUALITY
from gsr_cad.exporters.hosts import find_host, run_blender
from test_mesh_ops import seeded_genomes
from test_region_ops import region_genomes
from test_subdivision import MESHES, OPEN, match_meshes

from gsr_cad import genome as genome_mod
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.geometry.subdivision import CatmullClark, get_catmull_clark
from gsr_cad.geometry.validation import mesh_report, validate_mesh
from gsr_cad.ops.mesh import Hole, Inset

pytestmark = [pytest.mark.blender, pytest.mark.xdist_group("blender")]  # one Blender run under --dist loadgroup

SCRIPT = Path(__file__).parent / "blender" / "subsurf_cases.py"
QUALITY = 10  # the modifier's quality in subsurf_cases.py
BOUNDARY = {"ALL": "all", "PRESERVE_CORNERS": "corners"}
NAMES = [*MESHES, "suzanne"]
RUNS = [(name, levels, limit, boundary) for name in NAMES for levels in (1, 2, 3) for limit in (False, True)
        for boundary in (("ALL", "PRESERVE_CORNERS") if name in OPEN or name == "suzanne" else ("ALL",))]


@pytest.fixture(scope="session")
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


# --- creases -----------------------------------------------------------------------------------------------
# Blender's crease c in [0, 1] is OpenSubdiv sharpness 10 c**2 (measured: refined points agree to float32
# precision only with that map). Only interior edges are creased: boundary edges are infinitely sharp anyway,
# and Blender alone also sharpens a vertex with exactly two edges by the smaller crease of the two.

CREASE_KINDS = {"any": (0.0, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 10.0), "semi": (0.0, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5)}
CREASE_RUNS = [(name, kind, levels, limit, boundary) for name in MESHES for kind in (*CREASE_KINDS, "rims")
               for levels in (1, 2, 3) for limit in (False, True)
               for boundary in (("ALL", "PRESERVE_CORNERS") if name in OPEN else ("ALL",))]


def creased(name: str, kind: str) -> PolyMesh:
    """MESHES[name] with reproducible creases on interior edges: random sharpness from CREASE_KINDS[kind], or
    ``"rims"``: whole face rims (no infinitely sharp dart)."""
    mesh = MESHES[name]
    rng = np.random.default_rng(sorted(MESHES).index(name))
    t = mesh.topology
    if kind == "rims":
        s = np.zeros(t.n_edges)
        for f in np.flatnonzero(rng.random(mesh.n_faces) < 0.4):
            he = t.he_edge[mesh.offsets[f]:mesh.offsets[f + 1]]
            s[he] = np.maximum(s[he], rng.choice([0.5, 1.5, 2.5, 10.0]))
    else:
        s = rng.choice(CREASE_KINDS[kind], size=t.n_edges)
    s[t.edge_is_boundary] = 0.0
    return mesh.with_creases(dict(zip(map(tuple, t.edges.tolist()), s)))


@pytest.fixture(scope="session")
def blender_creased(tmp_path_factory) -> dict[str, np.ndarray]:
    if find_host("blender") is None:
        pytest.skip("Blender is not installed (Debian: apt-get install blender)")
    work = tmp_path_factory.mktemp("blender_creases")
    meshes = {}
    for name in MESHES:
        for kind in (*CREASE_KINDS, "rims"):
            mesh = creased(name, kind)
            meshes[f"{name}-{kind}"] = {"vertices": mesh.vertices.tolist(), "faces": [list(f) for f in mesh.faces],
                                        "creases": [[a, b, float(np.sqrt(s / 10.0))] for (a, b), s in mesh.creases.items()]}
    runs = [(f"{name}-{kind}", levels, limit, boundary) for name, kind, levels, limit, boundary in CREASE_RUNS]
    (work / "cases.json").write_text(json.dumps({"meshes": meshes, "runs": runs}))
    run_blender(SCRIPT, [work / "cases.json", work / "out.npz"], timeout=600)
    with np.load(work / "out.npz") as data:
        return dict(data)


def test_blender_received_our_creases(blender_creased):
    mesh = creased("cube", "any")
    got = blender_creased["cube-any/control/creases"]
    stored = {tuple(sorted((int(a), int(b)))): 10.0 * c * c for a, b, c in got}
    assert stored.keys() == mesh.creases.keys()
    np.testing.assert_allclose([stored[k] for k in mesh.creases], list(mesh.creases.values()), rtol=1e-6)


@pytest.mark.parametrize("name,kind,levels,limit,boundary", CREASE_RUNS)
def test_creases_match_blender(blender_creased, name, kind, levels, limit, boundary):
    """Refined points and limits to 1e-6 of the diagonal. At an infinitely sharp dart (one sharp edge at a
    vertex) Blender's limit is OpenSubdiv's smooth stencil after QUALITY steps (its patches are isolated that
    far), which ``dart_isolation`` reproduces; our exact dart limit is where it converges (test_creases)."""
    control = creased(name, kind)
    cc = CatmullClark(control, levels, BOUNDARY[boundary], dart_isolation=QUALITY)
    ours = cc.limit(control.vertices) if limit else cc.refine(control.vertices)
    theirs = blender_mesh(blender_creased, f"{name}-{kind}/{levels}/{int(limit)}/{boundary}")
    err = match_meshes(ours, theirs, control.diagonal)
    assert err < 1e-6, err


def test_blender_creases_have_teeth(blender_creased):
    """Creased and uncreased results differ, so the comparison above tests the crease rules."""
    for name in ("cube", "torus"):
        a = blender_creased[f"{name}-rims/2/1/ALL/vertices"]
        smooth = get_catmull_clark(MESHES[name], 2).limit(MESHES[name].vertices).vertices
        assert cKDTree(smooth).query(a)[0].max() > 1e-2 * MESHES[name].diagonal



def dart_meshes() -> dict[str, PolyMesh]:
    """One infinitely sharp edge (a dart at each end): on the cube (valence 3) and on a genus-1 genome, at a
    vertex of valence 7."""
    cube = unit_cube()
    holed = genome_mod.replay(cube, (Inset(4, 0.2), Inset(5, 0.2), Hole(4, 5), Inset(1, 0.1), Inset(8, 0.06),
                                     Inset(3, 0.26)))
    valence = holed.topology.vertex_valence[holed.topology.edges]
    edge = int(np.lexsort((valence.min(axis=1), valence.max(axis=1)))[-1])
    assert valence[edge].max() == 7
    return {"cube": cube.with_creases({(0, 1): 10.0}),
            "holed": holed.with_creases({tuple(holed.topology.edges[edge].tolist()): 10.0})}


DART_QUALITIES = (2, 4, 6, 8, 10)


@pytest.fixture(scope="session")
def blender_darts(tmp_path_factory) -> dict[str, np.ndarray]:
    if find_host("blender") is None:
        pytest.skip("Blender is not installed (Debian: apt-get install blender)")
    work = tmp_path_factory.mktemp("blender_darts")
    meshes = {name: {"vertices": m.vertices.tolist(), "faces": [list(f) for f in m.faces],
                     "creases": [[a, b, 1.0] for a, b in m.creases]} for name, m in dart_meshes().items()}
    runs = [(name, 2, True, "ALL", q) for name in meshes for q in DART_QUALITIES]
    (work / "cases.json").write_text(json.dumps({"meshes": meshes, "runs": runs}))
    run_blender(SCRIPT, [work / "cases.json", work / "out.npz"], timeout=300)
    with np.load(work / "out.npz") as data:
        return dict(data)


@pytest.mark.parametrize("name", ["cube", "holed"])
def test_blender_dart_limit_converges_to_ours_with_quality(blender_darts, name):
    """Blender's limit at a dart is OpenSubdiv's smooth stencil at the modifier's quality (dart_isolation, to
    1e-6 at every quality); as the quality rises it approaches our exact dart limit geometrically."""
    control = dart_meshes()[name]
    exact = CatmullClark(control, 2).limit(control.vertices)
    gaps = []
    for q in DART_QUALITIES:
        theirs = blender_mesh(blender_darts, f"{name}/2/1/ALL/{q}")
        model = CatmullClark(control, 2, dart_isolation=q).limit(control.vertices)
        assert match_meshes(model, theirs, control.diagonal) < 1e-6, q
        gaps.append(match_meshes(exact, theirs, control.diagonal))
    ratios = np.array(gaps[1:]) / np.array(gaps[:-1])
    assert gaps[0] > 1e-4 and np.all((ratios > 0.1) & (ratios < 0.5)), gaps  # two levels per entry: 0.46**2 .. 0.6**2


# --- random creased genomes with holes ------------------------------------------------------------------------
GENOMES = 200


def creased_genomes() -> list[tuple]:
    """GENOMES seeded random genomes on the unit cube over every surface op (C, R and H included; both caps
    inset first), each building at least one hole and one crease in at most 80 faces."""
    def holed(ops, mesh) -> bool:
        return mesh.topology.euler_characteristic < 2 and bool(mesh.creases) and mesh.n_faces <= 80

    return seeded_genomes(GENOMES, (Inset(4, 0.2), Inset(5, 0.2)), "VELBIFSCRHII", 12, holed)


def creased_genome_meshes() -> list[PolyMesh]:
    """The control meshes of :func:`creased_genomes`."""
    return [genome_mod.replay(unit_cube(), g) for g in creased_genomes()]


@pytest.fixture(scope="session")
def blender_genomes(tmp_path_factory) -> tuple[list[PolyMesh], dict[str, np.ndarray]]:
    if find_host("blender") is None:
        pytest.skip("Blender is not installed (Debian: apt-get install blender)")
    meshes = creased_genome_meshes()
    work = tmp_path_factory.mktemp("blender_genomes")
    specs = {f"g{i}": {"vertices": m.vertices.tolist(), "faces": [list(f) for f in m.faces],
                       "creases": [[a, b, float(np.sqrt(s / 10.0))] for (a, b), s in m.creases.items()]}
             for i, m in enumerate(meshes)}
    runs = [(f"g{i}", 2, limit, "ALL") for i in range(len(meshes)) for limit in (False, True)]
    (work / "cases.json").write_text(json.dumps({"meshes": specs, "runs": runs}))
    run_blender(SCRIPT, [work / "cases.json", work / "out.npz"], timeout=900)
    with np.load(work / "out.npz") as data:
        return meshes, dict(data)


def _both_ways(ours: PolyMesh, theirs: PolyMesh) -> float:
    """Largest nearest-neighbour distance both ways (creases can make two refined points coincide)."""
    return max(cKDTree(theirs.vertices).query(ours.vertices)[0].max(),
               cKDTree(ours.vertices).query(theirs.vertices)[0].max())


def test_random_creased_genomes_with_holes_match_blender(blender_genomes):
    """Blender's modifier on the control meshes of 200 random genomes with holes and creases reproduces our
    refined meshes and our limit (at darts as OpenSubdiv evaluates them at QUALITY, see
    test_creases_match_blender) within 1e-6 of the diagonal."""
    meshes, data = blender_genomes
    holes = [(2 - m.topology.euler_characteristic) // 2 for m in meshes]
    assert len(meshes) == GENOMES and min(holes) >= 1 and max(holes) >= 2
    worst = {False: 0.0, True: 0.0}
    for i, m in enumerate(meshes):
        np.testing.assert_allclose(data[f"g{i}/control/vertices"], m.vertices, atol=1e-6 * m.diagonal)
        cc = CatmullClark(m, 2, dart_isolation=QUALITY)
        for limit in (False, True):
            ours = cc.limit(m.vertices) if limit else cc.refine(m.vertices)
            theirs = blender_mesh(data, f"g{i}/2/{int(limit)}/ALL")
            assert (ours.n_vertices, ours.n_faces) == (theirs.n_vertices, theirs.n_faces)
            worst[limit] = max(worst[limit], _both_ways(ours, theirs) / m.diagonal)
    assert worst[False] < 1e-6 and worst[True] < 1e-6, worst


# --- the Blender exporter replays creased genomes with holes ------------------------------------------------
RUNNER = Path(__file__).parent / "blender" / "replay_runner.py"


def _read_obj(path: Path) -> PolyMesh:
    v, f = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            f.append([int(x) - 1 for x in line.split()[1:]])
    return PolyMesh.from_faces(np.array(v), f)


@pytest.fixture(scope="session")
def blender_replays(tmp_path_factory):
    if find_host("blender") is None:
        pytest.skip("Blender is not installed (Debian: apt-get install blender)")
    from gsr_cad.exporters.blender import write_blender_script

    work = tmp_path_factory.mktemp("blender_replays")
    genomes = creased_genomes()
    jobs = []
    for i, genome in enumerate(genomes):
        script = write_blender_script(genome, unit_cube(), work / f"g{i}.py", levels=2, use_limit_surface=True)
        jobs.append({"script": str(script), "args": ["--control", str(work / f"c{i}.obj"),
                                                       "--evaluated", str(work / f"e{i}.obj")]})
    (work / "jobs.json").write_text(json.dumps(jobs))
    run_blender(RUNNER, [work / "jobs.json", work / "results.json"], timeout=1500)
    return genomes, work, json.loads((work / "results.json").read_text())


def test_blender_replays_creased_genomes_with_holes(blender_replays):
    """The exporter's script rebuilds the control mesh of 200 genomes with C, R and H (and the paper's ops)
    within 1e-6 of the diagonal, and its modifier (creases set from ours) gives our limit within 1e-5 (at
    infinitely sharp darts as OpenSubdiv evaluates them at the script's quality, see test_creases_match_blender;
    the exact dart limit, the point that converges to, is within 2e-5 of it)."""
    genomes, work, results = blender_replays
    # an edge loop around a tunnel whose sides another edge joins is invalid in our kernel (Blender would split
    # that edge too), so no replay diverges
    assert [r["error"] for r in results] == [None] * len(genomes)
    worst = {"control": 0.0, "limit": 0.0, "exact dart gap": 0.0}
    for i, genome in enumerate(genomes):
        ours = genome_mod.replay(unit_cube(), genome)
        control = _read_obj(work / f"c{i}.obj")
        assert control.faces == ours.faces
        worst["control"] = max(worst["control"], np.abs(control.vertices - ours.vertices).max() / ours.diagonal)
        limit = CatmullClark(ours, 2, dart_isolation=CREASE_QUALITY).limit(ours.vertices)
        theirs = _read_obj(work / f"e{i}.obj")
        assert (theirs.n_vertices, theirs.n_faces) == (limit.n_vertices, limit.n_faces)
        worst["limit"] = max(worst["limit"], _both_ways(limit, theirs) / ours.diagonal)
        exact = get_catmull_clark(ours, 2).limit(ours.vertices)
        worst["exact dart gap"] = max(worst["exact dart gap"],
                                      np.abs(exact.vertices - limit.vertices).max() / ours.diagonal)
    assert worst["control"] < 1e-6 and worst["limit"] < 1e-5 and worst["exact dart gap"] < 2e-5, worst


# --- the Blender exporter replays random region ops -------------------------------------------------------------
def test_blender_replays_random_region_ops(tmp_path):
    """The exporter's script rebuilds the control mesh of 100 random genomes with X and N (Blender's
    extrude_face_region and inset_region) within 1e-6 of the diagonal, every step checked by the script itself."""
    if find_host("blender") is None:
        pytest.skip("Blender is not installed (Debian: apt-get install blender)")
    from gsr_cad.exporters.blender import write_blender_script

    genomes = region_genomes(100)
    jobs = []
    for i, genome in enumerate(genomes):
        script = write_blender_script(genome, unit_cube(), tmp_path / f"g{i}.py", levels=0, use_limit_surface=False)
        jobs.append({"script": str(script), "args": ["--control", str(tmp_path / f"c{i}.obj")]})
    (tmp_path / "jobs.json").write_text(json.dumps(jobs))
    run_blender(RUNNER, [tmp_path / "jobs.json", tmp_path / "results.json"], timeout=900)
    results = json.loads((tmp_path / "results.json").read_text())
    assert [r["error"] for r in results] == [None] * len(genomes)
    worst = 0.0
    for i, genome in enumerate(genomes):
        ours = genome_mod.replay(unit_cube(), genome)
        control = _read_obj(tmp_path / f"c{i}.obj")
        assert control.faces == ours.faces
        worst = max(worst, np.abs(control.vertices - ours.vertices).max() / ours.diagonal)
    assert worst < 1e-6, worst
