"""The exporter protocol and what every exporter shares.

An exporter turns a :class:`~gsr_cad.reconstruct.result.Result` into files one CAD host reads, and
validates such a file by running the real host (or an independent reader) on it and comparing what comes
back with *our* geometry. Exporters declare the result kinds they support; ``export``/``validate`` dispatch
to ``export_<kind>``/``validate_<kind>``, so a surface branch is added by writing two methods and adding
``"surface"`` to ``kinds``; the registry (``gsr_cad.cli.formats``) never offers an exporter for a kind it
does not declare.

What results become is shared here: :func:`curve_spline` (a curve's B-spline) and :func:`surface_patches`
(a surface's limit patches, fitted once per result for every exporter).

Tolerances are relative to the geometry's scale, ``max(1, largest absolute coordinate)``: data stored as
numbers (poles, knots, nodes) must come back within :data:`EXACT_TOL` of it, points a host evaluates
within :data:`SAMPLE_TOL`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ExportError, GsrError, InputError, OpError
from gsr_cad.geometry import bspline
from gsr_cad.geometry.patches import PatchSet, limit_patches
from gsr_cad.ops import curve as curve_ops

EXACT_TOL = 1e-9
SAMPLE_TOL = 1e-6
PATCH_TOLERANCE = 1e-4
"""Default largest deviation of the limit-surface patches from the limit surface, relative to its diagonal."""


@dataclasses.dataclass(frozen=True)
class Check:
    """One validation finding: ``passed`` is None when the check could not run (host missing)."""

    file: str
    host: str
    check: str
    deviation: float | None
    passed: bool | None
    detail: str = ""

    @property
    def status(self) -> str:
        """One of "pass", "FAIL", "skip"."""
        return "skip" if self.passed is None else ("pass" if self.passed else "FAIL")


def measured(file: Path | str, host: str, check: str, deviation: float, tol: float, detail: str = "") -> Check:
    """A check that passes when ``deviation`` is finite and at most ``tol``."""
    dev = float(deviation)
    ok = math.isfinite(dev) and dev <= tol
    return Check(Path(file).name, host, check, dev, ok, detail or f"tolerance {tol:.3g}")


def failed(file: Path | str, host: str, check: str, detail: str) -> Check:
    """A check that failed without a deviation to report (unreadable file, wrong structure)."""
    return Check(Path(file).name, host, check, None, False, detail)


def skipped(file: Path | str, host: str, check: str, reason: str) -> Check:
    """A check that could not run, e.g. because the host is not installed."""
    return Check(Path(file).name, host, check, None, None, reason)


def expect_equal(file: Path | str, host: str, check: str, got: Any, want: Any) -> Check:
    """A structural check (counts, degrees, names): passes when ``got == want``."""
    ok = got == want
    detail = "as expected" if ok else f"got {got!r}, expected {want!r}"
    return Check(Path(file).name, host, check, None, ok, detail if len(detail) <= 160 else detail[:157] + "...")


def point_deviation(got: np.ndarray, want: np.ndarray) -> float:
    """Largest distance between corresponding points (or values); inf when the shapes differ."""
    a, b = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    if a.shape != b.shape or a.size == 0:
        return math.inf
    if a.ndim == 1:
        return float(np.max(np.abs(a - b)))
    return float(np.max(np.linalg.norm(a - b, axis=-1)))


def _planar(points: Any, dim: int) -> np.ndarray:
    a = np.asarray(points, dtype=float)
    if a.ndim == 2 and a.shape[1] == 2 and dim == 3:
        a = np.column_stack([a, np.zeros(len(a))])
    return a


def curve_checks(path: Path | str, host: str, spline: CurveSpline, params: np.ndarray, *, degree: int,
                 rational: bool, poles: Any, knots: Any, samples: Any,
                 param_range: Sequence[float] | None = None) -> list[Check]:
    """The checks every exact-B-spline format shares: degree, non-rational, poles and flattened knots
    (within :data:`EXACT_TOL`), the parameter range [0, 1], and the host's own evaluation at ``params``
    (within :data:`SAMPLE_TOL`; skipped when ``samples`` is None). ``poles``/``samples`` may be 2-D or 3-D
    (then z must be 0)."""
    got_poles = np.asarray(poles, dtype=float)
    got_samples = np.asarray(samples if samples is not None else [], dtype=float)
    dim = got_poles.shape[1] if got_poles.ndim == 2 else 2
    checks = [
        expect_equal(path, host, "degree", int(degree), spline.degree),
        expect_equal(path, host, "non-rational", bool(rational), False),
        measured(path, host, "poles", point_deviation(got_poles, _planar(spline.poles, dim)),
                 EXACT_TOL * spline.scale),
        measured(path, host, "knots", point_deviation(np.asarray(knots, dtype=float), spline.knots), EXACT_TOL),
    ]
    if param_range is not None:
        checks.append(measured(path, host, "parameter range",
                               point_deviation(np.asarray(param_range, dtype=float), np.array([0.0, 1.0])),
                               EXACT_TOL))
    if samples is None:
        return checks
    dim = got_samples.shape[1] if got_samples.ndim == 2 else 2
    checks.append(measured(path, host, f"{len(params)} curve samples",
                           point_deviation(got_samples, _planar(spline.points(params), dim)),
                           SAMPLE_TOL * spline.scale))
    return checks


def num(x: float) -> str:
    """Shortest text that reads back as exactly the same double."""
    return repr(float(x))


def patch_literals(patch: Any) -> tuple[str, str, str, str, str]:
    """Python literals of a B-spline patch for generated scripts: its poles ``[[(x, y, z), ...], ...]`` (rows
    along u), then its distinct u knots, their multiplicities, the v knots and theirs, exactly (:func:`num`)."""
    poles = "[" + ", ".join("[" + ", ".join(f"({num(x)}, {num(y)}, {num(z)})" for x, y, z in row) + "]"
                            for row in patch.poles.tolist()) + "]"
    (uk, um), (vk, vm) = patch.breakpoints_u, patch.breakpoints_v
    return (poles, "[" + ", ".join(num(k) for k in uk) + "]", "[" + ", ".join(str(int(m)) for m in um) + "]",
            "[" + ", ".join(num(k) for k in vk) + "]", "[" + ", ".join(str(int(m)) for m in vm) + "]")


@dataclasses.dataclass(frozen=True)
class CurveSpline:
    """A curve result as CAD sees it: poles, degree and the clamped uniform knot vector on [0, 1]."""

    poles: np.ndarray
    degree: int
    knots: np.ndarray

    @property
    def breakpoints(self) -> np.ndarray:
        """Distinct knot values."""
        return np.unique(self.knots)

    @property
    def multiplicities(self) -> np.ndarray:
        """Multiplicity of each distinct knot."""
        return np.unique(self.knots, return_counts=True)[1]

    @property
    def n_spans(self) -> int:
        return len(self.poles) - self.degree

    @property
    def scale(self) -> float:
        """``max(1, largest absolute coordinate)``: the unit of every tolerance."""
        return max(1.0, float(np.max(np.abs(self.poles))))

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal of the control polygon (1 when it is a point)."""
        d = float(np.linalg.norm(np.ptp(self.poles, axis=0)))
        return d if d > 0 else 1.0

    def points(self, params: np.ndarray) -> np.ndarray:
        """Our curve at ``params`` in [0, 1]."""
        return bspline.evaluate(self.poles, np.asarray(params, dtype=float), self.degree)

    def bezier(self) -> np.ndarray:
        """Exact Bezier pieces ``(n_spans, degree + 1, 2)``; span ``j`` covers ``[j, j + 1] / n_spans``."""
        return bspline.bezier_segments(self.poles, self.degree)

    def params(self, per_span: int) -> np.ndarray:
        """``per_span`` parameters per knot span, both ends included."""
        return np.linspace(0.0, 1.0, self.n_spans * per_span + 1)

    def dense(self, per_span: int = 64) -> np.ndarray:
        """A polyline close to the curve (for stroke widths, not for exact comparisons)."""
        return self.points(self.params(per_span))


