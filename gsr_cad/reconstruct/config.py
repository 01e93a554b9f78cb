"""Configuration of the curve reconstruction, with the paper's settings and our default preset.

Every field is also a CLI flag (``--field-name``). ``preset="paper"`` reproduces the paper's algorithm
exactly (index-wise fitness, random positions, no polish); ``preset="default"`` keeps the paper's GA but
evaluates each genome after a least-squares placement of its control points (Lamarckian evaluation) with a
geometric fitness that does not assume evenly spaced samples, and chooses the number of control points by
a penalised error (see :mod:`gsr_cad.reconstruct.curve`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, Literal, TypeVar

from ..errors import ConfigError

PRESETS = ("default", "paper")
_ConfigT = TypeVar("_ConfigT", "CurveConfig", "SurfaceConfig")

UNITS: dict[str, str] = {"model": "model units", "mm": "mm", "cm": "cm", "m": "m", "in": "in", "ft": "ft"}
"""What ``units`` may name, and how a length in it is written (a label only: nothing is rescaled)."""

OP_KINDS: dict[str, str] = {
    "V": "vertex translate", "E": "face extrude", "L": "edge loop", "B": "edge bevel", "I": "face inset",
    "F": "face translate", "S": "scale", "C": "edge crease (sharpness)", "R": "face rim crease",
    "H": "through-hole between two facing faces", "X": "extrude a region of faces together",
    "N": "inset a region of faces together",
}
"""The surface op letters ``op_kinds`` may hold, with what each does (the help text lists them from here)."""

UNITS_HELP = ("Unit of the target's coordinates, used to label every length in the summary, report.html, "
              "report.png and result.json (nothing is rescaled); 'model': plain model units.")


_GA_HELP = {
    "mutation_rate": "Probability, in [0, 1], that an op of a child is mutated.",
    "delete_rate": "Probability, in [0, 1], that an op chosen for mutation is deleted rather than replaced.",
    "append_rate": "Probability, in [0, 1], that a child gets one random op appended.",
    "generations": "Most generations the search runs.",
    "stall_generations": "Stop after this many generations without improvement; 0: never.",
    "max_seconds": "Stop the search after this many seconds of wall-clock time; 0: no limit.",
}
"""Help of the GA settings both configs share."""


def _field(default: Any, help: str, *, length: bool = False, **metadata: Any) -> Any:
    """A config field with its help sentence; ``length``: a distance, given on the CLI in model units or as
    ``N%`` of the target's bounding-box diagonal, held here as a fraction of that diagonal. Further
    ``metadata`` for the CLI: ``choices`` (allowed values), ``letters`` (letter -> meaning)."""
    return dataclasses.field(default=default, metadata={"help": help, "length": length, **metadata})


def _flag(field: str) -> str:
    return field.replace("_", "-")


def _real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _whole(low: int) -> Callable[[Any], bool]:
    return lambda value: isinstance(value, int) and not isinstance(value, bool) and value >= low


def _rate(value: Any) -> bool:
    return _real(value) and 0.0 <= value <= 1.0


def _finite_non_negative(value: Any) -> bool:
    return _real(value) and math.isfinite(value) and value >= 0


def _preset(cls: type[_ConfigT], kind: str, name: str, paper: dict[str, Any], overrides: dict[str, Any]
            ) -> _ConfigT:
    """Preset ``name`` ("paper": the fields ``paper``, else the defaults) with the non-None ``overrides``."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r} (choose from {', '.join(PRESETS)})")
    unknown = sorted(set(overrides) - {f.name for f in dataclasses.fields(cls)})
    if unknown:
        raise ConfigError(f"unknown {kind} setting(s): {', '.join(unknown)}")
    base = dict(paper) if name == "paper" else {}
    base.update({k: v for k, v in overrides.items() if v is not None})
    return cls(**base).validated()


def _check_units(config: Any) -> None:
    _check(config, ("units",), UNITS.__contains__, f"be one of {', '.join(UNITS)}")


