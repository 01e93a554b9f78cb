"""Kernel benchmark: how fast the geometry hot paths run, one table for every section.

Sections are functions ``(quick) -> list[Row]`` registered in ``SECTIONS``; a new section (say, op replay)
adds one function and one entry, and its rows land in the same table. A row is one measurement: how many
calls per second, and the time of one call (best of several repeats of a timed loop).

* ``ops``: replay of random 8-op genomes on the cube (all seven op kinds), alone and with the level-3 limit
  evaluation, topology cached or not (goals: under 1 ms cached, under 10 ms uncached).
* ``subdivision``: Catmull-Clark level 3 with limit positions (:func:`limit_mesh`) on meshes of 6 to 500
  faces. *cached*: a fresh PolyMesh with known connectivity each call (key, LRU hit, one sparse product,
  the output PolyMesh); *uncached*: the cache cleared before each call (the control mesh's topology and
  every matrix rebuilt, as when the GA meets a new connectivity); *product*: the sparse product alone
  (``CatmullClark.limit``).
* ``fit``: one round of the refinement's fit on torus cages of 128 and 500 control vertices, 8,000 target
  points: foot points on a new limit surface and hinted by the last round's, the normal equations, the damped
  solve (session 12, against the code before it: 153 -> 109 ms, 17.1 -> 9.6 ms, 43 -> 29 ms, 84 -> 39 ms on
  the 500-vertex cage).

    python benchmarks/kernel.py                      # every section -> benchmarks/results/kernel.md
    python benchmarks/kernel.py --quick --sections subdivision
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from gsr_cad.atomic import write_text
from gsr_cad.geometry import subdivision
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube

sys.path.insert(0, str(Path(__file__).resolve().parent))  # _common, also when this file is loaded by path
from _common import command, environment, markdown_table, print_table  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "kernel.md"


@dataclasses.dataclass
class Row:
    section: str
    case: str
    faces: int
    what: str
    seconds: float  # one call
    note: str = ""

    @property
    def per_second(self) -> float:
        return 1.0 / self.seconds


def timeit(fn: Callable[[], object], budget: float, repeats: int = 5) -> float:
    """Seconds per call of ``fn``: the best of ``repeats`` loops sized to take about ``budget / repeats``."""
    fn()
    start = time.perf_counter()
    fn()
    once = max(time.perf_counter() - start, 1e-7)
    n = max(1, int(budget / repeats / once))
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - start) / n)
    return best


# --- meshes -------------------------------------------------------------------------------------------


def torus(n: int, m: int, triangles: bool = False) -> PolyMesh:
    """An ``n`` x ``m`` quad torus; with ``triangles`` every other quad split in two."""
    u, w = np.meshgrid(np.linspace(0, 2 * np.pi, n + 1)[:-1], np.linspace(0, 2 * np.pi, m + 1)[:-1], indexing="ij")
    v = np.stack([(2 + np.cos(w)) * np.cos(u), (2 + np.cos(w)) * np.sin(u), np.sin(w)], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(n):
        for j in range(m):
            q = [i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m]
            faces += [q[:3], [q[0], q[2], q[3]]] if triangles and (i + j) % 2 else [q]
    return PolyMesh.from_faces(v, faces)


def inset_extruded_cube() -> PolyMesh:
    """The template cube after an inset and an extrusion of its top face (14 faces, irregular vertices)."""
    c = unit_cube()
    ring = c.vertices[[4, 5, 7, 6]] * [0.6, 0.6, 1]
    cap = ring + [0, 0, 0.6]
    faces = [list(f) for f in c.faces[:5]] + [[4, 5, 9, 8], [5, 7, 10, 9], [7, 6, 11, 10], [6, 4, 8, 11]]
    faces += [[8, 9, 13, 12], [9, 10, 14, 13], [10, 11, 15, 14], [11, 8, 12, 15], [12, 13, 14, 15]]
    return PolyMesh.from_faces(np.vstack([c.vertices, ring, cap]), faces)


def studded_cube() -> PolyMesh:
    """The template cube with every face inset and extruded (54 faces, valence 3 to 6): the size of the
    control mesh of a typical genome."""
    c = unit_cube()
    vertices, faces = [c.vertices], []
    for face in c.faces:
        corners = c.vertices[list(face)]
        centre = corners.mean(axis=0)
        ring = centre + 0.6 * (corners - centre)
        cap = ring + 0.4 * centre  # the cube is centred on the origin: centre points outwards
        r = len(np.concatenate(vertices)) + np.arange(4)
        k = r + 4
        vertices += [ring, cap]
        for i in range(4):
            j = (i + 1) % 4
            faces += [[face[i], face[j], r[j], r[i]], [r[i], r[j], k[j], k[i]]]
        faces.append(list(k))
    return PolyMesh.from_faces(np.concatenate(vertices), faces)


def subdivision_meshes(quick: bool) -> dict[str, PolyMesh]:
    meshes = {
        "cube": unit_cube(),
        "inset+extruded cube": inset_extruded_cube(),
        "torus 8x4": torus(8, 4),
        "studded cube": studded_cube(),
        "torus 16x8, half triangles": torus(16, 8, triangles=True),
        "torus 25x20": torus(25, 20),
    }
    if quick:
        meshes = {k: meshes[k] for k in ("cube", "torus 8x4")}
    return meshes


def bench_subdivision(quick: bool) -> list[Row]:
    levels = 3
    budget = 0.05 if quick else 0.5
    rows = []
    rng = np.random.default_rng(0)
    for name, mesh in subdivision_meshes(quick).items():
        fresh = itertools.cycle([PolyMesh(mesh.vertices + rng.normal(0, 0.01, mesh.vertices.shape), mesh.corners,
                                          mesh.offsets) for _ in range(64)])

        def cached(fresh=fresh):
            return subdivision.limit_mesh(next(fresh), levels)

        def uncached(mesh=mesh):
            subdivision.clear_cache()
            return subdivision.limit_mesh(PolyMesh(mesh.vertices, mesh.corners, mesh.offsets), levels)

        cc = subdivision.get_catmull_clark(mesh, levels)
        note = f"{cc.n_faces} faces out, limit matrix {cc.limit_matrix.nnz} nonzeros"
        rows.append(Row("subdivision", name, mesh.n_faces, f"limit L{levels} cached", timeit(cached, budget), note))
        rows.append(Row("subdivision", name, mesh.n_faces, f"limit L{levels} uncached",
                        timeit(uncached, budget, repeats=3)))
        rows.append(Row("subdivision", name, mesh.n_faces, f"L{levels} limit product",
                        timeit(lambda cc=cc, v=mesh.vertices: cc.limit(v), budget)))
    subdivision.clear_cache()
    return rows


def random_genomes(count: int, length: int, seed: int = 0) -> list[tuple]:
    """Seeded valid genomes of exactly ``length`` random ops (all seven kinds) on the unit cube."""
    from gsr_cad.errors import OpError
    from gsr_cad.ops import mesh as mesh_ops

    rng = np.random.default_rng(seed)
    cube = unit_cube()
    out = []
    while len(out) < count:
        state, genome = cube, []
        for _ in range(50 * length):
            op = mesh_ops.random_op(rng, state, cube.diagonal)
            try:
                state = op.apply(state)
            except OpError:
                continue
            genome.append(op)
            if len(genome) == length:
                out.append(tuple(genome))
                break
    return out


def bench_ops(quick: bool) -> list[Row]:
    """Replay of 8-op genomes on the cube, alone and followed by the level-3 limit evaluation.

    *replay*: ops per second over 32 random genomes; *replay + limit L3 cached*: the GA's case when the
    genome's connectivity was met before (topology cache hit); *uncached*: a connectivity never seen.
    """
    from gsr_cad.genome import replay

    genomes = random_genomes(8 if quick else 32, 8)
    cube = unit_cube()
    budget = 0.1 if quick else 1.0
    faces = int(np.median([replay(cube, g).n_faces for g in genomes]))
    cycle = itertools.cycle(genomes)

    def one_replay():
        return replay(cube, next(cycle))

    def cached():
        return subdivision.limit_mesh(one_replay(), 3)

    def uncached():
        subdivision.clear_cache()
        return subdivision.limit_mesh(one_replay(), 3)

    per_genome = timeit(one_replay, budget)
    note = f"median control mesh {faces} faces"
    return [
        Row("ops", "8-op genome replay (per op)", faces, "op replay", per_genome / 8, note),
        Row("ops", "8-op genome replay", faces, "genome replay", per_genome, note),
        Row("ops", "8-op genome", faces, "replay + limit L3 cached", timeit(cached, budget), note),
        Row("ops", "8-op genome", faces, "replay + limit L3 uncached", timeit(uncached, budget, repeats=3), note),
    ]


def _sampled_rows(surface) -> object:
    """One fit round's area samples of a new placement and their rows (the layout's, after its first round)."""
    hits, _ = surface.samples()
    return surface.rows(hits)


def bench_fit(quick: bool) -> list[Row]:
    """The parts of one round of the refinement's fit on a torus cage (regular) and a split cube (valence-3
    corners, refined locally to depth 5), the target points their limit surface's points moved off it (0.02):
    the foot points from scratch (a new limit surface: its search trees built) and from the last round's (a
    fit's later rounds), the area samples and their rows, the normal equations of the foot points and one damped
    solve of them."""
    from gsr_cad.geometry.limit_surface import LimitSurface, get_layout
    from gsr_cad.reconstruct.surface import _normal_equations, _solve_spd

    budget = 0.2 if quick else 2.0
    rows = []
    rng = np.random.default_rng(0)
    cube = unit_cube()
    split = subdivision.get_catmull_clark(cube, 2 if quick else 4, "all").refine(cube.vertices)
    cases = {"torus 16x8": torus(16, 8), f"cube split {2 if quick else 4}x": split}
    if not quick:
        cases["torus 25x20"] = torus(25, 20)
    for name, mesh in cases.items():
        count = 2000 if quick else 8000
        layout = get_layout(mesh, "all", 4 if name.startswith("torus") else 5)
        surface = LimitSurface(layout, mesh.vertices)
        on = surface.samples()[0].point
        points = on[rng.integers(0, len(on), count)] + rng.normal(0.0, 0.02, (count, 3))
        hits = surface.closest(points)
        A = surface.rows(hits)
        note = f"{count} target points, {mesh.n_vertices} control vertices"
        H, g = _normal_equations(A, hits.normal, points, np.full(count, 1.0 / count))
        M = (H + 1e-3 * float(H.diagonal().mean()) * sp.identity(H.shape[0], format="csc")).tocsc()
        rows.append(Row("fit", name, mesh.n_faces, "foot points, new surface",
                        timeit(lambda: LimitSurface(layout, mesh.vertices).closest(points), budget, 3), note))
        rows.append(Row("fit", name, mesh.n_faces, "foot points, hinted",
                        timeit(lambda: surface.closest(points, hits), budget), note))
        rows.append(Row("fit", name, mesh.n_faces, "area samples and their rows",
                        timeit(lambda: _sampled_rows(LimitSurface(layout, mesh.vertices)), budget), note))
        rows.append(Row("fit", name, mesh.n_faces, "normal equations",
                        timeit(lambda: _normal_equations(A, hits.normal, points, np.full(count, 1.0 / count)),
                               budget), note))
        rows.append(Row("fit", name, mesh.n_faces, "damped solve", timeit(lambda: _solve_spd(M, g), budget), note))
    return rows


SECTIONS: dict[str, Callable[[bool], list[Row]]] = {"subdivision": bench_subdivision, "ops": bench_ops,
                                                    "fit": bench_fit}


# --- output -------------------------------------------------------------------------------------------

HEADER = ("section", "case", "faces", "measure", "per second", "one call", "note")
RIGHT = ("faces", "per second", "one call")


def _duration(seconds: float) -> str:
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} µs"
    if seconds < 1:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def _cells(r: Row) -> tuple[str, ...]:
    return (r.section, r.case, str(r.faces), r.what, f"{r.per_second:,.0f}", _duration(r.seconds), r.note)


def markdown(rows: list[Row], argv: list[str]) -> str:
    lines = [
        "# Kernel benchmark",
        "",
        command("kernel.py", argv),
        "",
        f"{environment()}. One call: best of several timed loops.",
        "",
        *markdown_table(HEADER, [_cells(r) for r in rows], RIGHT),
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two small cases per section, short timing loops")
    parser.add_argument("--sections", default=",".join(SECTIONS),
                        help=f"comma-separated sections (default all: {', '.join(SECTIONS)})")
    parser.add_argument("--out", type=Path, default=RESULTS, help=f"markdown output (default {RESULTS})")
    args = parser.parse_args(argv)
    names = [s for s in args.sections.split(",") if s]
    unknown = sorted(set(names) - set(SECTIONS))
    if unknown:
        parser.error(f"unknown section(s) {', '.join(unknown)}; choose from {', '.join(SECTIONS)}")
    rows = [row for name in names for row in SECTIONS[name](args.quick)]
    print_table("kernel benchmark", HEADER, [_cells(r) for r in rows], RIGHT, [(r.section, r.case) for r in rows],
                width=140)
    write_text(args.out, markdown(rows, argv))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
