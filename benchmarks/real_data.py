"""Real-data surface benchmark: public meshes shipped in installed packages, gsr against the quad-remesh
baseline (:mod:`baseline_quadremesh`) at the same number of control vertices.

Targets, genus 0 (holes are issue 13): pymeshlab's sample meshes (a scan of a bone, the Stanford bunny (56k faces),
an airplane: scans and organic models) and OpenSCAD's bundled example parts rendered to STL by ``openscad`` (CAD
parts: a lettered block, a linear extrusion, text on a cube, a rounded foot under a tube, a relief of three stacked
extrusions; and every one of the "Old" and "Parametric" examples that renders to one closed genus-0 piece: a rounded
die with dimples, two intersections of extruded DXF profiles, an intersection of two height maps, a pyramid, a
sphere with an imprint, an intersection of rotated bars, a comb of cones, an oval sign with raised text); and
FreeCAD's IDF library of electronic packages, STEP models tessellated by OpenCascade (:func:`freecad_parts`: an
electrolytic capacitor, an E and an I ferrite core, an inductor, SMD packages with their gull-wing leads: MSOP-10,
TSSOP-8, SOT-323, DPAK, an SOD-523 diode, a 4-pin optocoupler), whichever are installed. pymeshlab's 10k-face bunny
and cow and OpenSCAD's CSG, logo and GEB examples are left out here: their genus (estimated by ``target_genus``) is
not 0; so are OpenSCAD's animation example (not a closed manifold) and assert example (many separate cubes). A
target of several disjoint pieces says so in its name cell (``linear_extrude``: four solids, which one closed cage
webs between). Then issue 13's genus targets (``genus_creases.genus_targets``: built nut, torus, ring, frame and the
public genus >= 1 meshes), with the genus template and the crease ops, their genus in the name cell. No download at
run time. ``--jobs 2`` runs two targets at a time (one core each, each refinement on one process) and prints the
same table in the same order; ``--jobs 1`` (the default) runs one at a time, its refinement growing the placed
template on a second core beside the search's winner (``--refine-workers``).

Columns: target, its faces, gsr's control vertices and ops, data->fit and fit->data mean/max (fractions
of the bounding-box diagonal, on the exact limit surface, see ``gsr_cad.reconstruct.surface``), seconds,
then the baseline's vertices and the same distances, and gsr's accuracy/complexity front (control
vertices: mean of both directions, exact, as result.json's front records it; then ``/`` the baseline's mean of
both directions, exact, at the vertex count QuadriFlow gives nearest it (23 face budgets from 0.5x to 1.6x scanned,
:data:`baseline_quadremesh.BUDGETS`), in parentheses; ``--no-front-baselines`` skips those).

    python benchmarks/real_data.py --max-seconds 300      # -> benchmarks/results/real_data.md
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from gsr_cad.atomic import write_text
from gsr_cad.plots import run_length
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.second_path import refine_workers
from gsr_cad.reconstruct.surface import reconstruct_surface, surface_metrics

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import environment, load_average  # noqa: E402
from baseline_quadremesh import baseline  # noqa: E402
from genus_creases import GENUS_OPTIONS, genus_targets  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "real_data.md"
PYMESHLAB_MESHES = ("bone.ply", "bunny.obj", "airplane.obj")
OPENSCAD_PARTS = ("Basics/LetterBlock.scad", "Basics/linear_extrude.scad", "Basics/text_on_cube.scad",
                  "Advanced/offset.scad", "Advanced/surface_image.scad", "Old/example006.scad", "Old/example007.scad",
                  "Old/example010.scad", "Old/example011.scad", "Old/example012.scad", "Old/example013.scad",
                  "Old/example014.scad", "Old/example019.scad", "Parametric/sign.scad")
FREECAD_IDF = Path("/usr/share/freecad/Mod/Idf/Idflibs")
FREECAD_PARTS = ("CAP_50SGV_8_10", "EPL22_6_16", "I22_2_5_16", "MSOP_10", "RLF_7030", "SOD_523", "SOT428_DPAK",
                 "SOT_323_3", "TCMT1107_4", "TSS0P_8")
"""The IDF library's parts that are one closed genus-0 solid (FreeCAD 0.20's files, Debian 12: the others are
several solids, a body and its leads apart, or have holes)."""
TESSELLATION = 1e-3
"""The tessellation's chord tolerance, a fraction of the part's bounding-box diagonal."""


def targets(work: Path, only: list[str] | None = None) -> list[Path]:
    """The installed public meshes (module docstring), OpenSCAD parts rendered into ``work``; with ``only``,
    those whose file names it lists (the others are not rendered)."""
    out = []
    try:
        import pymeshlab

        folder = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes"
        out += [folder / name for name in PYMESHLAB_MESHES if (folder / name).exists()]
    except ImportError:
        pass
    scad = Path("/usr/share/openscad/examples")
    if shutil.which("openscad") and scad.is_dir():
        for part in OPENSCAD_PARTS:
            stl = work / (Path(part).stem + ".stl")
            if only and stl.name not in only:
                continue
            try:
                subprocess.run(["openscad", "-o", str(stl), str(scad / part)], check=True, capture_output=True,
                               timeout=300)
                out.append(stl)
            except (subprocess.SubprocessError, OSError):
                continue
    return out


def freecad_parts(work: Path, only: list[str] | None = None) -> list[Path]:
    """FreeCAD's bundled IDF library parts (:data:`FREECAD_PARTS`, STEP models of electronic packages) that are one
    closed genus-0 solid, tessellated by OpenCascade (build123d, the cad extra) into ``work`` as STL, to within
    :data:`TESSELLATION` of their diagonal; none without FreeCAD's data or build123d."""
    if not FREECAD_IDF.is_dir():
        return []
    try:
        from build123d import export_stl, import_step
    except ImportError:
        return []
    out = []
    for name in FREECAD_PARTS:
        stl = work / f"{name}.stl"
        if (only and stl.name not in only) or not (FREECAD_IDF / f"{name}.stp").is_file():
            continue
        try:
            shape = import_step(FREECAD_IDF / f"{name}.stp")
            box = shape.bounding_box()
            export_stl(shape, str(stl), tolerance=TESSELLATION * box.diagonal, angular_tolerance=0.1)
            out.append(stl)
        except Exception:  # noqa: BLE001 - OCCT raises many kinds; a part it cannot read is left out
            continue
    return out