def _check(config: Any, fields: tuple[str, ...], ok: Callable[[Any], bool], requirement: str) -> None:
    """ConfigError naming the first of ``fields`` whose value is not ``ok`` (it "must ``requirement``")."""
    for field in fields:
        value = getattr(config, field)
        if not ok(value):
            raise ConfigError(f"{_flag(field)} must {requirement}, not {value!r}")


def _ranges(config: Any, limits: dict[str, tuple[float, float]]) -> None:
    """ConfigError naming the first field outside its allowed range ``[low, high]`` (stated in the message)."""
    for field, (low, high) in limits.items():
        value = getattr(config, field)
        if value is not None and _real(value) and not low <= value <= high:
            raise ConfigError(f"{_flag(field)} must lie in [{low:g}, {high:g}], not {value!r}")


REFINE_STALL_GAIN = 0.1
"""With the refinement on, the search ends once ``refine_stall`` generations gained less than this share: on real
targets it creeps by a few percent per ten generations there (minutes), where the refinement's splits gain
several times more per second."""

_RUN_LIMITS = {"population": (2, 10_000), "initial_population": (1, 100_000), "min_initial_ops": (1, 50),
               "max_initial_ops": (1, 50), "min_ops": (1, 50), "generations": (1, 1_000_000),
               "stall_generations": (0, 1_000_000), "max_seconds": (0, 2_592_000)}
"""Allowed ranges of the GA settings shared by curves and surfaces (max-seconds: 30 days)."""
CURVE_LIMITS = {**_RUN_LIMITS, "tolerance": (0, 1), "max_distance": (0, 1), "bounds_margin": (0, 100),
                "move_scale": (0, 10), "max_control_points": (0, 10_000), "fit_iterations": (1, 10_000),
                "threshold": (-1e300, 1e300)}
"""Allowed range of each numeric curve setting (distances are fractions of the target's diagonal)."""
SURFACE_LIMITS = {**_RUN_LIMITS, "move_range": (0, 10), "extrude_range": (0, 10),
                  "face_move_range": (0, 10), "perturb_rel": (0, 1), "max_scale_factor": (1, 100),
                  "max_control_faces": (1, 100_000), "max_target_points": (0, 20_000_000),
                  "polish_rounds": (0, 1000), "final_polish_rounds": (0, 1000), "polish_every": (0, 1_000_000),
                  "polish_niches": (1, 100), "polish_damping": (0, 1000), "history_tolerance": (0, 1),
                  "threshold": (0, 10), "n_parents": (0, 10_000), "max_children": (0, 10_000),
                  "n_perturb": (0, 10_000), "n_newcomers": (0, 10_000), "max_duplicates": (1, 10_000),
                  "refine_until": (0, 10), "refine_max_faces": (1, 100_000),
                  "refine_points": (100, 20_000_000), "refine_share": (0, 0.99),
                  "refine_seconds": (0, 2_592_000), "refine_fill": (0, 10), "refine_stall": (0, 1_000_000),
                  "refine_workers": (0, 2)}
"""Allowed range of each numeric surface setting (distances are fractions of the target's diagonal)."""


