"""The practitioner's baseline: a quad remesh of the target (QuadriFlow, via ``pyquadriflow``) used as the
Catmull-Clark cage, its vertices fitted to the target by our own least-squares polish (the same fitter and
the same two-sided distances as ``gsr surface``).

    python benchmarks/baseline_quadremesh.py TARGET.obj --vertices 40
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from gsr_cad.errors import GsrError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.surface import SurfaceProblem, surface_metrics

FIT_ROUNDS = 30


@dataclasses.dataclass
class Baseline:
    """A remeshed and fitted cage and its metrics (``None`` when the remesher gave no usable quad mesh)."""

    control: PolyMesh | None
    metrics: dict
    seconds: float


def quad_remesh(target: SurfaceTarget, faces: int, seed: int = 0) -> PolyMesh:
    """QuadriFlow's quad remesh of a mesh target with about ``faces`` quads."""
    from pyQuadriFlow.pyQuadriFlow import pyquadriflow  # the bench extra

    try:
        out = pyquadriflow(int(faces), int(seed), target.points.tolist(), target.faces.tolist(), False, False, False,
                           False, False)
    except Exception as exc:  # the wrapper raises a bare Exception on QuadriFlow's errors
        raise GsrError(f"QuadriFlow failed: {exc}") from None
    vertices = np.asarray(out["vertices"], dtype=np.float64)
    quads = np.asarray(out["faces"], dtype=np.int64)
    if vertices.ndim != 2 or len(quads) == 0:
        raise GsrError("QuadriFlow returned no quads")
    used, local = np.unique(quads, return_inverse=True)
    return PolyMesh.from_faces(vertices[used], local.reshape(-1, 4).tolist())


def baseline(target: SurfaceTarget, vertices: int, config: SurfaceConfig | None = None) -> Baseline:
    """The quad remesh whose vertex count is nearest ``vertices`` (a few face budgets tried; a closed quad
    mesh has about as many faces as vertices), fitted with ``FIT_ROUNDS`` polish rounds."""
    config = config or SurfaceConfig()
    start = time.perf_counter()
    best = None
    for faces in sorted({max(6, int(vertices * f)) for f in (0.8, 1.0, 1.25)}):
        try:
            cage = quad_remesh(target, faces)
        except (GsrError, ValueError, IndexError):
            continue
        if best is None or abs(cage.n_vertices - vertices) < abs(best.n_vertices - vertices):
            best = cage
    if best is None:
        return Baseline(None, {}, time.perf_counter() - start)
    try:  # a remesh the subdivision refuses (non-manifold) is no baseline
        problem = SurfaceProblem(target, config, best)
        fitted = best.with_vertices(problem.fit(best, FIT_ROUNDS, min_gain=0.999)[0])
        return Baseline(fitted, surface_metrics(fitted, target, config), time.perf_counter() - start)
    except GsrError:
        return Baseline(None, {}, time.perf_counter() - start)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("target")
    ap.add_argument("--vertices", type=int, required=True)
    args = ap.parse_args(argv)
    b = baseline(surface_target(args.target), args.vertices)
    m = b.metrics
    if b.control is None:
        print("no quad remesh")
        return 1
    print(f"{b.control.n_vertices} vertices: data->fit {m['data_to_fit_mean']:.3g}/{m['data_to_fit_max']:.3g}, "
          f"fit->data {m['fit_to_data_mean']:.3g}/{m['fit_to_data_max']:.3g}, {b.seconds:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
