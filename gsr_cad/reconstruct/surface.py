"""Surface reconstruction: a mesh or point cloud -> Catmull-Clark control mesh + the ops that build it.

The GA (paper, sections 4-5, "plus" scheme, the paper's settings) evolves genomes of the seven surface
ops (V E L B I F S) on a template quad mesh, by default a cube placed and scaled so that its limit surface
spans the target's box (on its principal axes, :mod:`~gsr_cad.reconstruct.placement`); a genome starts as
one or two random ops. A user template is fitted to the target by a similarity first.

Fitness. The paper's mixed mean distance (``fitness="mixed"``, the ``paper`` preset) compares vertex
*sets* of the level-``k`` limit mesh and the target: it suits a target that is itself a limit mesh of the
same level, and keeps a floor of unmatched points on any other sampling. The default
(``fitness="surface"``) is the symmetric distance between the target and the *exact* limit surface
(:mod:`~gsr_cad.geometry.limit_surface`: B-spline patches, refined locally at extraordinary vertices):
the mean of (target points, drawn by area, -> their foot points on the limit surface) and (area samples of
the limit surface -> the target's points beyond their sampling radius), over the diagonal. It is 0 when the
surfaces coincide, whatever the sampling or the target's tessellation level. The reported metrics add the
maxima and the distance back to a mesh target's triangles (:func:`two_sided`); the mixed mean distance is
reported too.

Least-squares polish (beyond the paper). The limit surface is linear in the control vertices (a point
at fixed patch parameters is a fixed combination of them, :meth:`LimitSurface.rows`), so for fixed
closest-point correspondences the best vertex positions solve a small linear least-squares
problem (point-to-plane, lightly damped); a few such ICP-like rounds fit any genome's vertex positions,
never into a mesh the ops would refuse (folded or flipped faces). It is used three ways:

* every genome is scored after up to ``polish_rounds`` rounds, which stop early once a round gains
  little (``polish_gain``): a structure that can fit the target keeps converging and scores what it can
  reach, so the GA searches for the structure and the polish finds the positions (its genes are not
  changed by this);
* every ``polish_every`` generations the best genome gets the polish written back (the GA's local-search
  hook) as ``translate_vertex`` ops replacing its trailing ones, one per moved vertex;
* the winner is polished once more (``final_polish_rounds``) and its history of moves folded into one
  move per vertex after its other ops where they replay alone, so the saved genome is short and replays
  exactly to the saved control mesh.

Protrusion starts (beyond the paper). A template placed on the target's whole box stretches its body over
a bump on one side, and from there no fit reaches inset then extrude; when one template face is clearly the
best place for a bump, the first population also gets that face moved in, inset and extruded back out,
fitted to convergence (:meth:`SurfaceProblem.protrusion_seeds`). With ``survival="nsga2"`` the search keeps
NSGA-II's spread of (distance, control vertices) rather than the lowest distances
(:mod:`gsr_cad.ga.pareto`); the front is the non-dominated set of every cage scored either way.

History rewrite (beyond the paper). Several histories build the same connectivity (on a cube, an inset
then an extrude of the inset face has the connectivity of two parallel edge loops), and with the polish
placing the vertices they fit equally well, so the search keeps whichever it met first, with a move for
every vertex. With ``simplify_history`` the winner is rewritten by :func:`~gsr_cad.ops.rewrite.simplify_history`
into the shortest equivalent history found, whose op parameters place the vertices themselves (an inset
then an extrude and the template's corners moved, rather than two loops and sixteen moves), provided its
distance to the target exceeds the winner's by at most ``history_tolerance`` (of the diagonal).

Refinement (beyond the paper). With ``refine`` (the default; off in the ``paper`` preset) the winner's cage
is then grown where the residual is, coarse to fine (:mod:`~gsr_cad.reconstruct.refine`): edge loops,
extrudes, insets and bevels aimed at the faces carrying the largest two-sided error, and splits of the
whole cage by edge loops that keep its limit surface, each fitted by the adaptive least-squares fit
(sparse, stiffness annealed, every face kept sound), until ``max_distance`` (else ``refine_until``) is met,
the time (``refine_share`` of ``max_seconds``, else ``refine_seconds``) or ``refine_max_faces`` runs out,
or no op gains. Every level joins the accuracy/complexity front (``metrics["front"]``, one record per
level in ``metrics["refinement"]``), measured alike: a mesh target's triangles both ways, the surface -> target
direction less each triangle's chord sag (see :meth:`SurfaceProblem._back`). Sharp edges (beyond the paper,
``sharp_edges``, :mod:`~gsr_cad.reconstruct.sharp`): the search's simple cages, the placed cube and a designer's
start get their edges along the part's edges creased where that brings them closer; the template path grows
from its creased cube, and the simplest cage of the front within the goal is the result.

Replays are cached by genome prefix (children share their parents' prefixes); subdivision matrices by
connectivity (in :mod:`gsr_cad.geometry.subdivision`); KD-trees once per target.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import os
import time
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

from ..errors import ConfigError, GsrError, InputError, OpError
from ..ga import GAConfig, GenerationReport, RunResult, fingerprint, start_or_resume
from ..ga.pareto import has_pymoo, non_dominated
from ..geometry.limit_surface import Hits, LimitSurface, get_layout
from ..geometry.polymesh import PolyMesh
from ..geometry.subdivision import get_catmull_clark
from ..geometry.surface_distance import (NearTriangles, area_samples, chord_sag, cloud_distance,
                                         facet_triangles, mixed_mean_distance, sampling_radius)
from ..ops import mesh_kernel as MK
from ..ops.mesh_kernel import unsound_faces
from ..ops.base import replay
from ..ops.mesh import Crease, Extrude, Inset, OpRanges, TranslateVertex, moves_to, perturb_op, random_op
from ..ops.rewrite import simplify_history
from .config import REFINE_STALL_GAIN, SurfaceConfig
from .features import CreaseProposals
from .inputs import CLOUD_SAMPLING_NEIGHBOURS, SurfaceTarget, load_template, surface_target, validate_template
from .starts import start_prefixes, structured_start
from .placement import Placement, fit_template, place_cube
from .refine import Level, _inradius, _reach, apply_ops, refine, snapped_within
from .result import MAX_OPS, Result
from .second_path import TemplatePath, refine_workers
from .sharp import sharpened
from .snap import snap_far_vertices
from .templates import feature_genomes, fitted_template, genus_metrics, target_genus

_STATE_CACHE = 4096  # replayed genome prefixes kept (small meshes: a few kB each)
REWRITE_TOLERANCES = (1e-9, 1e-6, 1e-3)
"""How far (over the diagonal) the history rewrite may move control vertices, tried in turn; the
rewrite must also keep the distance to the target within ``history_tolerance`` of the winner's."""
DEFAULT_FIT_POINTS = 1500  # target points a fit scores when max_target_points is 0
METRIC_DENSITY = 2
"""Area samples per patch side that the final metrics' surface side adds to the polish's (:func:`two_sided`)."""
METRIC_POINTS = 20000  # area samples of a mesh target the reported distances use (a cloud: all its points)
METRIC_CHUNK = 50_000  # points whose foot points the reported distances find at once (bounded memory)
BACK_SAMPLES = 20_000
"""Area samples of a mesh target whose triangles a fit with ``exact_back`` projects onto (its surface -> target
direction, :class:`~gsr_cad.geometry.surface_distance.NearTriangles`); the reported metrics use every triangle."""
CHORD_SAG_SHARE = 1.0  # share of a triangle's chord sag within which the refinement's fit leaves the surface free
SEARCH_POINTS = 50_000  # most points of a cloud the search sees (a fixed random subset of larger ones)
_TARGET_SEED = 20240  # fixed seed of the target subsample (the cost must not depend on the run's seed)
CLOUD_POINTS_PER_FACE = 8  # data points a refined cage needs per face on a point cloud (refine_face_limit)
RESTART_SHARE = 0.5
"""When the refinement of the searched winner stops short of its goal with more than this share of its time left,
the template is refined too (:func:`_refined`)."""
REACHED_SHARE = 0.25
"""When it meets its goal with more than this share of its time left, the template is refined too, to a simpler
cage that meets it (:func:`_refined`)."""


def box_template(target: SurfaceTarget, fit: str = "box") -> PolyMesh:
    """The unit cube placed on the target's oriented box (:func:`~gsr_cad.reconstruct.placement.place_cube`),
    its limit surface spanning the box. ``fit="box"`` scales each axis to the box; ``fit="cube"`` keeps a
    cube sized by the largest extent."""
    return place_template("cube", target, SurfaceConfig(template_fit=fit)).mesh


def place_template(template: str | os.PathLike[str] | PolyMesh | None, target: SurfaceTarget,
                   config: SurfaceConfig) -> Placement:
    """The template and how it was placed: ``"cube"`` (or None) on the target's oriented box; ``"genus"``: the
    template with the target's genus (:func:`~gsr_cad.reconstruct.templates.fitted_template`); a PolyMesh or
    a mesh file, checked to be a valid quad mesh, then fitted to the target by a similarity when
    ``config.fit_template`` (:mod:`~gsr_cad.reconstruct.placement`)."""
    if template is None or (isinstance(template, str) and template == "cube"):
        if config.template_fit not in ("box", "cube"):
            raise ConfigError(f"template-fit must be box or cube, not {config.template_fit!r}")
        return place_cube(target.points, config.template_fit, fit_points(target, DEFAULT_FIT_POINTS))
    if isinstance(template, str) and template == "genus":
        genus = target_genus(target)[0]
        return Placement(fitted_template(target, genus), f"genus-{genus} template on the target's box", np.eye(3),
                         np.ones(1), np.zeros(3))
    if isinstance(template, PolyMesh):
        mesh = validate_template(template)
    elif isinstance(template, (str, os.PathLike)):
        mesh = load_template(template)
    else:
        raise InputError(f"template must be 'cube', a mesh file or a PolyMesh, not {type(template).__name__}")
    if not config.fit_template:
        return Placement(mesh, "as given", np.eye(3), np.ones(1), np.zeros(3))
    return fit_template(mesh, fit_points(target, DEFAULT_FIT_POINTS))


def make_template(template: str | os.PathLike[str] | PolyMesh | None, target: SurfaceTarget,
                  config: SurfaceConfig) -> PolyMesh:
    """The placed template of :func:`place_template`."""
    return place_template(template, target, config).mesh


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """One genome's score: its control mesh (after the evaluation polish), that mesh's limit mesh and
    triangles, and the cost."""

    control: PolyMesh
    limit: PolyMesh
    triangles: np.ndarray
    cost: float


class _Pairs(NamedTuple):
    """Correspondences of one polish round: each target point's foot point on the limit surface; the
    surface's area samples, their closest target points and weights (see :meth:`SurfaceProblem._back`)."""

    foot: Hits
    samples: Hits
    goal: np.ndarray
    weight: np.ndarray