@dataclasses.dataclass(frozen=True)
class CurveConfig:
    """All settings of a curve reconstruction (see the module docstring for the presets)."""

    scheme: Literal["bspline", "chaikin"] = _field(
        "bspline",
        "How the control polygon becomes a curve: 'bspline' a clamped uniform cubic B-spline, 'chaikin' Chaikin "
        "corner cutting (its quadratic B-spline limit).")
    fitness: Literal["geometric", "index"] = _field(
        "geometric",
        "How a curve is scored: 'geometric' each target point's distance to its nearest curve point, 'index' the "
        "i-th point's distance to the i-th of as many evenly spaced curve samples (the paper's).")
    polish: bool = _field(
        True,
        "Score each genome after a least-squares placement of its control points; off: score the genome's own "
        "positions (the paper's).")
    tolerance: float = _field(
        1e-5,
        "RMS distance to the target below which more control points bring nothing (the cost's error floor); 0: "
        "none, every point that lowers the error counts.", length=True)
    max_distance: float | None = _field(
        None,
        "CAD tolerance: the largest distance of any target point to the curve that the result must meet (missed: "
        "a warning and exit code 3); none: no maximum.", length=True)
    bounds_margin: float = _field(
        1.0,
        "Margin of the box the control points must stay in, in target bounding-box diagonals added on every side;"
        " 0: the target's own bounding box.")
    local_add: bool = _field(
        True,
        "Insert new control points near their neighbours (Gaussian); off: anywhere in the box (the paper's).")
    p_add: float = _field(
        0.5,
        "Probability, in [0, 1], that a random op inserts a control point rather than moves one.")
    move_scale: float = _field(
        0.25,
        "Largest random move of a control point per axis, as a fraction of the box size; 0: points never move.")
    max_control_points: int = _field(
        0,
        "Most control points a curve may have; 0: no cap (a segment between corners gets at most two thirds of "
        "its points).")
    fit_iterations: int = _field(
        25,
        "Foot-point iterations of each least-squares placement (more: slower, slightly tighter).")
    initial_population: int = _field(
        100,
        "Random genomes drawn in generation 0, before the cut to --population (the paper preset: 1000; with polish "
        "a genome is scored by its structure, which a first population of --population genomes already covers).")
    population: int = _field(100, "Genomes kept from one generation to the next.")
    min_initial_ops: int = _field(4, "Fewest ops in a random initial genome.")
    max_initial_ops: int = _field(8, "Most ops in a random initial genome.")
    min_ops: int = _field(3, "Fewest ops a genome may have (shorter ones are repaired).")
    elite_fraction: float = _field(
        0.2,
        "Fraction, in (0, 1), of the best genomes copied unchanged into the next generation.")
    mutation_rate: float = _field(0.05, _GA_HELP["mutation_rate"])
    delete_rate: float = _field(0.01, _GA_HELP["delete_rate"])
    append_rate: float = _field(0.05, _GA_HELP["append_rate"])
    generations: int = _field(100, _GA_HELP["generations"])
    threshold: float = _field(
        0.0,
        "Stop once the best fitness (the cost, see fitness_kind in result.json) is at or below this; 0: no threshold; "
        "negative: 1e-4 of the diagonal per target point (the paper's rule, used without polish).")
    stall_generations: int = _field(15, _GA_HELP["stall_generations"])
    max_seconds: float = _field(0.0, _GA_HELP["max_seconds"])
    units: str = _field("model", UNITS_HELP, choices=tuple(UNITS))
    closure: Literal["auto", "closed", "open"] = _field(
        "auto",
        "Closed (periodic, no seam) or open curve; auto: closed when the last point is within about three sample "
        "spacings of the first (--closed / --open on the command line).")
    find_corners: bool = _field(
        True,
        "Propose C0 corners (a knot of multiplicity = degree: the curve passes through that control point) at sharp "
        "turns of the data; off: smooth curves only.")
    corner_angle: float = _field(
        25.0, "Smallest turning angle, in degrees, of a data point proposed as a corner.")
    search_points: int = _field(
        3000,
        "The search fits at most about this many of the points (metrics and the tolerance check use all of them); "
        "0: all points.")
    tolerance_stall_generations: int = _field(
        3,
        "With max-distance: generations without improvement that end the search (the structure search already "
        "gives every segment the fewest points meeting it); 0: stall-generations.")

    @classmethod
    def preset(cls, name: str = "default", **overrides: Any) -> CurveConfig:
        """A named preset with field overrides (unknown fields raise ConfigError)."""
        paper = dict(fitness="index", polish=False, bounds_margin=0.0, local_add=False, move_scale=0.1,
                     initial_population=1000, generations=300, stall_generations=0, threshold=-1.0, closure="open", find_corners=False,
                     search_points=0)
        return _preset(cls, "curve", name, paper, overrides)

    def validated(self) -> CurveConfig:
        """Return self, or raise ConfigError naming the first absurd setting."""
        if self.scheme not in ("bspline", "chaikin"):
            raise ConfigError(f"scheme must be bspline or chaikin, not {self.scheme!r}")
        if self.fitness not in ("geometric", "index"):
            raise ConfigError(f"fitness must be geometric or index, not {self.fitness!r}")
        _check(self, ("initial_population", "population", "generations", "min_ops", "min_initial_ops",
                      "max_initial_ops", "fit_iterations"), _whole(1), "be a positive whole number")
        if self.population < 2:
            raise ConfigError("population must be at least 2")
        if self.initial_population < self.population:
            raise ConfigError("initial-population must be at least the population")
        if self.max_initial_ops < self.min_initial_ops:
            raise ConfigError("max-initial-ops must be >= min-initial-ops")
        _check(self, ("mutation_rate", "delete_rate", "append_rate", "p_add"), _rate, "lie in [0, 1]")
        if not (0.0 < self.elite_fraction < 1.0):
            raise ConfigError(f"elite-fraction must lie in (0, 1), not {self.elite_fraction!r}")
        _check(self, ("tolerance", "bounds_margin", "move_scale", "max_seconds"), _finite_non_negative,
               "be a finite number >= 0")
        if self.max_distance is not None and not (math.isfinite(self.max_distance) and self.max_distance > 0):
            raise ConfigError(f"max-distance must be a positive number, not {self.max_distance!r}")
        if not math.isfinite(self.threshold):
            raise ConfigError("threshold must be finite")
        if self.stall_generations < 0 or self.max_control_points < 0:
            raise ConfigError("stall-generations and max-control-points must be >= 0")
        if self.max_control_points and self.max_control_points < 4:
            raise ConfigError("max-control-points must be at least 4 (the template has 4)")
        if self.closure not in ("auto", "closed", "open"):
            raise ConfigError(f"closure must be auto, closed or open, not {self.closure!r}")
        if not (_real(self.corner_angle) and 0.0 < self.corner_angle < 180.0):
            raise ConfigError(f"corner-angle must lie in (0, 180) degrees, not {self.corner_angle!r}")
        if not (isinstance(self.search_points, int) and (self.search_points == 0 or self.search_points >= 100)):
            raise ConfigError(f"search-points must be 0 or at least 100, not {self.search_points!r}")
        _check_units(self)
        _ranges(self, CURVE_LIMITS)
        return self

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