def curve_spline(result: Any) -> CurveSpline:
    """The B-spline of a curve result; ExportError when it has too few or non-finite control points."""
    if result.kind != "curve" or result.control_points is None:
        raise ExportError(f"expected a curve result, got a {result.kind} result")
    poles = np.asarray(result.control_points, dtype=float)
    degree = int(result.degree)
    if poles.ndim != 2 or poles.shape[1] != 2 or not np.all(np.isfinite(poles)):
        raise ExportError("curve control points must be finite [x, y] rows")
    if len(poles) < degree + 1:
        raise ExportError(f"a degree-{degree} curve needs at least {degree + 1} control points, got {len(poles)}")
    return CurveSpline(poles, degree, bspline.clamped_uniform_knots(len(poles), degree))


@dataclasses.dataclass(frozen=True)
class HistoryStep:
    """The control polygon after one op (``op`` None for the template), with a readable label."""

    label: str
    op: dict[str, Any] | None
    points: np.ndarray


def _fmt_pair(v: Sequence[float]) -> str:
    return f"({float(v[0]):.4g}, {float(v[1]):.4g})"


def op_label(number: int, op: dict[str, Any] | None, width: int = 2) -> str:
    """``"03 add point 2 at (0.41, 0.77)"``: the step number, then the op in words."""
    head = f"{number:0{width}d}"
    if op is None:
        return f"{head} template"
    name = str(op.get("op", "op"))
    if name == "add_point":
        return f"{head} add point {op['index']} at {_fmt_pair(op['position'])}"
    if name == "move_point":
        return f"{head} move point {op['index']} by {_fmt_pair(op['delta'])}"
    fields = ", ".join(f"{k}={v}" for k, v in op.items() if k != "op")
    return f"{head} {name.replace('_', ' ')} {fields}".rstrip()


