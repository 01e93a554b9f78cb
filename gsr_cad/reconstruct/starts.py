"""A designer's start for the refinement's second path: the body's box with the legs (module :mod:`.leads`) or the
blocks (module :mod:`.blocks`) read off the target's voxel solid, where it pays.

Each start is gated twice, every cage fitted alike (:data:`GATE_ROUNDS`):
* on its own body's box (the same loops, no legs or blocks): it gains at least :data:`MIN_GAIN` (log distance per
  log control vertices; a split gains about 0.3-0.5) and :data:`MIN_RATIO`, so that a blob or a slotted part
  whose "leads" are ribs keeps the plain template;
* on the template's box split as often as the legs' (what the second path grows otherwise): it is closer, and
  gains :data:`MIN_GAIN` per added vertex where it has more.
Of two kept, the closer stands. Its edges along the part's edges are then creased where that brings it closer
(module :mod:`.sharp`: an E core's body and prongs, 144 control vertices, 2.7e-3 of the diagonal both ways smooth,
8.3e-4 creased).

The body with its first legs or blocks are points of the front between the body and the start
(:func:`start_prefixes`): the start is grown as a whole, and the front would otherwise jump from the other paths'
cages to it."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..errors import GsrError
from ..geometry.polymesh import SHARPNESS_INFINITE, PolyMesh
from ..ops.mesh import Crease, Extrude, Inset, TranslateVertex
from .blocks import BLOCK_PATH, block_genomes, find_blocks
from .leads import LEAD_PATH, SPLITS, cube_frame, find_leads, lead_genomes
from .refine import _reach_partial, apply_ops, fill_counts, split_all
from .sharp import sharpened

MIN_GAIN = 0.5
"""The least gain: as much as the best splits gain per added vertex (TSSOP-8's eight legs, 0.59 at the gate, grew
to 678 control vertices at 7.2e-4 of the diagonal both ways, where the baseline has 2.0e-3 at 755)."""
MIN_RATIO = 1.5
"""And the start must bring the cage this many times closer (a single short "lead" adds few vertices: LetterBlock's
letter, 98 -> 114 control vertices, 2.1e-2 -> 1.7e-2 of the diagonal, a gain of 1.5 that is no leg)."""
GATE_ROUNDS = 20
PREFIX_ROUNDS = 40
"""Rounds of the adaptive fit each prefix of a start gets (:func:`start_prefixes`)."""
START_OPS = frozenset("VLIE")
"""The ops a start may hold must all be allowed (``op_kinds``); a block's region extrusion (X) is the face
extrude (E) of a selection of faces, as a designer extrudes in Blender."""


def _fitted(problem, genome: tuple, deadline: float | None) -> tuple[int, float, PolyMesh] | None:
    """``(control vertices, distance, the fitted cage)`` of the cage ``genome`` builds, fitted :data:`GATE_ROUNDS`;
    None when the fit fails or time runs out."""
    if deadline is not None and time.perf_counter() >= deadline:
        return None
    try:
        mesh = problem.control_mesh(genome)
        vertices, cost = problem.fit(mesh, GATE_ROUNDS, min_gain=1.0, adaptive=True, deadline=deadline, settle=True)
    except GsrError:
        return None
    return (mesh.n_vertices, cost, mesh.with_vertices(vertices)) if math.isfinite(cost) and cost > 0 else None


def _gate(problem, genomes: tuple[tuple, tuple], deadline: float | None
          ) -> tuple[dict[str, Any], PolyMesh] | None:
    """The two cages ``genomes`` build (the body's box, the start) fitted alike, whether the start gains on
    the box, and the start's fitted cage; None when a fit fails or time runs out."""
    body = _fitted(problem, genomes[0], deadline)
    start = _fitted(problem, genomes[1], deadline) if body is not None else None
    if start is None or start[0] <= body[0]:
        return None
    gain = math.log(body[1] / start[1]) / math.log(start[0] / body[0])
    return {"body_vertices": body[0], "body_distance": body[1], "vertices": start[0], "distance": start[1],
            "gain": gain, "kept": bool(gain >= MIN_GAIN and start[1] * MIN_RATIO <= body[1])}, start[2]


def structured_start(problem, deadline: float | None = None, max_faces: int | None = None
                     ) -> tuple[tuple, dict[str, Any]] | None:
    """``(the start's genome, what was measured)``; the genome is the start's ops, its creases and the moves to its
    fit, so that a path with no time to fit it again starts from it as fitted (result.json ``lead_start``: ``path``,
    the kept start's refinement path or None, ``body_ops`` how many of its ops build its body (``prefixes``, added by
    the refinement: :func:`start_prefixes`' points), and per kind ``leads`` / ``blocks`` what was found and the
    gate's figures); the genome is empty when no start is kept. None when the template is
    not a placed cube, nothing is found, ops a start needs are not allowed (:data:`START_OPS`) or every start found
    has more faces than ``max_faces`` (the refinement's face budget: such a start is no cage it may grow)."""
    axes = cube_frame(problem.template)
    if axes is None or not START_OPS <= set(problem.config.op_kinds):
        return None
    started = time.perf_counter()
    info: dict[str, Any] = {"path": None, "leads": None, "blocks": None}
    starts = []
    leads = find_leads(problem.target)
    if leads is not None and (built := lead_genomes(problem, leads)) is not None:
        grown = sum(isinstance(op, Inset) for op in built[1][len(built[0]):])
        starts.append((LEAD_PATH, "leads", built, {"found": len(leads.leads), "grown": grown}))
    blocks = find_blocks(problem.target, axes)
    if blocks is not None and (made := block_genomes(problem, blocks, axes)) is not None:
        starts.append((BLOCK_PATH, "blocks", made[:2], {"found": len(blocks.blocks), "grown": made[2]}))
    if max_faces is not None:
        starts = [start for start in starts if all(_within(problem, g, max_faces) for g in start[2][:2])]
    if not starts:
        return None
    best: tuple[float, str, tuple, PolyMesh] | None = None
    reference: tuple[int, float, PolyMesh] | None = None
    for path, kind, genomes, found in starts:
        gated = _gate(problem, genomes, deadline)
        if gated is None:
            continue
        info[kind] = figures = {**found, **gated[0]}
        if figures["kept"] and reference is None:
            reference = _template_box(problem, deadline)
            if reference is not None:
                info["template_vertices"], info["template_distance"] = reference[:2]
        if figures["kept"] and reference is not None:
            # the template's box split as often is what the second path grows otherwise: the start must gain on it
            # too (offset.stl's five blocks, 162 vertices at 3.0e-3 of the diagonal, kept on their body's box
            # alone, took the place of the template's path, 74 vertices at 1.5e-3)
            n, cost = reference[:2]
            gain = None if figures["vertices"] <= n else math.log(cost / figures["distance"]) / math.log(
                figures["vertices"] / n)
            figures["gain_on_template"] = gain
            figures["kept"] = figures["distance"] < cost and (gain is None or gain >= MIN_GAIN)
        if figures["kept"] and (best is None or figures["distance"] < best[0]):
            best = (figures["distance"], path, genomes[1], gated[1], len(genomes[0]))
    if best is None:
        info["seconds"] = time.perf_counter() - started
        return (), info
    info["path"], info["body_ops"] = best[1], best[4]
    genome = best[2]
    # its edges slid onto the blocks' sides run along the part's edges: creased where that brings it closer
    sharp = sharpened(problem, problem.control_mesh(genome), best[3].vertices, best[0], GATE_ROUNDS, deadline)
    fitted = best[3].vertices
    if sharp is not None:
        genome += sharp[0]
        fitted = sharp[1]
        info["creases"], info["creased_distance"] = len(sharp[0]), sharp[2]
    # the moves to its fit too: a path short of time starts from the cage as fitted, not as built (a gull-wing
    # part in a 30 s refinement: the legs' start taken unfitted, 1.4e-2 of the diagonal, where its fit is 2.1e-3)
    # (where some refuse, past the deadline or folding a face, the ones that replay, if they bring it closer)
    built = problem.control_mesh(genome)
    moves, reached, refused = problem._moves(built, fitted, deadline)
    if moves and (not refused or problem.fit(reached, 0)[1] < problem.fit(built, 0)[1]):
        genome += tuple(moves)
    info["seconds"] = time.perf_counter() - started
    return genome, info


def _within(problem, genome: tuple, max_faces: int) -> bool:
    """Whether ``genome``'s cage has at most ``max_faces`` faces (a cage the problem's face limit refuses has not)."""
    try:
        return problem.control_mesh(genome).n_faces <= max_faces
    except GsrError:
        return False


def _template_box(problem, deadline: float | None) -> tuple[int, float, PolyMesh] | None:
    """The template split :data:`~gsr_cad.reconstruct.leads.SPLITS` times, fitted as the gate fits: ``(control
    vertices, distance, the fitted cage)``, or None when it does not split or time runs out."""
    genome: tuple = ()
    state = problem.template
    for _ in range(SPLITS):
        split = split_all(state, state)
        if split is None:
            return None
        genome += split[0]
        state = split[1]
    return _fitted(problem, genome, deadline)


def start_prefixes(problem, genome: tuple, body_ops: int, deadline: float | None = None
                   ) -> list[tuple[int, float, tuple]]:
    """Points of the front between a start's body and the start (``genome``, whose first ``body_ops`` ops build
    the body): ``(control vertices, distance, genome)`` of the body with its first legs or blocks, each whole (a
    leg's inset and extrusions), at the sizes the refinement fills between its levels
    (:func:`~gsr_cad.reconstruct.refine.fill_counts`). The body is first moved to where the whole start, fitted as
    the gate fits, puts it (the ops only append vertices: the body's are the start's first), so that the legs or
    blocks grow out of the fitted body; each prefix is then creased where the start is and fitted
    (:data:`PREFIX_ROUNDS`). A fit of the body with a few blocks from the box stalls (example013, 186 control
    vertices: 1.2e-2 of the diagonal both ways; 3.7e-3 grown from the moved body, where the front held 6.3e-3 at 194
    from the template's path and the quad-remesh baseline 5.4e-3 at 201). Where the ops do not apply to the moved
    body, the prefix is built on the box and fitted from the fitted start's positions instead. Each is measured as
    its moves replay. Empty where time runs out (``deadline``)."""
    end = next((i for i in range(body_ops, len(genome)) if isinstance(genome[i], (Crease, TranslateVertex))),
               len(genome))
    # a leg or block is whole before each op that starts the next (a leg's extrusions follow its inset)
    cuts = [i for i in range(body_ops + 1, end) if type(genome[i]) is not Extrude]
    try:
        full = problem.control_mesh(genome)
        body = problem.control_mesh(genome[:body_ops])
        sizes = [problem.control_mesh(genome[:i]).n_vertices for i in cuts]
        picked = fill_counts(sizes, body.n_vertices, full.n_vertices)
        if not picked or (deadline is not None and time.perf_counter() >= deadline):
            return []
        fitted, cost = problem.fit(full, GATE_ROUNDS, min_gain=1.0, adaptive=True, deadline=deadline, settle=True)
        moved, _, _ = _reach_partial(problem, genome[:body_ops], body, fitted[:body.n_vertices], deadline)
    except GsrError:
        return []
    edges = full.topology.edges
    count = full.n_vertices
    sharp = edges[full.edge_sharpness >= SHARPNESS_INFINITE]
    creased = set((sharp.min(axis=1) * count + sharp.max(axis=1)).tolist())
    out = []
    for k in picked:
        best = None
        # grown from the moved body, fitted from there; else built on the box and fitted from the start's positions
        # (a leg's inset, sized on the box, may not fit a moved face)
        for part, start in ((moved + genome[body_ops:cuts[k]], None), (genome[:cuts[k]], fitted)):
            if deadline is not None and time.perf_counter() >= deadline:
                break
            try:
                mesh = problem.control_mesh(part)
                ends = mesh.topology.edges
                keys = (ends.min(axis=1) * count + ends.max(axis=1)).tolist()
                creases = tuple(Crease(e, float(SHARPNESS_INFINITE)) for e, key in enumerate(keys) if key in creased)
                state = apply_ops(creases, mesh) if creases else mesh
                if state is None:
                    continue
                via = () if start is None else (start[:mesh.n_vertices],)
                vertices, cost = problem.fit(state if start is None else state.with_vertices(via[0]), PREFIX_ROUNDS,
                                             min_gain=1.0, adaptive=True, deadline=deadline, settle=True)
                if not math.isfinite(cost):
                    continue
                built, reached, _ = _reach_partial(problem, part + creases, state, vertices, deadline, via)
                cost = problem.fit(reached, 0)[1]
            except GsrError:
                continue
            if math.isfinite(cost) and (best is None or cost < best[1]):
                best = (mesh.n_vertices, float(cost), built)
        if best is not None:
            out.append(best)
    return out