class SurfaceProblem:
    """The GA problem for one target: random ops, repair, the cost of a genome and the polish."""

    def __init__(self, target: SurfaceTarget, config: SurfaceConfig, template: PolyMesh, exact_back: bool = False,
                 exact_facets: bool = False):
        self.target = target
        self.exact_back = exact_back and target.faces is not None
        """Surface samples -> a mesh target's triangles (not its sampled points) in the fit (the refinement:
        a fine mesh's chords are its surface)."""
        self.config = config
        self.template = template
        self.diag = target.diagonal
        goal = config.max_distance if config.max_distance is not None else config.refine_until
        self.fit_floor = min(FIT_FLOOR, 0.5 * goal)  # a goal the user set below the floor is still reached
        self.ranges = OpRanges(move=config.move_range, extrude=config.extrude_range, inward=config.inward_rate,
                               face_move=config.face_move_range, max_factor=config.max_scale_factor)
        # area samples repeat a small mesh's vertices: each distinct point once, weighted by its count
        self.points, counts = np.unique(fit_points(target, config.max_target_points or DEFAULT_FIT_POINTS), axis=0,
                                        return_counts=True)
        self.point_weight = counts / counts.sum()
        cloud = self.points
        self._cloud_tree = cKDTree(cloud)
        self._cloud = cloud
        self._cloud_radius = sampling_radius(cloud, self._cloud_tree, CLOUD_SAMPLING_NEIGHBOURS)
        self._on_facet = (on_facets(target, cloud) if exact_facets and target.faces is not None
                          else np.zeros(len(cloud), dtype=bool))
        """With ``exact_facets`` (the refinement), which fit points lie on a planar face of the part (see
        :meth:`_back`; the search keeps the cheaper slack everywhere)."""
        # a template finer than the limit still gets room for a few ops
        self.max_faces = max(config.max_control_faces, 2 * template.n_faces)
        self._states: OrderedDict[tuple, tuple[int, PolyMesh | None]] = OrderedDict()
        self._last_node = 0  # the number of the latest replayed prefix (see :meth:`_step`)
        self.evaluations = 0
        """Limit surfaces measured against the target by :meth:`fit` so far (its rounds and their checks): a count of
        the work that, unlike seconds, the same inputs repeat (the refinement's front fills are bounded by it)."""
        proposals = (CreaseProposals(target.points, target.faces, boundary=config.boundary)
                     if set("CR") & set(config.op_kinds) else None)
        self.creases = (proposals.edges, proposals.faces) if proposals else (None, None)
        self.proposals = proposals
        self.evaluated: dict[int, tuple[float, tuple]] = {}
        """Per control-vertex count, the cheapest genome scored in this process (for :func:`front`)."""
        self.scored: set[tuple] = set()
        """The genomes :meth:`cost` scored in this process (in ``evaluated`` already where they are the cheapest)."""

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_states"] = OrderedDict()
        state["_last_node"] = 0
        state["evaluated"] = {}
        state["scored"] = set()
        return state

    # --- replay with a prefix cache ----------------------------------------------------------------------
    def _step(self, node: int, state: PolyMesh, op) -> tuple[int, PolyMesh | None]:
        """``op`` applied to ``state``, the mesh of the replayed prefix numbered ``node``: the number of the longer
        prefix and its mesh, or ``(node, None)`` when it cannot apply.

        Prefixes are numbered as they are first replayed (the template is 0) and cached by ``(node, op)``: a
        lookup hashes one op, not the whole prefix, so a replay costs linear time in the genome's length (a
        refined cage's history has thousands of ops). Numbers are never reused, so an evicted prefix's
        descendants are merely replayed again."""
        key = (node, op)
        cache = self._states
        hit = cache.get(key)
        if hit is not None:
            cache.move_to_end(key)
            return hit
        try:
            nxt = op.apply(state)
            if nxt.n_faces > self.max_faces:
                nxt = None
        except OpError:
            nxt = None
        if nxt is None:
            out = (node, None)
        else:
            self._last_node += 1
            out = (self._last_node, nxt)
        cache[key] = out
        if len(cache) > _STATE_CACHE:
            cache.popitem(last=False)
        return out

    def _replay(self, genome: tuple) -> tuple[list, int, PolyMesh]:
        """The ops of ``genome`` that apply in order (others skipped), their prefix's number and its mesh."""
        kept: list = []
        node, state = 0, self.template
        for op in genome:
            child, nxt = self._step(node, state, op)
            if nxt is not None:
                kept.append(op)
                node, state = child, nxt
        return kept, node, state

    def walk(self, genome: tuple) -> tuple[tuple, PolyMesh]:
        """The ops of ``genome`` that apply in order (others skipped) and the resulting control mesh."""
        kept, _, state = self._replay(genome)
        return tuple(kept), state

    def control_mesh(self, genome: tuple) -> PolyMesh:
        """The control mesh a (repaired) genome builds; OpError if an op cannot apply."""
        kept, state = self.walk(genome)
        if len(kept) != len(genome):
            raise OpError("the genome has ops that cannot apply")
        return state

    # --- GA protocol -------------------------------------------------------------------------------------
    def seed_genomes(self) -> list[tuple]:
        """Starts for the search: the protrusion starts of :meth:`protrusion_seeds`, and starts from the
        target's feature lines when crease ops are on (:func:`feature_genomes`), built in at most a quarter
        of ``max_seconds`` (when set)."""
        seeds = self.protrusion_seeds()
        if self.proposals is None:
            return seeds
        return seeds + self._feature_seeds()

    def protrusion_seeds(self) -> list[tuple]:
        """Starts for a target with a bump on one side of the template. A candidate moves a template face in
        by a share of the template's depth along its normal (``PROTRUSION_DEPTHS``), insets it by a share of
        its size (``PROTRUSION_INSETS``) and extrudes it back out by as much, so that the template's body spans
        the target's body and the extruded face its bump (a template placed on the whole box stretches its
        body over the bump, and from there no fit reaches inset then extrude). Each face is tried with the
        middle candidate, as built; when one face is clearly the best (its cost below ``PROTRUSION_MARGIN``
        times the faces' median: a bump, not a rounding), its candidates are ranked as built and the
        ``PROTRUSION_FITS`` best fitted until they converge (structures compared nearly converged), kept as
        ``I E V...`` genomes. Needs I, E and V in ``op_kinds`` and a template of at most ``PROTRUSION_MAX_FACES``
        faces; empty otherwise."""
        if not {"I", "E", "V"} <= set(self.config.op_kinds) or self.template.n_faces > PROTRUSION_MAX_FACES:
            return []
        normals = _unit_rows(self.template.face_newell)
        depth = self.template.vertices @ normals.T  # (vertices, faces): heights along each face's normal
        extent = depth.max(axis=0) - depth.min(axis=0)
        middle = (PROTRUSION_DEPTHS[len(PROTRUSION_DEPTHS) // 2], PROTRUSION_INSETS[-1])
        probe = [(self._protrusion(f, *middle, float(extent[f])), f) for f in range(self.template.n_faces)]
        costs = np.array([c[0] for c, _ in probe])
        finite = costs[np.isfinite(costs)]
        if len(finite) < 3 or finite.min() >= PROTRUSION_MARGIN * np.median(finite):
            return []
        face = probe[int(np.argmin(costs))][1]
        ranked = sorted((self._protrusion(face, share, inset, float(extent[face]))
                         for share, inset in itertools.product(PROTRUSION_DEPTHS, PROTRUSION_INSETS)),
                        key=lambda t: t[0])
        rounds = max(self.config.final_polish_rounds, 1)
        out: list[tuple[float, tuple]] = []
        for cost, ops, built in ranked[:PROTRUSION_FITS]:
            if built is None:
                continue
            with contextlib.suppress(GsrError):
                vertices, cost = self.fit(built, rounds, min_gain=1.0, adaptive=True)
                moves, _, refused = self._moves(self.control_mesh(ops), vertices)
                if not refused:
                    out.append((cost, ops + moves))
        return [genome for _, genome in sorted(out, key=lambda t: t[0])]

    def _protrusion(self, face: int, share: float, inset: float, extent: float
                    ) -> tuple[float, tuple, PolyMesh | None]:
        """One candidate of :meth:`protrusion_seeds`: its cost as built, its ops on the template (an inset and an
        extrude) and the control mesh they build with the face moved in (inf, (), None when an op refuses)."""
        h = share * extent
        try:
            moved = MK.translate_face(self.template, face, -h)
            ops = (Inset(face, inset * _inradius(moved, face)), Extrude(face, h))
            built = moved
            for op in ops:
                built = op.apply(built)
            built = self.control_mesh(ops).with_vertices(built.vertices)
            return self.fit(built, 0)[1], ops, built
        except GsrError:
            return math.inf, (), None

    def _feature_seeds(self) -> list[tuple]:
        """The feature-line starts of :func:`feature_genomes`."""
        budget = 0.25 * self.config.max_seconds if self.config.max_seconds > 0 else None

        def scored(genome: tuple) -> tuple[float, PolyMesh | None]:  # structures compared nearly converged
            try:
                mesh = self.control_mesh(genome)
                vertices, cost = self.fit(mesh, max(self.config.final_polish_rounds, 1), min_gain=0.95)
            except GsrError:
                return math.inf, None
            return cost, mesh.with_vertices(vertices)

        return feature_genomes(self.template, self.proposals, scored, self.config.op_kinds, budget)

    def random_gene(self, rng: np.random.Generator, prefix: tuple):
        """A random op (kinds ``op_kinds``, sizes from the op ranges) for the mesh ``prefix`` builds."""
        return random_op(rng, self.walk(prefix)[1], self.diag, self.config.op_kinds, self.ranges, *self.creases)

    def repair(self, genome: tuple, rng: np.random.Generator) -> tuple:
        """The ops that apply (and keep the mesh within ``max_control_faces``), topped up to ``min_ops``."""
        kept, node, state = self._replay(genome)
        attempts = 0
        while len(kept) < self.config.min_ops and attempts < 50:
            attempts += 1
            op = random_op(rng, state, self.diag, self.config.op_kinds, self.ranges, *self.creases)
            child, nxt = self._step(node, state, op)
            if nxt is not None:
                kept.append(op)
                node, state = child, nxt
        return tuple(kept)

    def perturb(self, gene, rng: np.random.Generator):
        """The same op with its parameters nudged by ``perturb_rel`` of the diagonal."""
        return perturb_op(gene, rng, self.diag, rel=self.config.perturb_rel)

    def cost(self, genome: tuple) -> float:
        """The configured distance after the evaluation polish (inf for a genome that does not replay)."""
        self.scored.add(tuple(genome))
        try:
            e = self.evaluate(genome, self.config.polish_rounds)
        except GsrError:  # an op that cannot apply, or a mesh the subdivision refuses
            return math.inf
        n = e.control.n_vertices
        if n not in self.evaluated or e.cost < self.evaluated[n][0]:
            self.evaluated[n] = (e.cost, tuple(genome))
        return e.cost

    def local_search(self, genome: tuple) -> tuple:
        """The polish written back as ``translate_vertex`` ops (the GA's memetic hook)."""
        return self.polished(genome, max(self.config.polish_rounds, 1))

    def simplified(self, genome: tuple, should_stop: Callable[[], bool] | None = None) -> tuple:
        """``genome`` rewritten into the shortest equivalent history found (:mod:`gsr_cad.ops.rewrite`) whose
        cost exceeds ``genome``'s by at most ``history_tolerance``; ``genome`` itself if none does (the
        search for one ends early once ``should_stop()`` is true)."""
        limit = self.evaluate(genome, 0).cost + self.config.history_tolerance
        return simplify_history(self.template, genome, REWRITE_TOLERANCES, kinds=self.config.op_kinds,
                                accept=lambda history: self.evaluate(history, 0).cost <= limit,
                                should_stop=should_stop)

    def complexity(self, genome: tuple) -> float:
        """The number of control vertices ``genome`` builds (NSGA-II's second objective)."""
        return float(self.walk(genome)[1].n_vertices)

    def niche(self, genome: tuple) -> tuple:
        """The connectivity of the control mesh ``genome`` builds (the GA polishes the best of a few)."""
        return self.walk(genome)[1].topology_key

    # --- scoring -------------------------------------------------------------------------------------------
    def surface(self, mesh: PolyMesh) -> LimitSurface:
        """The exact limit surface of ``mesh`` (layout cached per connectivity)."""
        return LimitSurface(get_layout(mesh, self.config.boundary, self.config.limit_depth), mesh.vertices)

    def _mixed(self, mesh: PolyMesh) -> float:
        """The paper's mixed mean distance of ``mesh``'s level-``k`` limit vertices, over the diagonal."""
        cc = get_catmull_clark(mesh, self.config.levels, self.config.boundary)
        limit = cc.limit_matrix @ mesh.vertices
        return mixed_mean_distance(limit, self.target.points, self.diag, self.target.kdtree) / self.diag

    def evaluate(self, genome: tuple, rounds: int) -> Evaluation:
        """Score ``genome`` after ``rounds`` least-squares rounds on its control vertices."""
        mesh = self.control_mesh(genome)
        vertices, cost = self.fit(mesh, rounds)
        control = mesh if rounds <= 0 else mesh.with_vertices(vertices)
        cc = get_catmull_clark(mesh, self.config.levels, self.config.boundary)
        if self.config.fitness == "mixed":
            cost = self._mixed(control)
        return Evaluation(control, cc.limit(vertices), cc.triangles, float(cost))

    def _back(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Surface samples -> target, as the fit sees it: ``(distance, corresponding point, weight)``.

        The target is the cloud of the fit's points (a mesh's area samples, which lie on its vertices and
        inside its large triangles), each standing for the surface within its sampling radius: a surface
        point within that radius of its nearest point costs nothing and is not pulled (weight 0), one
        beyond pays the excess and is pulled by it, towards the point. A tessellation's chords are not its
        surface, so the fit must not be pulled onto them; the exact distance to the triangles is reported.
        With ``exact_back`` (the refinement on a mesh target) the closest points are on the triangles near
        ``BACK_SAMPLES`` area samples of it (:class:`NearTriangles`), less the triangle's chord sag
        (:func:`chord_sag`: within it a curved tessellation's surface may lie, beyond it the excess is paid and
        pulled; a fine mesh's sag is negligible, and a sampling radius of a coarse one's vertices, as a cloud,
        left a 640-triangle target's surface 1e-2 of the diagonal off while the fit saw 2e-4); so
        are, with ``exact_facets``, the surface points whose nearest point lies on a planar face of the part
        (:func:`on_facets`), which is its surface (else a bulge over a flat CAD face within the sampling radius went unseen).
        """
        if self.exact_back:
            d, near, tri = self._near_triangles().closest_triangles(X)
            sag = self._sag()[tri]
            if not sag.any():
                return d, near, np.ones(len(X))
            # within the chord's sag of a curved tessellation: free; beyond it, pulled by the excess only
            excess = np.maximum(d - sag, 0.0)
            share = np.divide(excess, d, out=np.zeros_like(d), where=d > 0)
            return excess, X + share[:, None] * (near - X), (excess > 0).astype(np.float64)
        d, idx = cloud_distance(X, self._cloud, self._cloud_radius, self._cloud_tree)
        near = self._cloud[idx]
        gap = np.linalg.norm(near - X, axis=1)
        # pulled by the excess only: to the sphere of the nearest point's radius, not to the point
        share = np.divide(d, gap, out=np.zeros_like(d), where=gap > 0)
        goal, weight = X + share[:, None] * (near - X), (d > 0).astype(np.float64)
        flat = np.flatnonzero(self._on_facet[idx])
        if flat.size:
            d[flat], goal[flat] = self._near_triangles().closest(X[flat])
            weight[flat] = 1.0
        return d, goal, weight

    def _sag(self) -> np.ndarray:
        """Per target triangle, :func:`~gsr_cad.geometry.surface_distance.chord_sag` (computed on first use)."""
        sag = self.__dict__.get("_chord_sag")
        if sag is None:
            sag = self._chord_sag = CHORD_SAG_SHARE * chord_sag(self.target.points, self.target.faces)
        return sag

    def _near_triangles(self) -> NearTriangles:
        """The mesh target's :class:`NearTriangles` (built on first use)."""
        near = self.__dict__.get("_near")
        if near is None:
            near = self._near = NearTriangles(self.target.points, self.target.faces, BACK_SAMPLES,
                                              seed=_TARGET_SEED)
        return near

    def _pairs(self, surface: LimitSurface, hint: Hits | None = None) -> tuple[_Pairs, float]:
        """The correspondences of one polish round on ``surface`` and its symmetric cost: the target points'
        foot points on the limit surface, and the surface's area samples' closest points on the target
        (as in :meth:`_back`, weighted by area). ``hint``: the previous round's foot points."""
        fwd = surface.closest(self.points, hint)
        samples, area = surface.samples()
        d_back, goal, weight = self._back(samples.point)
        share = area / max(float(area.sum()), 1e-300)
        cost = 0.5 * (float(self.point_weight @ fwd.distance) + float(share @ d_back)) / self.diag
        return _Pairs(fwd, samples, goal, share * weight), float(cost)

    def _system(self, surface: LimitSurface, pairs: _Pairs) -> tuple[sp.csr_matrix, np.ndarray]:
        """Normal equations ``(H, g)`` of one polish round for the correspondences ``pairs``: both directions'
        least-squares rows (:func:`_normal_equations`), summed."""
        H1, g1 = _normal_equations(surface.rows(pairs.foot), pairs.foot.normal, self.points, self.point_weight)
        H2, g2 = _normal_equations(surface.rows(pairs.samples), _pull_directions(pairs.samples, pairs.goal),
                                   pairs.goal, pairs.weight)
        return (H1 + H2).tocsr(), g1 + g2

    def fit(self, mesh: PolyMesh, rounds: int, min_gain: float | None = None,
            adaptive: bool = False, stiffness: float = 1.0, deadline: float | None = None,
            fairing: float | None = None, convex: bool = True,
            should_stop: Callable[[], bool] | None = None, settle: bool = False) -> tuple[np.ndarray, float]:
        """Control vertices of ``mesh`` after up to ``rounds`` damped least-squares rounds (the best round's),
        and their symmetric point-to-surface cost (``rounds`` 0: the cost of ``mesh`` as it is).

        Each round fixes the correspondences (see :meth:`_pairs`: foot points on the exact limit surface,
        which is linear in the control vertices ``V`` at fixed patch parameters) and solves for ``V``
        minimising, with both directions weighted as in the symmetric distance, the point-to-plane
        residuals (along the limit surface's normals, which lets the surface slide along itself and
        converges in a few rounds) plus ``POINT_WEIGHT`` times the point-to-point residuals, plus
        ``polish_damping`` (relative to the system's mean diagonal) times ``|V - V_current|^2``. A step is
        kept sound (:func:`_sound_step`: the steps of the vertices of faces the mesh ops would refuse are
        shortened); when no part of it is, the step is made smoother (its umbrella Laplacian over the cage
        penalised) and more damped, tenfold each time, up to ``_SMOOTH_TRIES`` times, then the rounds stop.
        Rounds also stop once one gains less than the factor ``min_gain`` (default ``config.polish_gain``): a
        structure that cannot fit the target stops after a few rounds, one that can keeps converging.
        ``adaptive`` (large cages far from the target): a round that raises the cost is undone and retried ten
        times more damped (up to ``_RETRIES`` times in a row), and the damping relaxes fourfold after each round
        that gains.
        Adaptive fits also keep the cage fair along the surface (:func:`_tangent_fairing`), which lets the
        point-to-plane rows pull thin fins and webs of surface back onto the target without crumpling the cage;
        ``fairing`` is their first weight (default ``TANGENT_FAIRING``; a fit continuing a converged one starts at 0: restarted at full weight
        they outweigh its small residual, every round is undone, and the fit stalls). When the first step of a
        faired fit raises the cost, the rows are dropped and the step redone without them (not counted as a
        round): a proposal on a converged cage (example012, 642 control vertices: an edge loop's three trial
        rounds measured 3.0e-3 of the diagonal faired, the cage as it came; 2.94e-3 without the rows).
        ``deadline`` (a ``time.perf_counter()`` value): no round starts that would end after it (each taking as
        long as the rounds so far). ``self.fit_rounds``: the rounds the last fit started (for time predictions).
        ``convex`` False (a cage no op will be applied to): adaptive fits keep their margin on edge lengths, areas
        and star shapes but let corners turn concave (:func:`unsound_faces`). ``should_stop()`` turning true
        ends the rounds as the deadline does. ``settle``: the rounds also stop once the best cost has settled
        (:data:`SETTLE_ROUNDS`, :data:`SETTLE_GAIN`).
        """
        min_gain = self.config.polish_gain if min_gain is None else min_gain
        layout = get_layout(mesh, self.config.boundary, self.config.limit_depth)
        V = np.array(mesh.vertices, dtype=np.float64)
        n = len(V)
        normals0 = mesh.face_newell
        best_v, best_cost, last = V, math.inf, math.inf
        bests: list[float] = []  # the best cost after each round (``settle``)
        hint = None
        rel, fails, stiff = self.config.polish_damping, 0, stiffness
        margin = _FIT_MARGIN if adaptive else 1.0
        lenient = unsound_faces(mesh, normals0, margin, convex) if adaptive else None
        held = unsound_faces(mesh, normals0)  # unsound from the start (a split of a skewed cage): kept as they are
        saved: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None
        plain: sp.csc_matrix | None = None  # the saved round's system without the fairing rows
        gained = False  # a step of this fit has lowered the cost
        smooth = lap = None
        fairing = TANGENT_FAIRING if fairing is None else fairing
        began = time.perf_counter()
        self.fit_rounds = 0
        redone = 0  # 1 once a round was redone without the fairing rows (it does not count as a round)
        for r in range(max(rounds, 0) + 2):
            surface = LimitSurface(layout, V)
            pairs, cost = self._pairs(surface, hint)
            self.evaluations += 1
            hint = pairs.foot
            if cost < best_cost:
                best_v, best_cost = V, cost
            bests.append(best_cost)
            settled = settle and r >= SETTLE_ROUNDS and best_cost >= (1.0 - SETTLE_GAIN) * bests[r - SETTLE_ROUNDS]
            # no round starts that would end after the deadline (a round takes about as long as the last)
            if r == rounds + redone or settled or cost <= self.fit_floor or (
                    deadline is not None and time.perf_counter() + (time.perf_counter() - began) / max(r, 1) >= deadline
            ) or (should_stop is not None and should_stop()):
                break
            self.fit_rounds = r + 1
            if adaptive and saved is not None and cost >= saved[3]:
                if plain is not None and not gained:
                    # the fairing rows outweigh the residual of a cage already near its fit (a proposal on a
                    # converged cage: every round was undone and the trial measured the cage as it came); the
                    # round is redone without them, as damped as it was
                    saved, plain, fairing, redone = (saved[0], plain, saved[2], saved[3]), None, 0.0, 1
                else:
                    fails += 1  # the step made it worse: back to where it started, damped more
                    if fails > _RETRIES:
                        break
                    rel *= 10.0
                    stiff = min(stiff * 4.0, max(stiffness, _STIFF_END))
                V, H, g, _ = saved
            else:
                if cost >= min_gain * last:
                    break
                gained = gained or saved is not None
                last, fails = cost, 0
                if adaptive and saved is not None:
                    rel = max(rel / 4.0, self.config.polish_damping)
                    stiff = max(stiff * _STIFF_RELAX, _STIFF_END)
                H, g = self._system(surface, pairs)
                plain = None
                if adaptive and fairing > 0.0:
                    if lap is None:
                        lap = _umbrella(mesh)
                    fair = _tangent_fairing(mesh, V, lap, float(H.diagonal().sum()), fairing)
                    fairing = fairing * FAIRING_DECAY if fairing * FAIRING_DECAY >= FAIRING_END else 0.0
                    plain = H.tocsc()
                    H = H + (fair.T @ fair)
                H = H.tocsc() if adaptive else H.toarray()
                saved = (V, H, g, cost)
            scale = max(float(H.diagonal().sum()) / H.shape[0], 1e-300)
            lam = rel * scale
            moved = False
            x = V.ravel()  # minimises |J x - y|^2 + lam |x - V|^2 (+ mu |Lap (x - V)|^2)
            for attempt in range(_SMOOTH_TRIES + 1):
                mu = stiff if adaptive else 0.0
                if attempt:
                    mu = max(mu, _SMOOTH_START) * 10.0 ** (attempt - (0 if adaptive else 1))
                if mu > 0 and smooth is None:
                    smooth = _smoothing(mesh)
                try:
                    if adaptive:  # sparse: cages of hundreds of vertices
                        A = (H + lam * sp.identity(3 * n, format="csc") + (mu * scale) * smooth).tocsc()
                        cg = _cg_step(A, g - H @ x) if 3 * n >= CG_UNKNOWNS else None
                        step = (cg.reshape(n, 3) if cg is not None
                                else _solve_spd(A, g + (A - H) @ x).reshape(n, 3) - V)
                    else:
                        A = H + lam * np.eye(3 * n)
                        if mu > 0:
                            A += (mu * scale) * smooth.toarray()
                        step = scipy.linalg.solve(A, g + (A - H) @ x, assume_a="pos",
                                                  check_finite=False).reshape(n, 3) - V
                except (np.linalg.LinAlgError, ValueError, RuntimeError):
                    break
                trial = _sound_step(mesh, V, step, normals0, margin, lenient, held, convex)
                if trial is not None:
                    V, moved = trial, True
                    break
                lam *= 10.0
            if not moved:
                break
        return best_v, best_cost

    def snap(self, mesh: PolyMesh, threshold: float) -> tuple[PolyMesh, int]:
        """``mesh`` with its control vertices whose limit points lie over ``threshold`` from the target moved
        onto it as far as the mesh ops allow, and how many moved (:func:`~.snap.snap_far_vertices`)."""
        return snap_far_vertices(mesh, self.target.closest, threshold, unsound_faces)

    def _moves(self, state: PolyMesh, goal: np.ndarray, deadline: float | None = None,
               via: tuple[np.ndarray, ...] = ()) -> tuple[tuple, PolyMesh, int]:
        """``translate_vertex`` ops taking ``state``'s vertices to ``goal``: ``(ops, resulting mesh, how many
        vertices did not get there)``.

        The ops refuse a move that would fold a face, and whether one does depends on the order. Each vertex
        first gets one op, in passes while they make progress, longest moves first (:func:`_move_order`);
        the vertices left then follow their straight paths in 2, 4, 8 or 16 equal stages (the others are
        already there: one op each, a few more only for the vertices that need them); failing that, every
        vertex follows the straight path between the two meshes in stages; failing that too, the first
        attempt's partial moves stand. Staged moves are then merged vertex by vertex where the history still
        replays (:func:`_compact_moves`), replaying at most ``COMPACT_SHARE`` times as many ops as the stages
        applied (plus ``COMPACT_EXTRA``): a count, not a time, so that the same seed gives the same history on any
        machine. No staged attempt or merge starts after ``deadline`` (a ``perf_counter`` value).

        ``via``: positions on a sound way from ``state`` to ``goal`` (a snapped fit's, see
        :func:`~gsr_cad.reconstruct.refine.snapped`). Where some move still refuses, the moves pass through
        them, merged likewise, if that leaves fewer vertices behind: a fin folded onto the target turns its
        faces over, which the straight path between the two cages folds on the way (bone, 378 control
        vertices: 18 moves refused straight, none through the way; 4.4e-4 of the diagonal reached instead of
        8.0e-4).
        """
        moves, current, refused = self._straight_moves(state, goal, deadline)
        if not refused or not via:
            return moves, current, refused
        steps: list = []
        trial, left = state, 0
        for point in (*via, goal):
            more, trial, left = self._straight_moves(trial, point, deadline)
            steps += more
        if left >= refused:
            return moves, current, refused
        budget = int(COMPACT_SHARE * len(steps)) + COMPACT_EXTRA
        return _compact_moves(state, steps, deadline, budget), trial, left

    def _straight_moves(self, state: PolyMesh, goal: np.ndarray, deadline: float | None
                        ) -> tuple[tuple, PolyMesh, int]:
        """:meth:`_moves` without a way through other positions."""
        tol = 1e-12 * self.diag
        goal = np.asarray(goal, dtype=np.float64)
        moves, current, refused = _ordered_moves(state, goal, tol)
        if not refused:
            return moves, current, 0
        for origin, ops in ((current, moves), (state, ())):
            start = origin.vertices
            for stages in (2, 4, 8, 16):
                if deadline is not None and time.perf_counter() >= deadline:  # no staged attempt starts after it
                    return moves, current, refused
                trial, steps = origin, list(ops)
                for k in range(1, stages + 1):
                    stage, trial, left = _ordered_moves(trial, start + (k / stages) * (goal - start), tol)
                    steps += stage
                    if left:
                        break
                else:
                    budget = int(COMPACT_SHARE * stages * state.n_vertices) + COMPACT_EXTRA
                    return _compact_moves(state, steps, deadline, budget), trial, 0
        return moves, current, refused

    def _bases(self, genome: tuple, mesh: PolyMesh, compact: bool) -> list[tuple[tuple, PolyMesh]]:
        """Where the polish's ``translate_vertex`` ops may start: the genome without its trailing
        ``translate_vertex`` ops and, with ``compact``, the genome's other ops alone when they replay to
        the same connectivity (one move per vertex then replaces the whole history of moves)."""
        cut = len(genome)
        while cut > 0 and isinstance(genome[cut - 1], TranslateVertex):
            cut -= 1
        out = [(genome[:cut], self.control_mesh(genome[:cut]))]
        core = tuple(op for op in genome if not isinstance(op, TranslateVertex))
        if compact and core != genome[:cut]:
            kept, state = self.walk(core)
            if len(kept) == len(core) and state.topology_key == mesh.topology_key:
                out.append((core, state))
        return out

    def polished(self, genome: tuple, rounds: int, min_gain: float = 1.0, attempts: int = 3,
                 compact: bool = False, deadline: float | None = None) -> tuple:
        """``genome``'s positions polished and written back as ``translate_vertex`` ops after the shortest
        base of :meth:`_bases` that reaches them (during the search, only the trailing moves are replaced:
        earlier moves place the ops that follow them, which helps those ops fit).

        Moves the ops refuse are left out and the polish is tried again from what did apply, up to
        ``attempts`` times (no fit round starting that would end after ``deadline``, a ``perf_counter`` value).
        Returns the cheapest genome seen (``genome`` itself if nothing helps).
        """
        best = tuple(genome)
        if rounds <= 0:
            return best
        best_cost = self.evaluate(best, 0).cost
        for _ in range(attempts):
            mesh = self.control_mesh(best)
            if deadline is not None and time.perf_counter() >= deadline:
                break
            new_v = self.fit(mesh, rounds, min_gain, deadline=deadline)[0]
            tries = []
            for ops, base in self._bases(best, mesh, compact):
                moves, _, refused = self._moves(base, new_v)
                tries.append((refused, len(ops) + len(moves), ops + moves))
            refused, _, candidate = min(tries, key=lambda t: t[:2])
            cost = self.evaluate(candidate, 0).cost
            if cost >= best_cost:
                break
            best, best_cost = candidate, cost
            if not refused:
                break
        return best

    def pruned(self, genome: tuple) -> tuple:
        """``genome`` without its negligible ``translate_vertex`` ops (shorter than ``NEGLIGIBLE_MOVE`` times
        ``history_tolerance``), provided the rest replays and its cost exceeds ``genome``'s by at most
        ``history_tolerance``; ``genome`` itself otherwise."""
        genome = tuple(genome)
        cut = NEGLIGIBLE_MOVE * self.config.history_tolerance * self.diag
        short = tuple(op for op in genome
                      if not (isinstance(op, TranslateVertex) and float(np.linalg.norm(op.delta)) < cut))
        if short == genome or len(self.walk(short)[0]) != len(short):
            return genome
        try:
            limit = self.evaluate(genome, 0).cost + self.config.history_tolerance
            return short if self.evaluate(short, 0).cost <= limit else genome
        except GsrError:
            return genome

    def grouped(self, genome: tuple, deadline: float | None = None) -> tuple:
        """``genome`` as a designer writes it: its structural ops first, then one move per vertex to the same
        control mesh, when those ops build its connectivity without the moves between them and every move
        replays in one pass (:func:`_ordered_moves`); ``genome`` itself otherwise, when that is longer, or
        when the moves (timed by one of them) are predicted to end after ``deadline`` (a ``perf_counter`` value).
        """
        genome = tuple(genome)
        core = tuple(op for op in genome if not isinstance(op, TranslateVertex))
        if genome[:len(core)] == core:
            return genome
        want = self.control_mesh(genome)
        kept, state = self.walk(core)
        if len(kept) != len(core) or state.topology_key != want.topology_key:
            return genome
        if deadline is not None:
            start = time.perf_counter()
            with contextlib.suppress(OpError):  # about what each move costs
                TranslateVertex(0, (0.0, 0.0, 0.0)).apply(state)
            if time.perf_counter() + 2 * state.n_vertices * (time.perf_counter() - start) > deadline:
                return genome
        moves, reached, refused = _ordered_moves(state, want.vertices, 1e-12 * self.diag)
        if (refused or len(core) + len(moves) > len(genome)
                or np.abs(reached.vertices - want.vertices).max() > 1e-12 * self.diag):
            return genome
        return core + moves

    def merged(self, genome: tuple) -> tuple:
        """``genome`` with each run of consecutive ``translate_vertex`` ops merged into one op per vertex (its
        net move), run by run where the merged moves apply and reach the run's mesh (within 1e-13 of the
        diagonal), and the whole history still replays to the same mesh (within 1e-12): the same modelling
        history, fewer steps. One forward replay (each run's ops applied twice at most), so thousands of ops
        cost seconds; ``genome`` itself when the merged history does not hold."""
        genome = tuple(genome)
        want = self.control_mesh(genome).vertices
        close = 1e-13 * self.diag
        out: list = []
        state = self.template
        i = 0
        try:
            while i < len(genome):
                j = i
                while j < len(genome) and isinstance(genome[j], TranslateVertex):
                    j += 1
                if j - i < 2:
                    state = genome[i].apply(state)
                    out.append(genome[i])
                    i += 1
                    continue
                after = state
                for op in genome[i:j]:
                    after = op.apply(after)
                net: dict[int, np.ndarray] = {}
                for op in genome[i:j]:
                    net[op.vertex] = net.get(op.vertex, np.zeros(3)) + np.asarray(op.delta)
                moves = [TranslateVertex(v, tuple(float(x) for x in d)) for v, d in net.items() if np.any(d != 0.0)]
                trial = state
                try:
                    for op in moves:
                        trial = op.apply(trial)
                    ok = np.abs(trial.vertices - after.vertices).max() <= close
                except OpError:
                    ok = False
                out.extend(moves if ok else genome[i:j])
                state = trial if ok else after
                i = j
        except OpError:
            return genome
        out_t = tuple(out)
        if out_t == genome:
            return genome
        kept, final = self.walk(out_t)
        if len(kept) != len(out_t) or np.abs(final.vertices - want).max() > 1e-12 * self.diag:
            return genome
        return out_t


PROTRUSION_DEPTHS = (0.2, 0.35, 0.5)
"""Shares of the template's depth along a face's normal that :meth:`SurfaceProblem.protrusion_seeds` tries as
the bump's height."""
PROTRUSION_INSETS = (0.2, 0.45)
"""Shares of the face's inradius that the protrusion starts inset the face by."""
PROTRUSION_FITS = 2  # protrusion starts fitted to convergence (the best ranked as built)
PROTRUSION_MAX_FACES = 24  # larger templates get no protrusion probe (one cost per face)
PROTRUSION_MARGIN = 0.9
"""A face is taken for a bump's when its probe costs below this share of the median face's."""


NEGLIGIBLE_MOVE = 0.1
"""A ``translate_vertex`` op shorter than this share of ``history_tolerance`` (of the diagonal) is dropped from
the saved history (:meth:`SurfaceProblem.pruned`): a vertex move changes the limit surface by at most its length."""

_STEP_PASSES = 24  # passes of :func:`_sound_step`
_HALVINGS = 6  # a vertex's step halved more often than this is dropped
_STEP_KEEP = 0.02  # a step shortened below this share of its length is given up
_RETRIES = 3
SETTLE_ROUNDS, SETTLE_GAIN = 5, 2e-3
"""A fit with ``settle`` stops once its best cost gained less than ``SETTLE_GAIN`` (relative) over its last
``SETTLE_ROUNDS`` rounds: converged, where a round that does not gain at all (``min_gain`` 1) may never come (an
adaptive fit undoes a round that raised the cost and retries it damped, and a converged cage alternates the two).
On a blob's face-bounded refinement (122 fits, 914 rounds) that saved 37 % of the rounds and lost at most 0.4 % of
a fit's distance (0.008 % on average); rounds gaining less than 0.04 % each would have needed hundreds to gain what
a level gains."""
FIT_FLOOR = 1e-6
"""A fit stops once its cost (the mean of both directions over the diagonal) is this low, or half the run's goal
where the user set a lower one: a micrometre on a metre, below any measured target's noise and the limit
evaluation's own accuracy (its pending triangles). Rounds past it polish nothing a user can see; an exactly
representable target's fit went on from 1e-7 to 1.5e-8 in three quarters of its refinement's time."""
_FIT_MARGIN = 20.0  # adaptive fits keep faces this much clear of the ops' limits (no slivers)
_STIFF_RELAX, _STIFF_END = 0.5, 1e-3  # adaptive fits: stiffness annealed, coarse to fine
_SMOOTH_TRIES = 4
_SMOOTH_START = 1e-2  # first weight of the step's smoothness (relative to the system's mean diagonal)


COMPACT_SHARE = 2.0
"""Merging staged moves may replay this many times as many ops as finding them tried (one per vertex and stage):
a bone's 898-vertex cage in 16 stages made 14,000 moves, whose unbounded merge, one vertex at a time, ran for more
than ten minutes of a 300 s budget."""
COMPACT_EXTRA = 2000  # op replays every merge may use besides (small cages merge completely)


def _ordered_moves(state: PolyMesh, goal: np.ndarray, tol: float) -> tuple[tuple, PolyMesh, int]:
    """:func:`~gsr_cad.ops.mesh.moves_to` with the vertices renumbered so that the longest moves come first
    (a long move is the one a neighbour's earlier move most often makes fold), then in index order."""
    order = _move_order(state.vertices, goal)
    moves, current, refused = moves_to(state, goal, tol, order)
    if refused:
        plain, mesh, left = moves_to(state, goal, tol)
        if left < refused:
            return plain, mesh, left
    return moves, current, refused


def _compact_moves(state: PolyMesh, moves: list[TranslateVertex], until: float | None = None,
                   budget: int | None = None) -> tuple:
    """``moves`` (which replay on ``state``) with each vertex's several moves merged into one, at the place of
    its last or its first, where the whole sequence still replays: the same end state, fewer steps.

    Only the stretch between a vertex's first and last move is replayed (after its last one every vertex is
    where it was). Each merge still replays up to the whole sequence (hundreds of vertices in 16 stages: a
    second each), so no merge starts after ``until`` (a ``perf_counter`` value) or once ``budget`` op replays are
    spent (None: no limit); the rest stay as they are."""
    moves = list(moves)
    before = [state]  # before[i]: the state op i applies to
    for op in moves:
        before.append(op.apply(before[-1]))
    spent = 0
    for vertex in dict.fromkeys(op.vertex for op in moves):
        if (until is not None and time.perf_counter() >= until) or (budget is not None and spent >= budget):
            break
        at = [i for i, op in enumerate(moves) if op.vertex == vertex]
        if len(at) < 2:
            continue
        net = tuple(float(x) for x in np.sum([moves[i].delta for i in at], axis=0))
        first, last = at[0], at[-1]
        for keep in (last, first):
            head = [TranslateVertex(vertex, net) if i == keep else moves[i] for i in range(first, last + 1)
                    if i == keep or i not in at]
            states = [before[first]]
            try:
                for op in head:
                    spent += 1
                    states.append(op.apply(states[-1]))
            except OpError:
                continue
            moves = moves[:first] + head + moves[last + 1:]
            before = before[:first] + states[:-1] + before[last + 1:]
            break
    return tuple(moves)


def _move_order(start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    return np.argsort(-np.linalg.norm(goal - start, axis=1), kind="stable")


def _umbrella(mesh: PolyMesh) -> sp.csr_matrix:
    """``(n, n)`` umbrella Laplacian of the cage: each vertex minus the mean of its cage neighbours."""
    topo = mesh.topology
    n = mesh.n_vertices
    a, b = topo.he_origin, topo.he_dest
    adj = sp.csr_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    adj.data[:] = 1.0
    deg = np.asarray(adj.sum(axis=1)).ravel()
    return (sp.identity(n, format="csr") - sp.diags(1.0 / np.maximum(deg, 1.0)) @ adj).tocsr()


def _smoothing(mesh: PolyMesh) -> sp.csc_matrix:
    """``(3 n, 3 n)`` sparse normal matrix of the umbrella Laplacian of a step of ``mesh``'s vertices (each vertex's
    step minus the mean of its cage neighbours'), in the unknowns ``V.ravel()``."""
    lap = _umbrella(mesh)
    return sp.kron(lap.T @ lap, sp.identity(3), format="csc")


TANGENT_FAIRING = 10.0
"""Weight of the tangential fairing rows (:func:`_tangent_fairing`) next to the data rows, as a ratio of their
mean squared column norms. On the bone's 966-vertex cage (fins between its knobs, 10 % of the surface more than
1e-2 of the diagonal off), 30 rounds of the adaptive fit took the surface -> target mean from 3.0e-3 to 2.8e-3
without the rows and to 1.3e-3 with them (1.7e-3 at weight 1, 1.2e-3 at 30, 2.7e-3 at 100: the fit then
stops early); unguarded, weight 1 reached 2.6e-4 / 3.2e-4 both ways with every face sound, 0.1 left 14 unsound.
The rows bias a cage that can fit exactly, so their weight decays by ``FAIRING_DECAY`` with every round that
gains, and is zero once below ``FAIRING_END`` (14 rounds): the fit ends at the data's own least-squares optimum."""
FAIRING_DECAY, FAIRING_END = 0.5, 1e-3


def _tangent_fairing(mesh: PolyMesh, V: np.ndarray, lap: sp.csr_matrix, data: float,
                     weight: float = TANGENT_FAIRING) -> sp.csr_matrix:
    """Least-squares rows (zero goal) asking each control vertex of ``mesh`` at ``V`` to sit at the mean of
    its cage neighbours *along the surface*: the umbrella Laplacian ``lap`` projected on two tangent
    directions per vertex (normal to its area-weighted cage normal), weighted against the data rows ``J``
    by ``weight`` (``data``: the sum of the data rows' squared entries, the trace of their normal matrix).
    Point-to-plane rows leave the control vertices free to slide along the
    surface; these rows spend that freedom on evenly spread, well-shaped faces instead of crumpled ones."""
    n = len(V)
    moved = mesh.with_vertices(V)
    normal = np.zeros((n, 3))
    np.add.at(normal, moved.corners, np.repeat(moved.face_newell, moved.face_sizes, axis=0))
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(normal, helper)
    t1 /= np.maximum(np.linalg.norm(t1, axis=1), 1e-300)[:, None]
    t2 = np.cross(normal, t1)
    c = lap.tocoo()
    rows, cols, vals = [], [], []
    for k, t in enumerate((t1, t2)):
        for axis in range(3):
            rows.append(2 * c.row + k)
            cols.append(3 * c.col + axis)
            vals.append(c.data * t[c.row, axis])
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * n, 3 * n))
    t_scale = float(T.multiply(T).sum())
    if t_scale <= 0.0:
        return T
    return math.sqrt(weight * data / t_scale) * T


POINT_WEIGHT = 1e-4
"""Weight of the point-to-point residuals next to the point-to-plane ones in the polish."""


CG_UNKNOWNS = 1500
"""A fit round's damped system of at least this many unknowns (500 control vertices) is solved by conjugate
gradients (:func:`_cg_step`): SuperLU's factor fills in as the cage grows (a 1,538-vertex cage: 0.35 s a solve,
80 % of its round; block-Jacobi CG to a relative residual of 1e-8: 0.09 s, the step within 1e-5 of it)."""
CG_TOLERANCE = 1e-8
CG_ITERATIONS = 400


def _cg_step(A: sp.csc_matrix, r: np.ndarray) -> np.ndarray | None:
    """``A^-1 r`` by conjugate gradients preconditioned with the inverses of ``A``'s 3x3 diagonal blocks (one
    control vertex's coordinates); None when that does not converge within :data:`CG_ITERATIONS` (or a block is
    singular): the caller factors ``A`` instead. Deterministic: a seed repeats its run."""
    n = A.shape[0] // 3
    coo = A.tocoo()
    own = coo.row // 3 == coo.col // 3
    blocks = np.zeros((n, 3, 3))
    np.add.at(blocks, (coo.row[own] // 3, coo.row[own] % 3, coo.col[own] % 3), coo.data[own])
    try:
        inverse = np.linalg.inv(blocks)
    except np.linalg.LinAlgError:
        return None
    precondition = spla.LinearOperator(A.shape, matvec=lambda v: np.einsum("kij,kj->ki", inverse,
                                                                           v.reshape(n, 3)).ravel())
    x, info = spla.cg(A.tocsr(), r, rtol=CG_TOLERANCE, atol=0.0, maxiter=CG_ITERATIONS, M=precondition)
    return x if info == 0 and np.all(np.isfinite(x)) else None


def _solve_spd(A: sp.csc_matrix, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` for a sparse symmetric positive definite ``A`` (a fit round's damped normal equations):
    SuperLU in its symmetric mode (a minimum-degree ordering of ``A + A^T``, diagonal pivots first), twice as
    fast as its general mode on a cage's system. NaN where ``A`` is singular: no step (the fit damps it more)."""
    try:
        return spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True}).solve(b)
    except RuntimeError:  # SuperLU: "Factor is exactly singular"
        return np.full(len(b), np.nan)


def _sound(mesh: PolyMesh, reference_normals: np.ndarray) -> bool:
    """True when every face passes the mesh ops' own checks (:func:`unsound_faces`), so vertex moves to
    ``mesh`` replay as ops."""
    return not np.any(unsound_faces(mesh, reference_normals))


def _sound_step(mesh: PolyMesh, V: np.ndarray, step: np.ndarray, normals0: np.ndarray,
                margin: float = 1.0, lenient: np.ndarray | None = None,
                held: np.ndarray | None = None, convex: bool = True) -> np.ndarray | None:
    """``V`` moved by ``step``, each vertex of a face it would make unsound (:func:`unsound_faces` with
    ``margin``, without it for the faces ``lenient``: those that were already inside the margin where the fit
    started) moving half as far in the next pass, down to ``_HALVINGS`` halvings (then not at all), in up to
    ``_STEP_PASSES`` passes, provided at least ``_STEP_KEEP`` of the step's length stays; None when no such move
    is sound. The faces ``held`` (unsound where the fit started) keep their vertices and are not checked: a few
    such faces do not stop the rest of the cage from moving. ``convex``: as :func:`unsound_faces` takes it.

    Shortening only the offending vertices' steps, not holding them, keeps most of a round's progress: the
    bunny's split cage (738 control vertices) held 300-470 vertices a round and kept 2-10 % of the step's
    length (2.2e-3 of the diagonal after 25 rounds); halved, it keeps 10-30 % (1.7e-3 after 25 rounds, where
    the held steps needed 60 rounds for 1.8e-3)."""
    if not np.all(np.isfinite(step)):
        return None
    corners = mesh.corners
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    held = held if held is not None and held.any() else None
    if held is not None:
        step = step.copy()
        step[corners[held[face_of]]] = 0.0
    total = float(np.abs(step).sum())
    share = np.ones(len(V))
    for _ in range(_STEP_PASSES):
        s = share[:, None] * step
        if float(np.abs(s).sum()) < _STEP_KEEP * total:
            break
        moved = mesh.with_vertices(V + s)
        bad = unsound_faces(moved, normals0, margin, convex)
        if lenient is not None and lenient.any():
            bad[lenient] = unsound_faces(moved, normals0)[lenient]
        if held is not None:
            bad[held] = False
        if not bad.any():
            return V + s
        share[corners[bad[face_of]]] *= 0.5
        share[share < 0.5 ** _HALVINGS] = 0.0
    return None


def _unit_rows(a: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(a, axis=1, keepdims=True)
    return np.divide(a, length, out=np.zeros_like(a), where=length > 0)


def _pull_directions(samples: Hits, goal: np.ndarray) -> np.ndarray:
    """Directions of the surface -> target rows: from each area sample towards its corresponding target point
    (the target's normal there, when that point is inside a triangle), the surface's normal where they meet.
    Along the surface's own normal a fin or web of surface (a double sheet past the data, whose closest target
    points lie in its plane) had no residual and stayed: bone's fins kept fit->data at 3.5e-3 of the diagonal
    after 20 rounds of the refinement's fit, 1.7e-3 along these directions."""
    direction = _unit_rows(goal - samples.point)
    still = ~direction.any(axis=1)
    direction[still] = samples.normal[still]
    return direction


def _normal_equations(A: sp.csr_matrix, normals: np.ndarray, goal: np.ndarray, weight: np.ndarray
                      ) -> tuple[sp.csr_matrix, np.ndarray]:
    """Normal equations ``(J^T J, J^T y)`` in the unknowns ``V.ravel()`` (``3 n``) of the least-squares rows
    for residuals ``A_j V - goal_j`` of weight ``weight_j``: one point-to-plane row along ``normals_j`` and
    three point-to-point rows weighted ``POINT_WEIGHT`` times less. Assembled per pair of coordinates as
    ``A^T diag(w_j (n_j n_j^T + POINT_WEIGHT I)_cd) A`` without forming ``J`` (four rows per point, a third
    of them three times as dense: its product was a third of a fit round on bone's 354-vertex cage). The six
    products share ``A^T A``'s pattern, so their values fill the 3 x 3 blocks of one block-sparse matrix (a
    third faster than summing them as coordinates)."""
    A = sp.csr_matrix(A)
    n = A.shape[1]
    point = weight * POINT_WEIGHT
    plane = weight * np.einsum("ij,ij->i", normals, goal)
    g = A.T @ (plane[:, None] * normals + point[:, None] * goal)
    At = A.T.tocsr()
    row = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    blocks = {}
    for c in range(3):
        for d in range(c, 3):
            D = weight * normals[:, c] * normals[:, d] + (point if c == d else 0.0)
            blocks[c, d] = At @ sp.csr_matrix((A.data * D[row], A.indices, A.indptr), shape=A.shape)
    first = blocks[0, 0]
    if all(np.array_equal(b.indptr, first.indptr) and np.array_equal(b.indices, first.indices)
           for b in blocks.values()):
        data = np.empty((first.nnz, 3, 3))
        for (c, d), b in blocks.items():
            data[:, c, d] = data[:, d, c] = b.data
        H = sp.bsr_matrix((data, first.indices, first.indptr), shape=(3 * n, 3 * n)).tocsr()
        return H, np.asarray(g).ravel()
    # patterns that differ (scipy drops a product's zero sums: the cross terms of normals along the axes, a box's)
    rows, cols, vals = [], [], []
    for (c, d), b in blocks.items():
        b = b.tocoo()
        rows += [3 * b.row + c] + ([3 * b.col + d] if c != d else [])
        cols += [3 * b.col + d] + ([3 * b.row + c] if c != d else [])
        vals += [b.data] * (2 if c != d else 1)
    H = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * n, 3 * n))
    return H, np.asarray(g).ravel()


def _ga_config(config: SurfaceConfig) -> GAConfig:
    return GAConfig(
        scheme="plus",
        initial_population=max(config.initial_population, config.population),
        population=config.population,
        min_initial_genes=config.min_initial_ops,
        max_initial_genes=config.max_initial_ops,
        generations=config.generations,
        mutation_rate=config.mutation_rate,
        delete_rate=config.delete_rate,
        append_rate=config.append_rate,
        n_parents=config.n_parents,
        max_children=config.max_children,
        n_perturb=config.n_perturb,
        n_newcomers=config.n_newcomers,
        max_duplicates=config.max_duplicates,
        threshold=config.threshold,
        max_seconds=config.max_seconds or None,
        stall_generations=config.stall_generations or None,
        stall_gain=config.stall_gain,
        local_search_every=config.polish_every,
        local_search_count=config.polish_niches,
        survival=config.survival,
    )


def fit_points(target: SurfaceTarget, count: int) -> np.ndarray:
    """The target points a fit scores: ``count`` area samples of a mesh (its vertices would weight dense
    regions more), a cloud's points (a fixed random ``count`` of larger ones). Seeded: the cost must not
    depend on the run's seed."""
    if target.faces is not None:
        return area_samples(target.points, target.faces, count, _TARGET_SEED)
    n = len(target.points)
    if n <= count:
        return target.points
    return target.points[np.sort(np.random.default_rng(_TARGET_SEED).choice(n, count, replace=False))]


def on_facets(target: SurfaceTarget, points: np.ndarray) -> np.ndarray:
    """Per row of ``points`` (points of the mesh ``target``), True when it lies on a facet, a triangle of one of
    the target's planar faces (:func:`~gsr_cad.geometry.surface_distance.facet_triangles`): there the
    triangles are the surface itself, not chords of it, so a fit gives such a point no sampling slack."""
    facet = facet_triangles(target.points, target.faces)
    if not facet.any():
        return np.zeros(len(points), dtype=bool)
    hit = target.triangle_set.closest(points)
    return facet[hit.triangle] & (hit.distance <= 1e-9 * target.diagonal)


def data_distances(surface: LimitSurface, points: np.ndarray, seeds: int = METRIC_POINTS,
                   chunk: int = METRIC_CHUNK) -> np.ndarray:
    """The exact distance of every row of ``points`` to the limit surface, ``chunk`` rows at a time (bounded
    memory whatever their number).

    Beyond ``seeds`` points, a fixed random ``seeds`` of them get the full search of
    :meth:`LimitSurface.closest`, and every other point starts its Newton iteration from its nearest
    seed's foot point, moved along the seed's tangent plane (a fresh search where that leaves the patch). A foot point so found is a point of
    the surface, so its distance can only be too large, and by 1-Lipschitz continuity it is certainly
    wrong where it exceeds the seed's distance plus the distance to the seed: those points, and the
    points whose distance could still be the largest, get the full search too, so the maximum is exact."""
    x = points
    n = len(x)
    if n <= seeds:
        return np.concatenate([surface.closest(x[a:a + chunk]).distance for a in range(0, n, chunk)])
    pick = np.sort(np.random.default_rng(_TARGET_SEED).choice(n, seeds, replace=False))
    base = surface.closest(x[pick])
    on = base.patch >= 0
    su, sv = np.zeros((seeds, 3)), np.zeros((seeds, 3))
    _, su[on], sv[on] = surface.evaluate(base.patch[on], base.u[on], base.v[on], derivatives=True)
    tree = cKDTree(x[pick])
    out = np.empty(n)
    for a in range(0, n, chunk):
        part = np.asarray(x[a:a + chunk], dtype=np.float64)
        gap, j = tree.query(part)
        hint = Hits(*(getattr(base, f.name)[j] for f in dataclasses.fields(Hits)))
        # Newton starts at the seed's parameters stepped along its tangent plane towards the point (one
        # iteration fewer)
        r = part - base.point[j]
        uu, uv, vv = (np.einsum("ij,ij->i", p, q) for p, q in ((su[j], su[j]), (su[j], sv[j]), (sv[j], sv[j])))
        ru, rv = np.einsum("ij,ij->i", su[j], r), np.einsum("ij,ij->i", sv[j], r)
        det = uu * vv - uv * uv
        ok = det > 1e-14 * (uu * vv + 1e-300)
        det = np.where(ok, det, 1.0)
        u = np.where(ok, np.clip(hint.u + (vv * ru - uv * rv) / det, 0.0, 1.0), hint.u)
        v = np.where(ok, np.clip(hint.v + (uu * rv - uv * ru) / det, 0.0, 1.0), hint.v)
        hint = dataclasses.replace(hint, u=u, v=v)
        d = surface.closest(part, hint).distance
        wrong = np.flatnonzero(d > (base.distance[j] + gap) * (1.0 + 1e-9))
        if wrong.size:
            d[wrong] = surface.closest(part[wrong]).distance
        out[a:a + chunk] = d
    out[pick] = base.distance
    # the exact maximum: search afresh from the largest down until no unchecked point can beat it
    order = np.argsort(out)[::-1]
    checked = 0
    top = -math.inf
    while checked < n and out[order[checked]] > top:
        rows = order[checked:checked + max(256, checked)]
        exact = surface.closest(x[rows]).distance
        out[rows] = exact
        top = max(top, float(exact.max()))
        checked += len(rows)
    return out


def two_sided(surface: LimitSurface, target: SurfaceTarget, data: np.ndarray, extra: np.ndarray | None = None,
              density: int = METRIC_DENSITY, counts: np.ndarray | None = None,
              timing: dict[str, float] | None = None) -> dict[str, float]:
    """Both directions between an exact limit surface and a target, over the target's diagonal:
    ``data_to_fit`` from the points ``data`` (every one, :func:`data_distances`, each counted ``counts``
    times if given; the max also over ``extra``, e.g. a mesh's vertices) to the surface, ``fit_to_data``
    from the surface's area samples (``density`` more per patch side than the polish uses) to the target,
    area-weighted. ``timing`` (if given) gets the seconds of the surface's side (``"surface"``), the one that
    grows with the cage."""
    diag = target.diagonal
    d_data = data_distances(surface, data)
    weight = np.full(len(d_data), 1.0 / len(d_data)) if counts is None else counts / counts.sum()
    top = float(d_data.max())
    if extra is not None and len(extra):
        top = max(top, float(data_distances(surface, extra).max()))
    start = time.perf_counter()
    samples, area = surface.samples(density)
    d_fit, _ = target.closest(samples.point)
    if timing is not None:
        timing["surface"] = time.perf_counter() - start
    return {"data_to_fit_mean": float(weight @ d_data / diag), "data_to_fit_max": top / diag,
            "data_to_fit_rms": float(np.sqrt(weight @ d_data ** 2) / diag),
            "fit_to_data_mean": float(area @ d_fit / max(float(area.sum()), 1e-300) / diag),
            "fit_to_data_max": float(d_fit.max() / diag)}


def _evaluated_from(problem: SurfaceProblem, memo: dict[tuple, float]) -> None:
    """``problem.evaluated`` made up from the search's memo (genome -> cost, in the order they were scored), for the
    genomes scored elsewhere: in a process pool's workers, or before a resumed run's checkpoint. The front then does
    not depend on where the costs were computed (a pool's run had lost the search's cages from its front). The
    genomes scored in this process are there already: a serial run replays none."""
    for genome, cost in memo.items():
        if not math.isfinite(cost) or genome in problem.scored:
            continue
        try:
            n = problem.control_mesh(genome).n_vertices
        except GsrError:
            continue
        if n not in problem.evaluated or cost < problem.evaluated[n][0]:
            problem.evaluated[n] = (cost, tuple(genome))


def front(evaluated: dict[int, tuple[float, tuple]]) -> list[tuple[int, float, tuple]]:
    """The accuracy/complexity front: ``(control vertices, distance, genome)`` of the evaluated genomes that
    no other dominates in (control vertices, distance) (:func:`~gsr_cad.ga.pareto.non_dominated`, pymoo's
    non-dominated sort when installed), by vertex count."""
    entries = [(n, float(evaluated[n][0]), evaluated[n][1]) for n in sorted(evaluated)]
    keep = non_dominated(np.array([[n, cost] for n, cost, _ in entries], dtype=np.float64).reshape(-1, 2))
    return [entries[i] for i in keep]


def surface_metrics(control: PolyMesh, target: SurfaceTarget, config: SurfaceConfig,
                    timing: dict[str, float] | None = None) -> dict[str, Any]:
    """Distances between the control mesh's exact limit surface and the whole target (both directions,
    :func:`two_sided`: from every point of a cloud, or from ``METRIC_POINTS`` area samples of a mesh and
    (for the max) every one of its vertices), and the paper's mixed mean distance of its level-``k`` limit
    vertices; all over the target's bounding-box diagonal. ``timing``: see :func:`two_sided`."""
    layout = get_layout(control, config.boundary, config.limit_depth)
    surface = LimitSurface(layout, control.vertices)
    cloud = target.faces is None
    # a mesh's area samples repeat its vertices: each distinct point once, counted as often as drawn
    data, counts = ((target.points, None) if cloud
                    else np.unique(fit_points(target, METRIC_POINTS), axis=0, return_counts=True))
    d = two_sided(surface, target, data, None if cloud else target.points, counts=counts, timing=timing)
    cc = get_catmull_clark(control, config.levels, config.boundary)
    diag = target.diagonal
    mixed = mixed_mean_distance(cc.limit_matrix @ control.vertices, target.points, diag, target.kdtree)
    return {
        **d,
        "mean_distance": d["data_to_fit_mean"],
        "max_distance": d["data_to_fit_max"],
        "rms_distance": d["data_to_fit_rms"],
        "mean_distance_to_target": d["fit_to_data_mean"],
        "max_distance_to_target": d["fit_to_data_max"],
        "symmetric_distance": 0.5 * (d["data_to_fit_mean"] + d["fit_to_data_mean"]),
        "mixed_mean_distance": float(mixed / diag),
        "paper_fitness": float(diag / mixed) if mixed > 0 else math.inf,
        "distance_surface": f"exact limit surface ({layout.n_patches} B-spline patches, refinement depth "
                            f"{config.limit_depth} at extraordinary vertices)",
        "n_data_samples": int(len(data) if counts is None else counts.sum()),
        "n_control_vertices": int(control.n_vertices),
        "n_control_faces": int(control.n_faces),
        "n_limit_vertices": int(cc.n_vertices),
    }


@dataclasses.dataclass
class Snapshot:
    """The best individual at one generation (kept in memory for the report, not in result.json)."""

    generation: int
    cost: float
    genome: tuple
    control: PolyMesh


@dataclasses.dataclass
class SurfaceResult(Result):
    """A surface :class:`Result` plus in-memory extras: the target, the template, the best individual
    at a few generations (``snapshots``, for the paper's Figure 5 layout) and the accuracy/complexity front
    with each point's genome (``front``: ``(control vertices, distance, genome)``, as ``metrics["front"]``;
    :meth:`front_control` builds a point's cage)."""

    target: SurfaceTarget | None = dataclasses.field(default=None, repr=False)
    template: PolyMesh | None = dataclasses.field(default=None, repr=False)
    snapshots: list[Snapshot] = dataclasses.field(default_factory=list, repr=False)
    front: list[tuple[int, float, tuple]] = dataclasses.field(default_factory=list, repr=False)

    def front_control(self, index: int) -> PolyMesh:
        """The control mesh of the front's point ``index`` (its genome replayed on the template)."""
        if self.template is None:
            raise InputError("this result holds no template to replay its front on")
        return replay(self.template, self.front[index][2])


def _letters(genome: tuple) -> str:
    """The op letters of ``genome`` ("?" for an op without one); past ``_MAX_LETTERS`` (a refined history
    of hundreds of moves) run-length encoded instead ("L9 V296")."""
    letters = "".join(getattr(op, "letter", "?") for op in genome)
    if len(letters) <= _MAX_LETTERS:
        return letters
    runs = [(k, len(list(g))) for k, g in itertools.groupby(letters)]
    return " ".join(k if n == 1 else f"{k}{n}" for k, n in runs)


_MAX_LETTERS = 900  # result.json strings are at most 1000 characters


def _pick_snapshots(changes: list[tuple[int, float, tuple]], count: int) -> list[tuple[int, float, tuple]]:
    """Up to ``count`` improvements spread over the run: the first, the last and evenly between."""
    if len(changes) <= count:
        return list(changes)
    idx = np.unique(np.round(np.linspace(0, len(changes) - 1, count)).astype(int))
    return [changes[i] for i in idx]


def reconstruct_surface(target, *, template: str | os.PathLike[str] | PolyMesh = "cube", preset: str = "default",
                        seed: int | None = None, config: SurfaceConfig | None = None,
                        progress: Callable[[GenerationReport], None] | None = None,
                        evaluator: Callable | None = None, n_snapshots: int = 4,
                        should_stop: Callable[[], bool] | None = None, checkpoint: str | os.PathLike[str] | None = None,
                        **overrides: Any) -> SurfaceResult:
    """Reconstruct a Catmull-Clark control mesh and its op history from a mesh or point cloud.

    ``target``: a path (OBJ, PLY, STL, OFF mesh or XYZ/CSV/TXT/PTS/NPY/faceless PLY-OBJ cloud), an
    ``(n, 3)`` array, a PolyMesh or a :class:`~gsr_cad.reconstruct.inputs.SurfaceTarget`. ``template``:
    "cube" (fitted to the target's box), a quad mesh file or a PolyMesh. ``overrides`` are
    :class:`SurfaceConfig` fields. ``evaluator`` is any ``(fn, items) -> list`` (e.g. a
    :class:`~gsr_cad.ga.ProcessPoolEvaluator`). Ctrl-C during the search keeps the best genome found so
    far (``result.interrupted``), as does ``should_stop()`` turning true; the final polish, the refinement and
    the history rewrite are then skipped or cut short. With ``checkpoint`` the search state is saved there every
    generation and, if that file exists, the run continues from it (same seed, same result as an
    uninterrupted run). Bad input raises InputError / TopologyError / ConfigError.
    """
    started = time.perf_counter()
    tgt = surface_target(target)
    config = (SurfaceConfig.preset(preset, **overrides) if config is None
              else dataclasses.replace(config, **overrides).validated())
    search = tgt.subsampled(SEARCH_POINTS, _TARGET_SEED)  # the search sees a bounded sample; metrics see all
    placement = place_template(template, search, config)
    tmpl = placement.mesh
    problem = SurfaceProblem(search, config, tmpl)
    tag = fingerprint("surface", tgt.points, tgt.faces, tmpl.vertices, tmpl.corners, config.to_json(), preset, seed)
    refining = config.refine and config.fitness == "surface"
    ga_config = _ga_config(config)
    if refining and config.refine_stall and not config.stall_generations:
        ga_config = dataclasses.replace(ga_config, stall_generations=config.refine_stall,
                                        stall_gain=max(config.stall_gain, REFINE_STALL_GAIN))
    deadline = started + config.max_seconds if config.max_seconds else None
    if deadline is not None:  # the search's share of the time left (the refinement gets the rest)
        share = (1.0 - config.refine_share) if refining else 1.0 - _POST_RESERVE
        ga_config = dataclasses.replace(ga_config, max_seconds=max(
            share * config.max_seconds - (time.perf_counter() - started), _MIN_SEARCH * config.max_seconds))
    engine = start_or_resume(problem, ga_config, seed, evaluator, checkpoint, tag)
    changes: list[tuple[int, float, tuple]] = []

    def on_generation(report: GenerationReport) -> None:
        if not changes or report.best_cost < changes[-1][1]:
            changes.append((report.generation, report.best_cost, tuple(report.best_genome)))
        if progress is not None:
            progress(report)

    run: RunResult = engine.run(on_generation=on_generation, should_stop=should_stop, checkpoint=checkpoint)
    best = tuple(run.best_genome)
    _evaluated_from(problem, engine.memo)
    pareto = front(problem.evaluated)
    if config.max_distance is not None and not refining:  # (the refinement picks on its own measure)
        meets = [entry for entry in pareto if entry[1] <= config.max_distance]
        if meets and meets[0][2] != best:
            best = meets[0][2]  # the simplest cage that meets the tolerance
    searched = time.perf_counter()

    def hurry() -> bool:  # a Ctrl-C that ended the search ends the run too (no polish, refinement or rewrite)
        return run.interrupted or (should_stop is not None and bool(should_stop()))

    snapshots = [Snapshot(g, c, genome, problem.evaluate(genome, 0 if hurry() else config.polish_rounds).control)
                 for g, c, genome in _pick_snapshots(changes, n_snapshots) if genome]
    tail = _tail(problem, best, search, tgt, config, deadline is not None)  # and the winner's metrics
    before_best = tail.metrics
    polish_at = time.perf_counter()
    # the polish and the history rewrite of the winner: before the refinement at most POST_SHARE of the time
    # left, else up to the final metrics
    post = None
    if deadline is not None:
        left = max(deadline - tail(tail.vertices) - polish_at, 0.0)
        post = polish_at + (POST_SHARE * left if refining else left)

    def post_stop() -> bool:
        return hurry() or (post is not None and time.perf_counter() >= post)

    final = best
    if best and not hurry():
        final = problem.merged(problem.polished(best, config.final_polish_rounds, compact=True, deadline=post))
    polished_at = time.perf_counter()
    polish_seconds = polished_at - polish_at
    searched_ops = _letters(final)
    if config.simplify_history and final and not post_stop():
        final = problem.simplified(final, post_stop)
    simplify_seconds = time.perf_counter() - polished_at
    refined_at = time.perf_counter()
    growth = None
    if refining and final and not hurry():
        goal = config.max_distance if config.max_distance is not None else config.refine_until
        until = (deadline if deadline is not None
                 else time.perf_counter() + config.refine_seconds if config.refine_seconds else None)
        growth = _refined(problem, final, goal, until, pareto, should_stop, config.max_distance is not None, tail)
        if growth is not None:
            final, pareto = growth.genome, growth.front
    late = None if deadline is None or not final else deadline - tail(problem.control_mesh(final).n_vertices)
    rewrite_at = time.perf_counter()
    if final and not hurry() and (late is None or time.perf_counter() < late):
        final = problem.pruned(problem.grouped(problem.merged(final), late))
    if len(final) > MAX_OPS:  # no result holds it: the closest front cage whose history fits
        fits = sorted((entry for entry in pareto if len(entry[2]) <= MAX_OPS), key=lambda entry: entry[1])
        final = fits[0][2] if fits else best
    refine_seconds = time.perf_counter() - refined_at
    rewrite_seconds = time.perf_counter() - rewrite_at
    control = problem.control_mesh(final)
    metrics_at = time.perf_counter()
    metrics = surface_metrics(control, tgt, config)
    metrics_seconds = time.perf_counter() - metrics_at
    exact = _front_distances(problem, pareto, final, metrics, tgt, config, deadline, tail)
    before = before_best if final != best and before_best is not None else metrics
    metrics.update({
        "fitness": problem.evaluate(final, 0).cost if growth is None else growth.cost,
        "fitness_kind": ("mixed mean distance / diagonal" if config.fitness == "mixed"
                         else "symmetric point-to-surface distance / diagonal"),
        "search_fitness": float(run.best_cost),
        "n_search_points": len(search.points),
        "unpolished_symmetric_distance": before["symmetric_distance"],
        "unpolished_mean_distance": before["mean_distance"],
        "polish_seconds": polish_seconds,
        "simplify_seconds": simplify_seconds,
        "refine_seconds": refine_seconds,
        "rewrite_seconds": rewrite_seconds,
        "metrics_seconds": metrics_seconds,
        "predicted_metrics_seconds": tail(control.n_vertices),
        "refinement": [] if growth is None else growth.levels,
        "refined_from": None if growth is None or not (growth.levels or growth.path == FRONT_PATH) else growth.path,
        "refine_workers": 0 if growth is None else growth.workers,
        "lead_start": None if growth is None else growth.leads,
        "sharp_edges": None if growth is None or growth.sharp is None else {
            **growth.sharp, "creases": sum(isinstance(op, Crease) for op in final)},
        "searched_ops": searched_ops,
        "seconds": time.perf_counter() - started,
        "generations": run.generations,
        "evaluations": run.evaluations,
        "stop_reason": ("refine_stall" if run.stop_reason == "stall" and ga_config.stall_generations
                        != config.stall_generations else run.stop_reason),
        "n_ops": len(final),
        "ops": _letters(final),
        **genus_metrics(control, *target_genus(tgt)),
        "template_placement": placement.to_json(),
        "front": [{"vertices": n, "ops": _letters(g), "distance": c, "n_ops": len(g), **exact.get(n, {})}
                  for n, c, g in pareto],
        "front_sort": "pymoo non-dominated sorting" if has_pymoo() else "non-dominated sorting (numpy)",
    })
    if config.max_distance is not None:
        # the front's measure: the search's symmetric distance (the reported fit_to_data also holds a mesh
        # target's own chord error)
        metrics["tolerance_met"] = bool(metrics["fitness"] <= config.max_distance)
    cfg = config.to_json()
    cfg.update({
        "preset": preset,
        "template": {"source": template if isinstance(template, str) else
                     ("mesh" if isinstance(template, PolyMesh) else os.fspath(template)),
                     "vertices": tmpl.vertices.tolist(), "faces": [list(f) for f in tmpl.faces]},
        "target": {"name": tgt.name, "kind": tgt.kind, "n_points": len(tgt.points),
                   "n_triangles": 0 if tgt.faces is None else len(tgt.faces), "diagonal": tgt.diagonal,
                   "bbox": tgt.bbox.tolist()},
    })
    return SurfaceResult(kind="surface", config=cfg, seed=run.seed, genome=final, metrics=metrics,
                         history=run.history, control_mesh=control, interrupted=run.interrupted,
                         target=tgt, template=tmpl, snapshots=snapshots, front=list(pareto))


FRONT_METRIC_POINTS = 5000
"""Area samples of a mesh target each front cage's exact distances use (the result's own use METRIC_POINTS)."""


def _front_distances(problem: SurfaceProblem, pareto: list[tuple[int, float, tuple]], final: tuple,
                     metrics: dict[str, Any], target: SurfaceTarget, config: SurfaceConfig,
                     deadline: float | None, tail: Callable[[int], float]) -> dict[int, dict[str, float]]:
    """Both directions' exact means for the front's cages, by control vertices: the front's ``distance`` is
    the measure the search or the refinement ranked by (a sample, the surface side less a mesh's chord sag),
    so a user comparing cages (or a baseline) at equal complexity gets the reported measure too. The result's
    own cage takes its final metrics; the others, smallest first, :data:`FRONT_METRIC_POINTS` samples and no
    extra surface density, while the time left (``deadline``) holds about half a final metrics (``tail``)."""
    keys = ("data_to_fit_mean", "fit_to_data_mean")
    out: dict[int, dict[str, float]] = {}
    cloud = target.faces is None
    data, counts = ((target.points, None) if cloud
                    else np.unique(fit_points(target, FRONT_METRIC_POINTS), axis=0, return_counts=True))
    for n, _, genome in sorted(pareto, key=lambda entry: entry[0]):
        if genome == final or n == metrics["n_control_vertices"]:  # (its history rewritten: the same cage)
            out[n] = {k: metrics[k] for k in keys}
            continue
        if deadline is not None and time.perf_counter() + 0.5 * tail(n) > deadline:
            break
        with contextlib.suppress(GsrError):
            control = problem.control_mesh(genome)
            surface = LimitSurface(get_layout(control, config.boundary, config.limit_depth), control.vertices)
            d = two_sided(surface, target, data, counts=counts, density=0)
            out[n] = {k: d[k] for k in keys}
    for entry in out.values():
        entry["symmetric_distance"] = 0.5 * (entry["data_to_fit_mean"] + entry["fit_to_data_mean"])
    return out


FRONT_PATH = "front"
"""``refined_from`` of a result whose cage is a point of the front simpler than the refinement paths' last cages
(a creased cage of the search within the goal, or closer than they came)."""
FRONT_ROUNDS = 30
"""Least-squares rounds each of the search's front cages smaller than its winner gets before it joins the
refinement's front (the search's evaluation polish stops after ``polish_rounds``; a user picking a simple cage
from the front gets its structure's fit)."""
POST_SHARE = 0.25
"""Most share of the time left after the search that the winner's final polish and history rewrite may take."""
_MIN_SEARCH = 0.01  # the search gets at least this share of max_seconds, whatever the preparation took
_POST_RESERVE = 0.1  # share of max_seconds left after the search when there is no refinement (polish, metrics)
TAIL_MARGIN = 1.3
TAIL_CALIBRATION_VERTICES = 90
TAIL_OBSERVED = 3000
TAIL_OBSERVE_GROWTH = 1.5
"""The final metrics of a cage are predicted from two warm measurements on the search's points: the search
winner's and its Catmull-Clark split cage's (split until it has ``TAIL_CALIBRATION_VERTICES``), each side of
:func:`two_sided` (the surface's area samples to the target, and the rest) a line through the two, all
``TAIL_MARGIN`` times; the refinement leaves that much time before the deadline. A single cold measurement
scaled up misjudged both ways: the surface's side grows with the cage (an OpenSCAD part: 11 s at 1456
vertices where growth by the power 0.4 gave 5.4 s), but at a small cage it is mostly the one-off cost of the
target's closest-triangle index (bunny: 72 s predicted for 930 vertices, 5 s taken, 70 s of refinement
lost), and a query costs more the farther the surface is (a split of the 8-vertex winner: 104 s at 1538
vertices; the 930-vertex refined cage: 5 s). So each refinement level's surface side is measured too
(:meth:`_Tail.observe`) and predicts that side from there."""


class _Tail:
    """The seconds the work after the refinement needs for a cage of ``vertices`` control vertices (callable):
    the final metrics on all of ``target``'s points, from ``timings``: ``(control vertices, seconds, seconds of
    the surface's side)`` measured on the search's points (two sizes: a line each; one: grown in proportion),
    the rest times ``scale`` (a cloud's points over the search's). ``metrics``: the search winner's."""

    def __init__(self, metrics: dict[str, Any] | None, timings: list[tuple[int, float, float]], scale: float,
                 target: SurfaceTarget | None = None, config: SurfaceConfig | None = None):
        self.metrics, self.scale, self.target, self.config = metrics, scale, target, config
        self.timings = sorted((max(int(n), 1), max(t, 0.0), min(max(s, 0.0), max(t, 0.0))) for n, t, s in timings)
        self.vertices = self.timings[0][0]
        self.observed: tuple[int, float] | None = None  # (control vertices, seconds per control vertex)

    def __call__(self, vertices: int) -> float:
        (n0, t0, s0), (n1, t1, s1) = self.timings[0], self.timings[-1]
        if n1 == n0 and self.observed is None:  # one size measured: both sides in proportion to the cage
            grow = max(vertices / n0, 1.0)
            return TAIL_MARGIN * grow * ((t0 - s0) * self.scale + s0)

        def line(a: float, b: float) -> float:
            slope = max((b - a) / (n1 - n0), 0.0) if n1 > n0 else 0.0
            return max(a, b) + slope * max(vertices - n1, 0)

        surface = line(s0, s1) if self.observed is None else self.observed[1] * max(vertices, self.observed[0])
        return TAIL_MARGIN * (line(t0 - s0, t1 - s1) * self.scale + surface)

    def observe(self, cage: PolyMesh) -> None:
        """Time the surface's side on ``cage`` (a refinement level: as close to the target as the final cage,
        where the search winner's split cages are not, and a closest-point query costs more the farther it
        starts): all its area samples, and the target's closest points of at most ``TAIL_OBSERVED`` of them.
        That side is then predicted in proportion to the cage from here. Skipped until the cage has grown by
        ``TAIL_OBSERVE_GROWTH`` since the last observation."""
        if self.target is None or self.config is None or (
                self.observed is not None and cage.n_vertices < TAIL_OBSERVE_GROWTH * self.observed[0]):
            return
        start = time.perf_counter()
        surface = LimitSurface(get_layout(cage, self.config.boundary, self.config.limit_depth), cage.vertices)
        points = surface.samples(METRIC_DENSITY)[0].point
        made = time.perf_counter() - start
        pick = np.random.default_rng(0).choice(len(points), size=min(len(points), TAIL_OBSERVED), replace=False)
        start = time.perf_counter()
        self.target.closest(points[pick])
        query = (time.perf_counter() - start) / max(len(pick), 1)
        self.observed = (cage.n_vertices, (made + query * len(points)) / cage.n_vertices)


def _tail(problem: SurfaceProblem, best: tuple, search: SurfaceTarget, target: SurfaceTarget,
          config: SurfaceConfig, calibrate: bool = True) -> _Tail:
    """The search winner's metrics on the search's points as a :class:`_Tail`; with ``calibrate`` also timed
    warm (the first call builds the target's indexes) at the winner and at its split cage."""
    scale = max(len(target.points) / max(len(search.points), 1), 1.0) if target.faces is None else 1.0
    if not best:
        return _Tail(None, [(1, 0.0, 0.0)], scale)
    mesh = problem.control_mesh(best)

    def timed(cage: PolyMesh) -> tuple[dict[str, Any], tuple[int, float, float]]:
        timing: dict[str, float] = {}
        start = time.perf_counter()
        metrics = surface_metrics(cage, search, config, timing)
        return metrics, (cage.n_vertices, time.perf_counter() - start, timing.get("surface", 0.0))

    metrics, first = timed(mesh)
    if not calibrate:
        return _Tail(metrics, [first], scale)
    timings = [timed(mesh)[1]]
    cage = mesh
    while cage.n_vertices < TAIL_CALIBRATION_VERTICES:
        cage = get_catmull_clark(cage, 1, config.boundary).refine(cage.vertices)
    if cage is not mesh:
        timings.append(timed(cage)[1])
    return _Tail(metrics, timings, scale, target, config)


class Growth(NamedTuple):
    """What the refinement made of the searched winner: the genome, its distance (the refinement's measure,
    :meth:`SurfaceProblem._pairs` with ``exact_back``), the front re-measured alike with every
    level on it, and one record per level for result.json."""

    genome: tuple
    cost: float
    front: list[tuple[int, float, tuple]]
    levels: list[dict[str, Any]]
    path: str = "winner"  # whose growth: the search's winner's, the placed template's or a start's (module starts)
    workers: int = 1  # processes it grew on
    leads: dict[str, Any] | None = None  # the starts found and their gate's figures (module starts), where looked for
    sharp: dict[str, Any] | None = None  # the creases kept on the front's cages and the template's (module sharp)


def refine_face_limit(target: SurfaceTarget, max_faces: int) -> int:
    """The largest cage the refinement may grow on ``target``: ``max_faces``, and for a point cloud at most one
    face per :data:`CLOUD_POINTS_PER_FACE` points, as a cage with more unknowns than its data can pin fits the
    points' scatter instead of a surface (a 200-point random cloud grew to 50 vertices in 24 s)."""
    if target.faces is not None:
        return max_faces
    return min(max_faces, max(len(target.points) // CLOUD_POINTS_PER_FACE, 6))


def _refined(problem: SurfaceProblem, genome: tuple, goal: float, deadline: float | None,
             searched: list[tuple[int, float, tuple]], should_stop: Callable[[], bool] | None,
             pick: bool, tail: Callable[[int], float] | None = None) -> Growth | None:
    """The searched winner ``genome`` grown by :func:`~gsr_cad.reconstruct.refine.refine` until ``goal``
    (``deadline``: a ``perf_counter`` value). The search's front is re-measured first by the refinement's
    measure (each cage after the search's evaluation polish, as a replayable genome, and creased along the
    part's edges where that gains, module :mod:`.sharp`); its simplest cage within ``goal``, if any, is taken
    without refining. None when the winner is within ``goal`` already and no tolerance was asked (``pick``).
    The template path starts from the template's creases where they gained on it. With time left
    (``RESTART_SHARE`` when the winner stalls short of ``goal``, ``REACHED_SHARE`` when it meets it) the template
    is refined too, and so it is after a designer's start (module starts) took its place in the second process,
    with ``REACHED_SHARE`` left. A winner with
    faces other than quads, where the template has only quads, is not refined: the template is, instead. With two
    processes (``config.refine_workers``) the template grows beside the winner in a second one
    (:class:`~gsr_cad.reconstruct.second_path.TemplatePath`; with every fit's corners free beside a winner of the
    template's own structure), both paths' cages are points of the front, and the final cage is the simpler of
    those within ``goal``, else the closer; a cage of the front simpler than that and within ``goal``, or closer
    than it, stands instead (``FRONT_PATH``)."""
    config = problem.config
    points = max(config.max_target_points or DEFAULT_FIT_POINTS, config.refine_points)
    target = problem.target
    exact = target.faces is not None
    grower = SurfaceProblem(target, dataclasses.replace(config, max_target_points=points), problem.template,
                            exact_back=exact, exact_facets=True)
    grower.max_faces = problem.max_faces = max(problem.max_faces, config.refine_max_faces)
    if deadline is not None and tail is not None and time.perf_counter() + tail(
            grower.control_mesh(genome).n_vertices) >= deadline:  # no time left beyond the final metrics
        return None
    start = grower.fit(grower.control_mesh(genome), 0)[1]
    if start <= goal and not pick:  # nothing to grow: the search's front and measure stand
        return None
    found: dict[int, tuple[float, tuple]] = {}

    def keep(n: int, cost: float, history: tuple) -> None:
        if n not in found or cost < found[n][0]:
            found[n] = (cost, history)

    def record(mesh: PolyMesh, cost: float, history: tuple) -> None:
        keep(mesh.n_vertices, cost, history)

    def level(mesh: PolyMesh, cost: float, history: tuple) -> None:
        record(mesh, cost, history)
        if isinstance(tail, _Tail):
            tail.observe(mesh)

    winner = grower.control_mesh(genome).n_vertices
    # the template itself fitted too: the search's own simplest cage may be a worse local minimum of the same
    # structure (example007's 8 vertices: a pyramid of moves at 5.9e-2 of the diagonal both ways, the box
    # fitted 3.7e-2)
    plain: tuple = ()  # the template path's start: the template, its edges along the part's creased where that gains
    sharp_info: dict[str, Any] = {"front_creased": 0, "seconds": 0.0}
    for n, _, g in [(problem.template.n_vertices, 0.0, ())] + list(searched):
        if ((g and n >= winner) or (should_stop is not None and should_stop())
                or (deadline is not None and time.perf_counter() >= deadline)):
            break
        with contextlib.suppress(GsrError):
            mesh = grower.control_mesh(g)  # fitted as far as a refinement level's cage (:data:`FRONT_ROUNDS`)
            fitted = grower.fit(mesh, max(config.polish_rounds, FRONT_ROUNDS))
            snap = snapped_within(grower, mesh.with_vertices(fitted[0]), fitted[1], deadline, should_stop)
            # the snapped fit (fins and webs folded onto the target) if its moves replay, else the plain one
            for v, cost, via in (snap, (*fitted, ())) if snap[1] < fitted[1] else ((*fitted, ()),):
                moves = _reach(grower, (), mesh, v, via)
                if moves is not None:
                    record(mesh, cost, g + moves)
                    # a box-like part's simple cage: its edges along the part's creased (module sharp)
                    clock = time.perf_counter()
                    sharp = sharpened(grower, mesh, v, cost, FRONT_ROUNDS, deadline, coarse=not g)
                    sharp_info["seconds"] += time.perf_counter() - clock
                    creased = None if sharp is None else apply_ops(sharp[0], mesh)
                    more = None if creased is None else _reach(grower, (), creased, sharp[1], (v,) if sharp[3] else ())
                    if more is not None:
                        record(mesh, sharp[2], g + sharp[0] + more)
                        sharp_info["front_creased"] += 1
                        if not g:  # with the moves to its fit: a cold fit of the creased cube may stall
                            plain = sharp[0] + more
                            sharp_info.update(template_creases=len(sharp[0]), template_distance=cost,
                                              creased_distance=sharp[2])
                    break
            else:
                record(mesh, grower.fit(mesh, 0)[1], g)
    meets = [entry for entry in front(found) if entry[1] <= goal]
    if meets:  # the simplest cage within the goal: a tolerance asked for, or a creased cage simpler than the winner
        return Growth(meets[0][2], meets[0][1], front(found), [], FRONT_PATH,
                      sharp=sharp_info if config.sharp_edges else None)
    faces = refine_face_limit(target, config.refine_max_faces)
    started = time.perf_counter()
    work = grower.evaluations
    fills: list[tuple[list, Callable[[int], None]]] = []  # the front's points between levels, after both paths
    quads = bool(np.all(grower.template.face_sizes == 4))
    if genome and quads and np.any(grower.control_mesh(genome).face_sizes != 4):
        # a winner with faces other than quads (a bevel's) admits no split, the template's quads do: the template
        # grows instead (LetterBlock's placed box refined alone, 300 s: 768 control vertices at 3.7e-3 of the
        # diagonal; the search's bevelled 31-vertex winner in a 300 s run: 356 at 9.0e-3)
        genome = ()
    path = "winner" if genome else "template"
    stopped = (lambda: False) if should_stop is None else should_stop
    # a leaded part's second path starts from its body and legs, where they gain on the body alone (module leads)
    lead = structured_start(grower, deadline, faces) if quads and not stopped() else None
    other_start = lead[0] if lead is not None else ()
    start_path = lead[1]["path"] if other_start else None
    # with a second CPU the template grows beside the winner (module second_path); else after it, in time left.
    # A winner of vertex moves only grows from the template's own structure: beside it, the template grows with
    # every fit's corners free (another strategy, closer on some chains, behind on others)
    shaped = any(not isinstance(op, TranslateVertex) for op in genome)
    other = (TemplatePath(grower, goal, deadline, faces, tail, free_corners=not shaped and not other_start,
                          genome=other_start or plain) if quads and not stopped()
             and refine_workers(config.refine_workers, None if deadline is None
                                else deadline - time.perf_counter()) > 1 else None)
    other_path = start_path or "template"
    if other is None and other_start:
        # one process: the legs grow first (they gained on the body alone), the winner in the time left
        genome, other_start, path, other_path = other_start, genome, start_path, path
    if lead is not None and lead[0] and not stopped():
        # the body with its first legs or blocks: points of the front below the start (module starts), fitted
        # here while the second process grows (the paths run to the deadline and would leave them no time)
        points = start_prefixes(grower, lead[0], lead[1]["body_ops"], deadline)
        for n, cost, history in points:
            keep(n, cost, history)
        lead[1]["prefixes"] = [{"vertices": n, "distance": cost} for n, cost, _ in points]
    try:
        final, levels = refine(grower, genome or plain, goal, deadline, faces, level,
                               stopped if other is None else lambda: stopped() or other.met(), tail, fills)
        if other is not None and (stopped() or levels[-1].cost <= goal):
            other.stop()  # a winner within the goal waits no longer: the template's cage so far is no simpler
        grown = None if other is None else other.result(stopped)
    finally:
        if other is not None:
            other.close()

    def rank(lv: Level) -> tuple[bool, int, float]:  # within the goal the simpler, else the closer
        return lv.cost > goal, (lv.control.n_vertices if lv.cost <= goal else 0), lv.cost

    if grown is not None:
        for n, cost, history in grown[2]:
            keep(n, cost, history)
        if rank(grown[1][-1]) < rank(levels[-1]):
            final, levels = grown[0], grown[1]
            path = other_path if shaped or other_start else "template, free corners"
    left = 0.0 if deadline is None else (deadline - time.perf_counter()) / max(deadline - started, 1e-9)
    if genome and other is not None and other_start and not stopped() and left > REACHED_SHARE:
        # the start took the template's place in the second process, and both paths ended early: the template
        # grows too, in the time left, and the better by the same rank stands (offset.stl, a rounded frustum
        # under a tube: its tapered walls made five blocks that gained on their body's box; they grew to 504
        # control vertices at 1.6e-3 of the diagonal both ways, the winner to 226 at 1.8e-3, and the template,
        # which they had displaced, reaches 74 at 1.5e-3)
        again, more = refine(grower, plain, goal, deadline, faces, level, should_stop, tail, fills,
                             free_corners=not shaped)
        if rank(more[-1]) < rank(levels[-1]):
            final, levels, path = again, more, "template" if shaped else "template, free corners"
    last = levels[-1]
    free = bool(genome) and quads and other is None and not stopped()
    if (free and last.cost > goal and 4 * last.control.n_faces <= faces  # stalled, not by the face budget
            and left > RESTART_SHARE):
        # the winner's structure stalled early (no op gains on it): the template grows instead, in the time left,
        # and the closer of the two stands (airplane: the search's bevelled cube, 10 vertices, two pentagons, no
        # split and no op gaining, stopped at 2.3e-2 of the diagonal with 210 of its 300 s left)
        again, more = refine(grower, other_start or plain, goal, deadline, faces, level, should_stop, tail, fills)
        if more[-1].cost < last.cost:
            final, levels, path = again, more, other_path
    elif free and last.cost <= goal and left > REACHED_SHARE and last.control.n_faces > grower.template.n_faces:
        # the goal met early: the template grows too, up to a cage simpler than the winner's, and the simpler
        # of the two that meet the goal stands; both paths are points of the front (bone: the search's 24-vertex
        # winner reached 2e-3 of the diagonal at 258 vertices, the placed cube at 114)
        again, more = refine(grower, other_start or plain, goal, deadline, last.control.n_faces - 1, level,
                             should_stop, tail, fills)
        if more[-1].cost <= goal and more[-1].control.n_vertices < last.control.n_vertices:
            final, levels, path = again, more, other_path
    # the kept path's first, all of them for at most config.refine_fill of the refinement's fit rounds (a run that met
    # its goal early does not spend the rest of its budget on them: bone 176 s -> 286 s with no limit); counted, not
    # timed, so that a seed repeats the front
    until = grower.evaluations + int(config.refine_fill * (grower.evaluations - work))
    for _, fill in sorted(fills, key=lambda job: job[0] is not levels):
        fill(until - grower.evaluations)
    rows = [{"vertices": lv.control.n_vertices, "faces": lv.control.n_faces,
             "ops": _letters(lv.ops), "distance": lv.cost, "seconds": lv.seconds, "proposal": lv.kind}
            for lv in levels]
    cost, pareto = levels[-1].cost, front(found)
    simpler = [e for e in pareto if e[0] < levels[-1].control.n_vertices and (e[1] <= goal or e[1] < cost)]
    if simpler:
        # a cage of the front simpler than the paths' last and within the goal, or closer where that is not
        # (text_on_cube in 60 s: the template's creased cube, 8 control vertices at 5.3e-3 of the diagonal both
        # ways, where the searched winner had grown to 66 at 5.9e-3)
        n, cost, final = next(e for e in simpler if e[1] <= goal) if any(e[1] <= goal for e in simpler) else min(
            simpler, key=lambda e: e[1])
        path = FRONT_PATH
    return Growth(final, cost, pareto, rows, path, 1 if other is None else 2,
                  None if lead is None else lead[1], sharp_info if config.sharp_edges else None)


def template_from_config(config: dict[str, Any]) -> PolyMesh:
    """The template saved in a surface result's config (to replay its genome)."""
    try:
        t = config["template"]
        return PolyMesh.from_faces(np.asarray(t["vertices"], dtype=float), t["faces"])
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"result config has no usable template ({exc})") from None
