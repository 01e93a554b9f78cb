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


def _check(config: Any, fields: tuple[str, ...], ok: Callable[[Any], bool], requirement: str) -> None:
    """ConfigError naming the first of ``fields`` whose value is not ``ok`` (it "must ``requirement``")."""
    for field in fields:
        value = getattr(config, field)
        if not ok(value):
            raise ConfigError(f"{_flag(field)} must {requirement}, not {value!r}")


@dataclasses.dataclass(frozen=True)
class CurveConfig:
    """All settings of a curve reconstruction (see the module docstring for the presets)."""

    scheme: Literal["bspline", "chaikin"] = "bspline"
    fitness: Literal["geometric", "index"] = "geometric"
    polish: bool = True
    tolerance: float = 1e-5
    max_distance: float | None = None
    bounds_margin: float = 1.0
    local_add: bool = True
    p_add: float = 0.5
    move_scale: float = 0.25
    max_control_points: int = 0
    fit_iterations: int = 25
    initial_population: int = 1000
    population: int = 100
    min_initial_ops: int = 4
    max_initial_ops: int = 8
    min_ops: int = 3
    elite_fraction: float = 0.2
    mutation_rate: float = 0.05
    delete_rate: float = 0.01
    append_rate: float = 0.05
    generations: int = 100
    threshold: float = 0.0
    stall_generations: int = 15
    max_seconds: float = 0.0
    closure: Literal["auto", "closed", "open"] = dataclasses.field(default="auto", metadata={
        "help": "closed (periodic) or open curve; auto: closed when the last point is about one sample spacing "
                "from the first"})
    find_corners: bool = dataclasses.field(default=True, metadata={
        "help": "propose C0 corners (knot multiplicity = degree) at sharp turns of the data; off: smooth curves only"})
    corner_angle: float = dataclasses.field(default=25.0, metadata={
        "help": "smallest turning angle, in degrees, of a data point proposed as a corner"})
    search_points: int = dataclasses.field(default=3000, metadata={
        "help": "the search fits at most about this many of the points (metrics use all of them); 0: all points"})

    @classmethod
    def preset(cls, name: str = "default", **overrides: Any) -> CurveConfig:
        """A named preset with field overrides (unknown fields raise ConfigError)."""
        paper = dict(fitness="index", polish=False, bounds_margin=0.0, local_add=False, move_scale=0.1,
                     generations=300, stall_generations=0, threshold=-1.0, closure="open", find_corners=False,
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

    template_fit: Literal["box", "cube"] = "box"
    levels: int = 2
    boundary: Literal["all", "corners"] = "all"
    fitness: Literal["surface", "mixed"] = "surface"
    op_kinds: str = "VELBIFS"
    move_range: float = 0.1
    extrude_range: float = 0.5
    inward_rate: float = 0.2
    face_move_range: float = 0.1
    max_scale_factor: float = 1.25
    perturb_rel: float = 0.02
    max_control_faces: int = 120
    max_target_points: int = 3000
    polish_rounds: int = 6
    polish_gain: float = 0.7
    final_polish_rounds: int = 20
    polish_every: int = 1
    polish_niches: int = 3
    polish_damping: float = 1e-3
    simplify_history: bool = True
    history_tolerance: float = 1e-6
    population: int = 100
    initial_population: int = 100
    min_initial_ops: int = 1
    max_initial_ops: int = 2
    min_ops: int = 1
    n_parents: int = 20
    max_children: int = 10
    n_perturb: int = 10
    n_newcomers: int = 10
    max_duplicates: int = 3
    mutation_rate: float = 0.05
    delete_rate: float = 0.01
    append_rate: float = 0.1
    generations: int = 200
    threshold: float = 1e-5
    stall_generations: int = 0
    max_seconds: float = 0.0

    @classmethod
    def preset(cls, name: str = "default", **overrides: Any) -> SurfaceConfig:
        """A named preset with field overrides (unknown fields raise ConfigError)."""
        paper = dict(template_fit="cube", fitness="mixed", move_range=1.0, extrude_range=1.0, inward_rate=0.0,
                     polish_rounds=0, final_polish_rounds=0, polish_every=0, threshold=0.0, simplify_history=False)
        return _preset(cls, "surface", name, paper, overrides)

    def validated(self) -> SurfaceConfig:
        """Return self, or raise ConfigError naming the first absurd setting."""
        choices = {"template_fit": ("box", "cube"), "boundary": ("all", "corners"), "fitness": SURFACE_FITNESS}
        for field, allowed in choices.items():
            _check(self, (field,), allowed.__contains__, f"be one of {', '.join(allowed)}")
        kinds = self.op_kinds
        if not isinstance(kinds, str) or not kinds or set(kinds) - set("VELBIFS") or len(set(kinds)) != len(kinds):
            raise ConfigError(f"op-kinds must be distinct letters from VELBIFS, not {kinds!r}")
        _check(self, ("levels", "max_control_faces", "max_target_points", "polish_rounds", "final_polish_rounds",
                      "polish_every", "polish_niches", "population", "initial_population", "min_initial_ops",
                      "max_initial_ops", "min_ops", "n_parents", "max_children", "n_perturb", "n_newcomers",
                      "max_duplicates", "generations", "stall_generations"), _whole(0), "be a whole number >= 0")
        _check(self, ("levels", "polish_niches", "population", "initial_population", "min_initial_ops", "min_ops",
                      "n_parents", "max_duplicates", "generations", "max_control_faces"), _whole(1), "be at least 1")
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
        _check(self, ("move_range", "extrude_range", "face_move_range", "perturb_rel", "polish_damping", "threshold",
                      "max_seconds", "history_tolerance"), _finite_non_negative, "be a finite number >= 0")
        _check(self, ("max_scale_factor",), lambda v: _finite_non_negative(v) and v >= 1.0, "be a finite number >= 1")
        return self

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