def _ops(letters: str) -> str:
    """The op letters run-length encoded (a long history comes encoded already: "L9 V296")."""
    return run_length(letters) or "-"


def parts(target) -> int:
    """How many disjoint pieces (edge-connected components of its triangles) a mesh target has: one closed
    cage must web between several, so its surface -> target distance cannot reach the pieces' own."""
    f = np.asarray(target.faces)
    n = len(target.points)
    graph = sp.coo_matrix((np.ones(f.size), (f.ravel(), np.roll(f, 1, axis=1).ravel())), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return len(np.unique(labels[np.unique(f)]))


def _front_point(target, vertices: int, distance: float, with_baseline: bool) -> str:
    """One front point, ``V: distance`` (its exact mean of both directions, measured here as the baseline's
    is), and with ``with_baseline`` the baseline's mean of both directions at the vertex count QuadriFlow
    gives nearest it (``/ -`` when none)."""
    text = f"{vertices}: {distance:.1e}"
    if not with_baseline:
        return text
    b = baseline(target, vertices)
    if b.control is None:
        return text + " / -"
    return text + f" / {b.metrics['symmetric_distance']:.1e} ({b.control.n_vertices})"


def _row(name: str, target, options: dict, args: argparse.Namespace) -> str:
    """One table row: gsr on ``target`` (with ``options``), the baseline at its vertex count and its front."""
    start = time.perf_counter()
    result = reconstruct_surface(target, seed=args.seed, max_seconds=args.max_seconds,
                                 refine_workers=args.refine_workers, **options)
    m = result.metrics
    pieces = parts(target)
    if pieces > 1:
        name += f" ({pieces} parts)"
    if options:
        name += (f" (genus {m['target_genus']} / {m['result_genus']}"
                 f"{'' if m['target_genus'] == m['result_genus'] else ' !'})")
    seconds = time.perf_counter() - start
    if args.metrics is not None:  # the whole result.json metrics, to attribute the time and read the levels
        write_text(args.metrics / f"{Path(name.split(' ')[0]).stem}.json",
                   json.dumps({"wall_seconds": seconds, **m}, indent=1, default=str))
    b = baseline(target, m["n_control_vertices"])
    bm = b.metrics
    base = ("| - | - | - |" if b.control is None else
            f"| {b.control.n_vertices} | {bm['data_to_fit_mean']:.2e} / {bm['data_to_fit_max']:.2e} "
            f"| {bm['fit_to_data_mean']:.2e} / {bm['fit_to_data_max']:.2e} |")
    # every front cage measured like the baseline (the run measures them only while its time lasts, and an
    # unmeasured point's ranking distance leaves out a mesh target's chord sag)
    front = [(n, surface_metrics(result.front_control(i), target, SurfaceConfig())["symmetric_distance"])
             for i, (n, _, _) in enumerate(result.front)]
    base += " " + ", ".join(_front_point(target, n, d, args.front_baselines) for n, d in front) + " |"
    return (f"| {name} | {len(target.faces)} | {m['n_control_vertices']} | {_ops(m['ops'])} "
            f"| {m['data_to_fit_mean']:.2e} / {m['data_to_fit_max']:.2e} "
            f"| {m['fit_to_data_mean']:.2e} / {m['fit_to_data_max']:.2e} | {seconds:.0f} " + base)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-seconds", type=float, default=300.0, help="search budget per target")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--only", nargs="*", help="target names to run (file names; genus targets by name)")
    ap.add_argument("--jobs", type=int, default=1, help="targets run at a time, in separate processes")
    ap.add_argument("--refine-workers", type=int, choices=(0, 1, 2), default=None,
                    help="processes each target's refinement grows on (default: 1 with --jobs above 1, so that "
                         "targets run side by side do not share a CPU; else 0, two where two CPUs are free)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--no-front-baselines", dest="front_baselines", action="store_false",
                    help="skip the baseline at every front point (only at gsr's result)")
    ap.add_argument("--metrics", type=Path, help="folder to write each target's result metrics to (JSON)")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error("--jobs must be at least 1")
    if args.refine_workers is None:
        args.refine_workers = 1 if args.jobs > 1 else 0
    if args.metrics is not None:
        args.metrics.mkdir(parents=True, exist_ok=True)
    header = ("| target | faces | gsr V | ops | data->fit mean / max | fit->data mean / max | s "
              "| baseline V | data->fit mean / max | fit->data mean / max | front (V: distance / baseline (its V)) |")
    lines = ["# Real-data surface benchmark", "", environment(), f"Load average at start: {load_average()}; "
             f"{args.jobs} target(s) at a time, each refined on "
             f"{refine_workers(args.refine_workers)} process(es).", "",
             f"Search budget {args.max_seconds:g} s per target (`--max-seconds`), seed {args.seed}; baseline `-`: "
             "QuadriFlow gave no quad mesh near that vertex count.", "", header, "|" + "---|" * 11]
    with tempfile.TemporaryDirectory() as tmp:
        paths = targets(Path(tmp), args.only) + freecad_parts(Path(tmp), args.only)
        runs = [(path.name, surface_target(path), {}) for path in paths]
        runs += [(name, target, GENUS_OPTIONS) for name, target in genus_targets(Path(tmp)).items()]
        runs = [run for run in runs if not args.only or run[0] in args.only]
        rows: list[str | None] = [None] * len(runs)
        with ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = {pool.submit(_row, *run, args): i for i, run in enumerate(runs)}
            for future in as_completed(futures):
                rows[futures[future]] = future.result()
                print(rows[futures[future]], flush=True)
                done = [row for row in rows if row is not None]  # rows as they land (a bounded run may be cut)
                write_text(args.out, "\n".join(lines + done) + "\n")
    write_text(args.out, "\n".join(lines + [row for row in rows if row is not None]) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