# --- surfaces ------------------------------------------------------------------------------------------------

SURFACE_FITNESS = ("surface", "mixed")


@dataclasses.dataclass(frozen=True)
class SurfaceConfig:
    """All settings of a surface reconstruction (see :mod:`gsr_cad.reconstruct.surface` for the presets).

    The GA fields default to the paper's surface settings (section 5); ``threshold`` stops the run once
    the best cost reaches it. ``fitness`` "surface" is the symmetric point-to-surface distance, "mixed"
    the paper's mixed mean distance (both over the target's bounding-box diagonal). The polish:
    ``polish_rounds`` > 0 scores every genome after up to that many least-squares rounds on its control
    vertices, stopping once a round gains less than the factor ``polish_gain`` (the genome keeps its own
    positions); ``polish_every`` = k > 0 writes the polish back into the best genome of each of the
    ``polish_niches`` best connectivities every k generations;
    the winner is polished with up to ``final_polish_rounds`` rounds; ``polish_damping`` pulls each round
    lightly towards the current positions. ``template_fit``: the default cube template scaled per axis
    ("box") or uniformly ("cube") to the target's box. Op ranges are fractions of the target's
    bounding-box diagonal (see :class:`~gsr_cad.ops.mesh.OpRanges`); ``max_control_faces`` bounds the
    control mesh, ``max_target_points`` the target points scored (a fixed random subset of larger ones).
    ``simplify_history`` rewrites the winner's history into the shortest equivalent one found (see
    :mod:`gsr_cad.ops.rewrite`) if that raises its distance to the target by at most ``history_tolerance``.
    """

    template_fit: Literal["box", "cube"] = _field(
        "box",
        "How the default cube template is fitted to the target's bounding box: 'box' scaled per axis, 'cube' "
        "scaled uniformly (the paper's).")
    max_distance: float | None = _field(
        None,
        "Pick the cage with the fewest control vertices on the accuracy/complexity front whose search distance "
        "(mean of both directions) is at most this; none: the most accurate.", length=True)
    fit_template: bool = _field(
        True,
        "Fit a user --template file to the target by a similarity (scale, rotation, translation) before the search; "
        "off: use it as given.")
    levels: int = _field(
        2,
        "Catmull-Clark subdivision levels of the limit mesh compared with the target (1 to 4; each level "
        "quadruples the faces).")
    limit_depth: int = _field(
        5,
        "Refinement steps next to extraordinary vertices when the exact limit surface is evaluated (each quarters "
        "the area left as flat triangles); 0: none.")
    boundary: Literal["all", "corners"] = _field(
        "all",
        "Boundary rule of the subdivision: 'all' smooths boundary corners too (Blender's default), 'corners' "
        "keeps them fixed.")
    fitness: Literal["surface", "mixed"] = _field(
        "surface",
        "What the search minimises: 'surface' the symmetric point-to-surface distance, 'mixed' the paper's mixed "
        "mean distance (both over the diagonal).")
    op_kinds: str = _field("VELBIFS", "Modelling ops the search may use, one letter each:", letters=OP_KINDS)
    move_range: float = _field(
        0.1,
        "Largest random vertex move (V) per axis, as a fraction of the target's bounding-box diagonal.")
    extrude_range: float = _field(
        0.5,
        "Largest random extrusion (E), as a fraction of the target's bounding-box diagonal.")
    inward_rate: float = _field(
        0.2,
        "Probability, in [0, 1], that a random extrusion goes into the mesh (a pocket); 0: outwards only (the "
        "paper's).")
    face_move_range: float = _field(
        0.1,
        "Largest random face move (F) along its normal, as a fraction of the target's bounding-box diagonal.")
    max_scale_factor: float = _field(
        1.25,
        "Largest random scale (S) factor (and its inverse the smallest); 1: no scaling.")
    perturb_rel: float = _field(
        0.02,
        "Size of the nudge a perturbed op's parameters get, as a fraction of the target's bounding-box diagonal.")
    max_control_faces: int = _field(120, "Most faces a control mesh may have (larger genomes are repaired).")
    max_target_points: int = _field(
        1500,
        "Most target points scored during the search (a fixed random subset of larger targets); 0: all.")
    polish_rounds: int = _field(
        6,
        "Least-squares rounds on the control vertices before each genome is scored; 0: no polish (the paper's).")
    polish_gain: float = _field(
        0.7,
        "Stop polishing once a round shrinks the error by less than this factor, in (0, 1].")
    final_polish_rounds: int = _field(
        20,
        "Least-squares rounds on the winner's control vertices after the search; 0: none.")
    polish_every: int = _field(
        1,
        "Write the polish back into the best genomes every this many generations; 0: never.")
    polish_niches: int = _field(3, "How many of the best connectivities get their best genome polished back.")
    polish_damping: float = _field(
        1e-3,
        "Pull of each polish round towards the current positions (relative to the system's scale); 0: none.")
    simplify_history: bool = _field(
        True,
        "Rewrite the winner's history into the shortest equivalent one found; off: keep it as searched.")
    history_tolerance: float = _field(
        1e-6,
        "How much the history rewrite may raise the distance to the target; 0: only exact rewrites.", length=True)
    refine: bool = _field(
        True,
        "After the search, grow the cage where the residual is (edge loops, extrudes, insets, bevels aimed at the "
        "largest two-sided error, each least-squares fitted) until --max-distance or --refine-until is met, the "
        "time runs out or no op gains; off: the searched cage as it is.")
    refine_until: float = _field(
        2e-3,
        "Distance (mean of both directions) at which the refinement stops when no --max-distance is given.",
        length=True)
    refine_max_faces: int = _field(1600, "Most faces the refinement may grow the cage to.")
    refine_points: int = _field(
        8000,
        "Least target points the refinement fits (at least --max-target-points; its cages reach hundreds of "
        "control vertices): fewer is faster and coarser; the reported distances use every point either way.")
    survival: str = _field(
        "cost",
        "How the search keeps its population: cost (the lowest distances, the paper's) or nsga2 (NSGA-II's rank and "
        "crowding on distance and control vertices: a spread of the accuracy/complexity front).",
        choices=("cost", "nsga2"))
    refine_share: float = _field(
        0.8,
        "Share of --max-seconds left to the refinement when it is on (the search stops earlier by as much), in "
        "[0, 1).")
    refine_seconds: float = _field(
        300.0,
        "Most seconds the refinement may take when no --max-seconds is given; 0: no limit.")
    refine_fill: float = _field(
        0.5,
        "After the refinement, the front's cages between its levels (a prefix of a level's loops or insets, fitted "
        "in full, for --max-distance to pick from) get at most this share of its fit rounds (counted, so a seed "
        "repeats them); 0: none.")
    refine_workers: int = _field(
        0,
        "Processes the refinement grows on: 2 grows the placed template in a second process beside the searched "
        "winner, and the closer stands; 1 grows the template after the winner only when time is left; 0: 2 where "
        "this process may use two or more CPUs, else 1.")
    sharp_edges: bool = _field(
        True,
        "Crease (infinitely sharp) the control edges that run along the target's sharp feature lines where that "
        "brings the fitted cage closer: a designer's start (body and blocks or legs) and the search's simple cages "
        "on the front; off: smooth cages only.")
    population: int = _field(100, "Individuals kept from one generation to the next.")
    initial_population: int = _field(100, "Random genomes drawn in generation 0.")
    min_initial_ops: int = _field(1, "Fewest ops in a random initial genome (and in a newcomer).")
    max_initial_ops: int = _field(2, "Most ops in a random initial genome (and in a newcomer).")
    min_ops: int = _field(1, "Fewest ops a genome may have.")
    n_parents: int = _field(20, "Parents chosen for crossover each generation.")
    max_children: int = _field(10, "Most children of one pair of parents.")
    n_perturb: int = _field(10, "Best individuals whose parameters are perturbed each generation; 0: none.")
    n_newcomers: int = _field(10, "Random newcomers added each generation; 0: none.")
    max_duplicates: int = _field(3, "Most copies of one genome kept in the population.")
    mutation_rate: float = _field(0.05, _GA_HELP["mutation_rate"])
    delete_rate: float = _field(0.01, _GA_HELP["delete_rate"])
    append_rate: float = _field(0.1, _GA_HELP["append_rate"])
    generations: int = _field(200, _GA_HELP["generations"])
    threshold: float = _field(
        1e-5,
        "Stop once the best fitness (a distance over the diagonal, see --fitness) is at or below this; 0: only on"
        " a perfect fit.")
    stall_generations: int = _field(0, _GA_HELP["stall_generations"])
    stall_gain: float = _field(
        0.0,
        "A generation counts as an improvement for --stall-generations only when it lowers the best fitness by "
        "more than this fraction of it, in [0, 1); 0: any gain.")
    refine_stall: int = _field(
        10,
        "With the refinement on and no --stall-generations: the search ends after this many generations that "
        f"together lower its best distance by less than {REFINE_STALL_GAIN:.0%} (the refinement grows the cage "
        "faster from there); 0: the search runs its --generations.")
    max_seconds: float = _field(0.0, _GA_HELP["max_seconds"])
    units: str = _field("model", UNITS_HELP, choices=tuple(UNITS))

    @classmethod
    def preset(cls, name: str = "default", **overrides: Any) -> SurfaceConfig:
        """A named preset with field overrides (unknown fields raise ConfigError)."""
        paper = dict(template_fit="cube", fitness="mixed", move_range=1.0, extrude_range=1.0, inward_rate=0.0,
                     polish_rounds=0, final_polish_rounds=0, polish_every=0, threshold=0.0, simplify_history=False,
                     refine=False)
        return _preset(cls, "surface", name, paper, overrides)

    def validated(self) -> SurfaceConfig:
        """Return self, or raise ConfigError naming the first absurd setting."""
        choices = {"template_fit": ("box", "cube"), "boundary": ("all", "corners"), "fitness": SURFACE_FITNESS,
                   "survival": ("cost", "nsga2")}
        for field, allowed in choices.items():
            _check(self, (field,), allowed.__contains__, f"be one of {', '.join(allowed)}")
        kinds = self.op_kinds
        if not isinstance(kinds, str) or not kinds or set(kinds) - set(OP_KINDS) or len(set(kinds)) != len(kinds):
            raise ConfigError(f"op-kinds must be distinct letters from {''.join(OP_KINDS)}, not {kinds!r}")
        _check(self, ("levels", "max_control_faces", "max_target_points", "polish_rounds", "final_polish_rounds",
                      "polish_every", "polish_niches", "population", "initial_population", "min_initial_ops",
                      "max_initial_ops", "min_ops", "n_parents", "max_children", "n_perturb", "n_newcomers",
                      "max_duplicates", "generations", "stall_generations", "refine_stall", "refine_max_faces",
                      "refine_points", "refine_workers"),
               _whole(0),
               "be a whole number >= 0")
        _check(self, ("levels", "polish_niches", "population", "initial_population", "min_initial_ops", "min_ops",
                      "n_parents", "max_duplicates", "generations", "max_control_faces"), _whole(1), "be at least 1")
        if self.max_distance is not None and not (_real(self.max_distance) and math.isfinite(self.max_distance)
                                                  and self.max_distance > 0):
            raise ConfigError(f"max-distance must be a positive number, not {self.max_distance!r}")
        _check(self, ("limit_depth",), lambda x: _whole(0)(x) and x <= 8, "be a whole number from 0 to 8")
        if self.levels > 4:
            raise ConfigError(f"levels must be at most 4 (each level quadruples the faces), not {self.levels}")
        if self.max_target_points and self.max_target_points < 4:
            raise ConfigError("max-target-points must be 0 (all) or at least 4")
        if self.population < 2:
            raise ConfigError("population must be at least 2")
        if self.max_initial_ops < self.min_initial_ops:
            raise ConfigError("max-initial-ops must be >= min-initial-ops")
        if self.n_parents > self.population or self.n_perturb > self.population:
            raise ConfigError("n-parents and n-perturb must not exceed the population")
        _check(self, ("mutation_rate", "delete_rate", "append_rate", "inward_rate"), _rate, "lie in [0, 1]")
        _check(self, ("polish_gain",), lambda v: _real(v) and 0.0 < v <= 1.0, "lie in (0, 1]")
        _check(self, ("stall_gain",), lambda v: _real(v) and 0.0 <= v < 1.0, "lie in [0, 1)")
        _check(self, ("move_range", "extrude_range", "face_move_range", "perturb_rel", "polish_damping", "threshold",
                      "max_seconds", "history_tolerance", "refine_until", "refine_share", "refine_seconds"),
               _finite_non_negative, "be a finite number >= 0")
        _check(self, ("max_scale_factor",), lambda v: _finite_non_negative(v) and v >= 1.0, "be a finite number >= 1")
        _check_units(self)
        _ranges(self, SURFACE_LIMITS)
        return self

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
