"""STEP exports of random creased genomes with holes (issue 13): how many become a valid closed solid on the
limit surface, how many the exporter refuses, and why.

The genomes are the first ``--count`` of the Blender run's generator (``creased_genomes`` in
tests/test_blender_subsurf.py: random ops over every surface op on the unit cube, at least one hole and one crease,
at most 80 faces). Each is exported by the STEP exporter (patch tolerance 1e-4 of the diagonal, patch_max_level 5
unless given) and, when written, validated by reading it back with OCP (BRepCheck_Analyzer valid, one closed
shell and solid, positive volume, OCCT's projection of exact limit points within the stated deviation). Columns:
faces, creases, outcome (``solid``, ``refused`` with the reason, ``invalid`` with the failed checks), the patches'
deviation over the diagonal, the fitting level, exact/fitted patches and the seconds.

    python benchmarks/step_creases.py --count 50          # -> results/step_creases.md (table appended)
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ExportError
from gsr_cad.exporters.model import surface_model
from gsr_cad.exporters.step import StepExporter
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.reconstruct.result import Result

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from _common import load_average  # noqa: E402
from test_blender_subsurf import creased_genomes  # noqa: E402


def genome_result(genome: tuple, max_level: int) -> Result:
    """A surface Result as `gsr surface` saves it, for ``genome`` on the unit cube."""
    cube = unit_cube()
    config = {"levels": 2, "boundary": "all", "patch_max_level": max_level,
              "template": {"source": "cube", "vertices": cube.vertices.tolist(), "faces": [list(f) for f in cube.faces]}}
    return Result(kind="surface", config=config, seed=None, genome=tuple(genome), metrics={}, history=[],
                  control_mesh=genome_mod.replay(cube, genome))


def run_one(index: int, genome: tuple, max_level: int, work: Path) -> dict:
    result = genome_result(genome, max_level)
    mesh = result.control_mesh
    row = {"genome": index, "faces": mesh.n_faces, "creases": len(mesh.creases), "deviation": None, "level": None,
           "patches": ""}
    exporter = StepExporter()
    start = time.perf_counter()
    try:
        path = exporter.export_surface(result, work, f"g{index}")[0]
    except ExportError as exc:
        row.update(outcome="refused", why=str(exc).splitlines()[0], seconds=time.perf_counter() - start)
    else:
        checks = exporter.validate_surface(path, result)
        bad = [c.check for c in checks if c.status != "pass"]
        row.update(outcome="invalid" if bad else "solid", why=", ".join(bad), seconds=time.perf_counter() - start)
    ps = surface_model(result).__dict__.get("patches")  # the model's cached patches, when they were fitted
    if ps is not None:
        row.update(deviation=ps.max_deviation / ps.diagonal, level=ps.level,
                   patches=f"{ps.n_exact}/{len(ps.patches) - ps.n_exact}")
    elif found := re.search(r"deviate by ([0-9.e+-]+)", row["why"]):
        row.update(deviation=float(found.group(1)), level=max_level)
    return row


def _fmt(x: float | None) -> str:
    return "-" if x is None else f"{x:.2e}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=50)
    parser.add_argument("--max-level", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "step_creases_table.md")
    args = parser.parse_args()
    genomes = creased_genomes()[:args.count]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, g in enumerate(genomes):
            rows.append(run_one(i, g, args.max_level, Path(tmp)))
            r = rows[-1]
            print(i, r["outcome"], r["deviation"], r["level"], f"{r['seconds']:.1f}s", r["why"], flush=True)
    counts = {k: sum(r["outcome"] == k for r in rows) for k in ("solid", "refused", "invalid")}
    lines = [f"{len(rows)} genomes, patch_max_level {args.max_level}, load {load_average()}: "
             f"{counts['solid']} valid solids, {counts['refused']} refused, {counts['invalid']} invalid", "",
             "| genome | faces | creases | outcome | deviation | level | exact/fitted | s | why |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['genome']} | {r['faces']} | {r['creases']} | {r['outcome']} | {_fmt(r['deviation'])} | {r['level']} "
              f"| {r['patches']} | {r['seconds']:.1f} | {r['why']} |" for r in rows]
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines[:1]))


if __name__ == "__main__":
    main()
