"""The exporter protocol and what every exporter shares.

An exporter turns a :class:`~gsr_cad.reconstruct.result.Result` into files one CAD host reads, and
validates such a file by running the real host (or an independent reader) on it and comparing what comes
back with *our* geometry. Exporters declare the result kinds they support; ``export``/``validate`` dispatch
to ``export_<kind>``/``validate_<kind>``, so a surface branch is added by writing two methods and adding
``"surface"`` to ``kinds``; the registry (``gsr_cad.cli.formats``) never offers an exporter for a kind it
does not declare.

What results become lives in :mod:`~gsr_cad.exporters.model` (one model per result, from its single
replay); the text of every generated script comes from :mod:`~gsr_cad.exporters.hostside` through the
literal encoder :mod:`~gsr_cad.exporters.encode`. A script format implements ``render_<kind>(result, stem)``
returning ``{file name: text}``: ``export`` writes those files, and ``gsr validate`` regenerates them to
refuse a file that differs before running it.

Tolerances are relative to the geometry's scale, ``max(1, largest absolute coordinate)``: data stored as
numbers (poles, knots, nodes) must come back within :data:`EXACT_TOL` of it, points a host evaluates
within :data:`SAMPLE_TOL`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from gsr_cad.atomic import atomic_path, write_text
from gsr_cad.errors import ExportError

from .model import CurveSpline

EXACT_TOL = 1e-9
SAMPLE_TOL = 1e-6


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
                 param_range: Sequence[float] | None = None, periodic: bool = False) -> list[Check]:
    """The checks every exact-B-spline format shares: degree, non-rational, poles and flattened knots
    (within :data:`EXACT_TOL`), the parameter range [0, 1], and the host's own evaluation at ``params``
    (within :data:`SAMPLE_TOL`; skipped when ``samples`` is None). ``poles``/``samples`` may be 2-D or 3-D
    (then z must be 0). A host that re-reads our closed curve as ``periodic`` is checked by its evaluation only."""
    got_poles = np.asarray(poles, dtype=float)
    got_samples = np.asarray(samples if samples is not None else [], dtype=float)
    dim = got_poles.shape[1] if got_poles.ndim == 2 else 2
    checks = [
        expect_equal(path, host, "degree", int(degree), spline.degree),
        expect_equal(path, host, "non-rational", bool(rational), False),
    ]
    closed = bool(np.allclose(spline.poles[0], spline.poles[-1], rtol=0.0, atol=EXACT_TOL * spline.scale))
    if periodic and closed and samples is not None:
        # the host turned our closed (end-clamped) curve into its periodic form: other poles and knots, the
        # same curve, so its own evaluation at our parameters is the check
        checks.append(skipped(path, host, "poles and knots", "the host re-reads the closed curve as periodic; "
                                                             "compared by its evaluated points"))
    else:
        checks += [measured(path, host, "poles", point_deviation(got_poles, _planar(spline.poles, dim)),
                            EXACT_TOL * spline.scale),
                   measured(path, host, "knots", point_deviation(np.asarray(knots, dtype=float), spline.knots),
                            EXACT_TOL)]
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
    """Shortest text that reads back as exactly the same double (for details and messages)."""
    return repr(float(x))


@contextlib.contextmanager
def scratch_dir() -> Iterator[Path]:
    """A temporary directory for host outputs during validation, removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="gsr-validate-") as d:
        yield Path(d)


def save_host_document(script_name: str, text: str, path: Path, run: Callable[[Path, Path], Any]) -> Path:
    """Write ``text`` as ``script_name`` in a scratch directory, let ``run(script, document)`` make the host
    save its document there, and copy that onto ``path`` atomically; ExportError when no document came."""
    with scratch_dir() as tmp:
        script, document = tmp / script_name, tmp / ("document" + Path(path).suffix)
        write_text(script, text)
        run(script, document)
        if not document.is_file():
            raise ExportError(f"the host saved no document for {Path(path).name}")
        with atomic_path(path) as target:
            shutil.copyfile(document, target)
    return Path(path)


def _planar_only(result: Any) -> str | None:
    """Why a curve exporter cannot write ``result``: every curve format here is planar for now."""
    pts = getattr(result, "control_points", None)
    if result.kind == "curve" and pts is not None and np.asarray(pts).ndim == 2 and np.asarray(pts).shape[1] != 2:
        return "it writes planar (x, y) curves only; this curve is 3D"
    return None


class Exporter:
    """Base of all exporters; subclasses set the class attributes and write ``export_<kind>``/``validate_<kind>``.

    The protocol the registry relies on: ``name`` (the CLI format name, equal to the entry-point name),
    ``kinds`` (result kinds handled), ``suffixes`` (file-name endings it writes; ``claims`` matches them),
    ``host`` (who judges the files), ``available()``, ``render(result, stem) -> dict | None``,
    ``export(result, out_dir, stem) -> list[Path]``, ``validate(path, result) -> list[Check]`` and
    ``failure(path, check, detail) -> Check``.
    """

    name: ClassVar[str] = ""
    kinds: ClassVar[tuple[str, ...]] = ()
    suffixes: ClassVar[tuple[str, ...]] = ()
    host: ClassVar[str] = ""
    curve_forms: ClassVar[bool] = True
    """Whether closed and cornered curves are carried exactly (False: a history script replaying open curves)."""

    def available(self) -> str | None:
        """None when this exporter can write files here, else why not (e.g. "build123d not installed")."""
        return None

    def supports(self, kind: str) -> bool:
        return kind in self.kinds

    def refuses(self, result: Any) -> str | None:
        """None when this exporter carries ``result`` exactly, else why not (a form its host script cannot
        replay yet): a default export then skips this format with a warning, an explicit one fails."""
        cfg = (result.config or {}) if result.kind == "curve" else {}
        if not self.curve_forms and (cfg.get("closed") or cfg.get("corners")):
            return ("its host script replays open curves without corners only (closed and cornered curves: "
                    "step, dxf, svg, scad, cadquery)")
        return _planar_only(result)

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

    def render(self, result: Any, stem: str) -> dict[str, str] | None:
        """``{file name: text}`` of a script format (regenerated by validation), None for other formats."""
        if result.kind not in self.kinds:
            raise ExportError(f"format {self.name!r} does not handle {result.kind} results")
        method = getattr(self, f"render_{result.kind}", None)
        return None if method is None else method(result, stem)

    def export(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        """Write this format's files for ``result`` into ``out_dir`` (atomically); returns their paths."""
        reason = self.available()
        if reason:
            raise ExportError(f"format {self.name!r} is unavailable: {reason}")
        texts = self.render(result, stem)
        if texts is not None:
            return [write_text(Path(out_dir) / name, text) for name, text in texts.items()]
        return self._method("export", result.kind)(result, Path(out_dir), stem)

    def validate(self, path: Path, result: Any) -> list[Check]:
        """Round-trip ``path`` through the host and compare with ``result``'s geometry."""
        return self._method("validate", result.kind)(Path(path), result)
