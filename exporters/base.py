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

from .model import CurveSpline, xyz

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


def _as_dim(points: Any, dim: int) -> np.ndarray:
    """Our points in the host's dimension: planar rows get z = 0 when the host gives (x, y, z)."""
    return xyz(points) if dim == 3 else np.asarray(points, dtype=float)


def _periodic_checks(path: Path | str, host: str, spline: CurveSpline, poles: np.ndarray,
                     knots: np.ndarray) -> list[Check]:
    """A closed curve the host holds as periodic: its poles and flattened knots must be one of our exact
    periodic forms (:meth:`CurveSpline.periodic_forms`; the one with the host's pole count)."""
    forms = [(_as_dim(p, poles.shape[1] if poles.ndim == 2 else 2), np.repeat(v, m))
             for p, v, m in spline.periodic_forms()]
    fits = [f for f in forms if f[0].shape == poles.shape] or forms[:1]
    if not fits:
        return [failed(path, host, "periodic", "the host holds a periodic curve; ours is open")]
    dev = [(point_deviation(poles, p), point_deviation(knots, t)) for p, t in fits]
    pole_dev, knot_dev = min(dev, key=lambda d: d[0] / spline.scale + d[1])
    return [measured(path, host, "periodic poles", pole_dev, EXACT_TOL * spline.scale),
            measured(path, host, "periodic knots", knot_dev, EXACT_TOL)]


def curve_checks(path: Path | str, host: str, spline: CurveSpline, params: np.ndarray, *, degree: int,
                 rational: bool, poles: Any, knots: Any, samples: Any,
                 param_range: Sequence[float] | None = None, periodic: bool = False,
                 closed: bool | None = None) -> list[Check]:
    """The checks every exact-B-spline format shares: degree, non-rational, poles and flattened knots
    (within :data:`EXACT_TOL`), the parameter range [0, 1], and the host's own evaluation at ``params``
    (within :data:`SAMPLE_TOL`; skipped when ``samples`` is None). ``poles``/``samples`` may be (x, y) or
    (x, y, z) rows (a planar curve's z must then be 0). A host that holds our closed curve as ``periodic`` is
    compared with our periodic forms; ``closed`` (the host's own closed flag, when it has one) must say
    whether our curve is closed."""
    got_poles = np.asarray(poles, dtype=float)
    got_samples = np.asarray(samples if samples is not None else [], dtype=float)
    dim = got_poles.shape[1] if got_poles.ndim == 2 else 2
    checks = [
        expect_equal(path, host, "degree", int(degree), spline.degree),
        expect_equal(path, host, "non-rational", bool(rational), False),
    ]
    if closed is not None:
        checks.append(expect_equal(path, host, "closed", bool(closed), spline.closed))
    if periodic:
        checks += _periodic_checks(path, host, spline, got_poles, np.asarray(knots, dtype=float))
    else:
        checks += [measured(path, host, "poles", point_deviation(got_poles, _as_dim(spline.poles, dim)),
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
                           point_deviation(got_samples, _as_dim(spline.points(params), dim)),
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


def _curve_dim(result: Any) -> int | None:
    pts = getattr(result, "control_points", None)
    a = np.asarray(pts) if result.kind == "curve" and pts is not None else None
    return int(a.shape[1]) if a is not None and a.ndim == 2 else None


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
    curve_dims: ClassVar[tuple[int, ...]] = (2, 3)
    """The curve dimensions carried exactly: (x, y) and (x, y, z), or (2,) for a format planar by nature."""

    def available(self) -> str | None:
        """None when this exporter can write files here, else why not (e.g. "build123d not installed")."""
        return None

    def supports(self, kind: str) -> bool:
        return kind in self.kinds

    def refuses(self, result: Any) -> str | None:
        """None when this exporter carries ``result`` exactly, else why not (a 3D curve for a format that is
        planar by nature, see ``curve_dims``): a default export then skips this format with a warning, an
        explicit one fails."""
        dim = _curve_dim(result)
        if dim is not None and dim not in self.curve_dims:
            return "it is planar by nature: it writes (x, y) curves only, and this curve is 3D"
        return None

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