def curve_history(result: Any) -> list[HistoryStep]:
    """Replay the genome on the template stored in ``result.config`` and label every state.

    Raises ExportError when the result carries no template or when the replay does not rebuild its
    control points exactly (a hand-edited or inconsistent result.json).
    """
    spline = curve_spline(result)
    cfg = result.config or {}
    if "template" not in cfg:
        raise ExportError("result.json has no config.template: the modelling history cannot be replayed")
    big = float(np.finfo(float).max)
    lo, hi = cfg.get("bounds") or ((-big, -big), (big, big))
    try:
        template = curve_ops.Polygon(np.asarray(cfg["template"], dtype=float), tuple(lo), tuple(hi))
        states = genome_mod.replay_states(template, result.genome)
    except (OpError, InputError, TypeError, ValueError) as exc:
        raise ExportError(f"the genome does not replay on the stored template: {str(exc).splitlines()[0]}") from None
    final = states[-1].points
    if final.shape != spline.poles.shape or not np.array_equal(final, spline.poles):
        dev = point_deviation(final, spline.poles)
        raise ExportError(f"replaying the genome does not rebuild control_points (deviation {dev:.3g})")
    width = max(2, len(str(len(result.genome))))
    ops: list[dict[str, Any] | None] = [None, *(op.to_json() for op in result.genome)]
    return [HistoryStep(op_label(i, op, width), op, s.points) for i, (op, s) in enumerate(zip(ops, states))]


_PATCH_CACHE: dict[tuple, PatchSet] = {}


def surface_patches(result: Any) -> PatchSet:
    """The limit patches of a surface result (``config``: ``boundary``, ``patch_tolerance`` relative to the
    diagonal, ``patch_max_level``); ExportError when the result has no mesh or the tolerance is not met.
    Cached by geometry and options, so that export and validation share one fit."""
    if result.kind != "surface" or result.control_mesh is None:
        raise ExportError(f"expected a surface result, got a {result.kind} result")
    cfg = result.config or {}
    mesh = result.control_mesh
    tol, boundary, level = cfg.get("patch_tolerance", PATCH_TOLERANCE), cfg.get("boundary", "all"), \
        cfg.get("patch_max_level", 5)
    key = (mesh.topology_key, mesh.vertices.tobytes(), repr(tol), repr(boundary), repr(level))
    if key in _PATCH_CACHE:
        return _PATCH_CACHE[key]
    try:
        patches = limit_patches(mesh, tol, boundary, level)
    except GsrError as exc:
        raise ExportError(f"cannot build the limit-surface patches: {str(exc).splitlines()[0]}") from None
    if not patches.within_tolerance:
        raise ExportError(f"the limit-surface patches deviate by {patches.max_deviation / patches.diagonal:.3g} "
                          f"of the diagonal, above the tolerance {tol:.3g} (raise config patch_tolerance or "
                          f"patch_max_level)")
    if len(_PATCH_CACHE) >= 8:
        _PATCH_CACHE.pop(next(iter(_PATCH_CACHE)))
    _PATCH_CACHE[key] = patches
    return patches


@contextlib.contextmanager
def scratch_dir() -> Iterator[Path]:
    """A temporary directory for host outputs during validation, removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="gsr-validate-") as d:
        yield Path(d)


class Exporter:
    """Base of all exporters; subclasses set the class attributes and write ``export_<kind>``/``validate_<kind>``.

    The protocol the registry relies on: ``name`` (the CLI format name, equal to the entry-point name),
    ``kinds`` (result kinds handled), ``suffixes`` (file-name endings it writes; ``claims`` matches them),
    ``host`` (who judges the files), ``available()``, ``export(result, out_dir, stem) -> list[Path]``,
    ``validate(path, result) -> list[Check]`` and ``failure(path, check, detail) -> Check``.
    """

    name: ClassVar[str] = ""
    kinds: ClassVar[tuple[str, ...]] = ()
    suffixes: ClassVar[tuple[str, ...]] = ()
    host: ClassVar[str] = ""

    def available(self) -> str | None:
        """None when this exporter can write files here, else why not (e.g. "build123d not installed")."""
        return None

    def supports(self, kind: str) -> bool:
        return kind in self.kinds

    def claims(self, path: Path) -> bool:
        """True when ``path`` is a file this exporter writes (by suffix)."""
        return any(path.name.endswith(s) for s in self.suffixes)

    def failure(self, path: Path, check: str, detail: str) -> Check:
        """A failed check of ``path`` under this exporter's host (for validations that crashed)."""
        return failed(path, self.host or self.name, check, detail)

    def filename(self, stem: str, suffix: str | None = None) -> str:
        return stem + (suffix or self.suffixes[0])

    def _method(self, verb: str, kind: str):
        if kind not in self.kinds:
            raise ExportError(f"format {self.name!r} does not handle {kind} results")
        return getattr(self, f"{verb}_{kind}")

    def export(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        """Write this format's files for ``result`` into ``out_dir`` (atomically); returns their paths."""
        reason = self.available()
        if reason:
            raise ExportError(f"format {self.name!r} is unavailable: {reason}")
        return self._method("export", result.kind)(result, Path(out_dir), stem)

    def validate(self, path: Path, result: Any) -> list[Check]:
        """Round-trip ``path`` through the host and compare with ``result``'s geometry."""
        return self._method("validate", result.kind)(Path(path), result)
