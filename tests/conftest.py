"""Shared fixtures and helpers: run the CLI in-process and capture its output; test meshes; OpenSubdiv's
Catmull-Clark (through lagrange) as a reference. Test modules import the helpers with ``from conftest import ...``."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from gsr_cad.cli import main
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.reconstruct import second_path

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "samples"


@dataclasses.dataclass
class CliRun:
    code: int
    out: str
    err: str


os.environ[second_path.ENV] = "1"
"""``refine_workers`` 0 is one process here and in the runs the tests start: the suite's xdist workers fill the
machine's CPUs, and a refinement's second process beside each would slow them. Tests of the second process ask for
it (``refine_workers=2``) or clear the variable."""


HEAVY_FIRST = ("test_surface_leads.py", "test_surface_refine.py", "test_surface_reconstruct.py",
               "test_surface_blocks.py", "test_surface_sharp.py", "test_export_curve_forms.py", "test_surface_cli.py",
               "test_export_surface_hosts.py", "test_signals.py", "test_surface_front.py", "test_surface_budget.py",
               "test_huge_inputs.py", "test_batch.py", "test_resume.py", "test_surface_history_moves.py",
               "test_export_surface_step.py")
"""Modules of long tests (runs of the refinement, host round trips, signals sent to whole runs), longest first
(``--durations``), collected before the others: xdist hands out tests in collection order, and long ones last left
a worker idle while the other finished them."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {name: k for k, name in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(HEAVY_FIRST)))


@pytest.fixture
def gsr(capsys):
    """Call ``gsr`` with a list of arguments; returns exit code, stdout and stderr."""

    def run(*args: str) -> CliRun:
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return CliRun(code, captured.out, captured.err)

    return run


def torus(n: int = 6, m: int = 4) -> PolyMesh:
    """An ``n`` x ``m`` quad torus (radii 2 and 1) around the z axis."""
    u, w = np.meshgrid(np.linspace(0, 2 * np.pi, n + 1)[:-1], np.linspace(0, 2 * np.pi, m + 1)[:-1], indexing="ij")
    v = np.stack([(2 + np.cos(w)) * np.cos(u), (2 + np.cos(w)) * np.sin(u), np.sin(w)], axis=-1).reshape(-1, 3)
    faces = [[i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m]
             for i in range(n) for j in range(m)]
    return PolyMesh.from_faces(v, faces)


def pentaprism(top: float = 0.6, height: float = 1.2) -> PolyMesh:
    """Closed, planar faces: a unit pentagon, its copy scaled by ``top`` at ``height``, and five quads."""
    t = np.linspace(0, 2 * np.pi, 6)[:-1]
    ring = np.c_[np.cos(t), np.sin(t)]
    v = np.r_[np.c_[ring, np.zeros(5)], np.c_[ring * top, np.full(5, height)]]
    faces = [[4, 3, 2, 1, 0], [5, 6, 7, 8, 9]] + [[i, (i + 1) % 5, (i + 1) % 5 + 5, i + 5] for i in range(5)]
    return PolyMesh.from_faces(v, faces)


def opensubdiv(mesh: PolyMesh, levels: int, *, limit: bool = True, boundary: str = "EdgeOnly") -> PolyMesh:
    """OpenSubdiv's Catmull-Clark mesh of ``mesh`` after ``levels`` (limit positions with ``limit``), through
    lagrange; ``boundary`` names a ``VertexBoundaryInterpolation``. Skips the test when lagrange is missing."""
    lagrange = pytest.importorskip("lagrange")
    from lagrange.subdivision import SchemeType, VertexBoundaryInterpolation, subdivide_mesh

    m = lagrange.SurfaceMesh()
    m.add_vertices(np.array(mesh.vertices))
    for f in mesh.faces:
        m.add_polygon(np.array(f, dtype=np.uint32))
    out = subdivide_mesh(m, num_levels=levels, scheme=SchemeType.CatmullClark, use_limit_surface=limit,
                         vertex_boundary_interpolation=getattr(VertexBoundaryInterpolation, boundary))
    return PolyMesh.from_faces(np.array(out.vertices), [out.get_facet_vertices(f) for f in range(out.num_facets)])


def grower(target):
    """A surface problem on ``target`` (the placed cube template, 4,000 points) measured and capped as the
    refinement measures and caps: what a designer's start (module starts) is built and gated on."""
    from gsr_cad.reconstruct.config import SurfaceConfig
    from gsr_cad.reconstruct.surface import SurfaceProblem, place_template

    config = SurfaceConfig()
    template = place_template("cube", target, config).mesh
    problem = SurfaceProblem(target, dataclasses.replace(config, max_target_points=4000), template, exact_back=True,
                             exact_facets=True)
    problem.max_faces = config.refine_max_faces
    return problem


def failures(checks) -> list[str]:
    """The exporter checks that failed (skipped ones are not failures), as ``check: detail``."""
    return [f"{c.check}: {c.detail}" for c in checks if c.passed is False]


def statuses(checks) -> dict[str, str]:
    """Each exporter check's status by check name."""
    return {c.check: c.status for c in checks}
