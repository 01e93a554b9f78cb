"""Bundled sample targets: deterministic generators for the paper's kinds of test data.

Every sample is registered by name in :data:`SAMPLES` together with its kind and a one-line description,
so that listing costs nothing and a sample is only built when asked for. Curve samples live in
:data:`CURVE_SAMPLES` (name -> builder of a :class:`CurveSample`); another kind (surfaces, written as OBJ)
joins by defining a sample class with the :class:`BundledSample` methods and registering its builders with
:func:`register` under its own kind, in a module named in :data:`KIND_MODULES` (imported on first need, so
curve users do not pay for mesh code) where ``gsr sample`` and ``samples/regenerate.py`` find them. The latter
writes every registered sample into ``samples/<kind>s/``
(a test checks that the bundled files still match the generators).

Curves follow the paper: B-spline targets are 200 points at uniform parameters of a clamped uniform cubic
B-spline whose control polygon is the ground truth; other curves are sampled uniformly by arc length.
Every builder is seeded and returns the same arrays on every call.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.special import fresnel

from ..atomic import atomic_path, write_text
from ..errors import InputError
from ..geometry.bspline import evaluate

N_POINTS = 200  # samples per target curve, as in the paper
N_CLEAN = 4000  # points of the dense noise-free reference polyline
KIND_DIRS = {"curve": "curves", "surface": "surfaces"}  # kind -> folder under samples/
KIND_MODULES = {"surface": "gsr_cad.reconstruct.surface_samples"}  # kind -> module that registers its samples


@runtime_checkable
class BundledSample(Protocol):
    """What the CLI and ``samples/regenerate.py`` need from a sample of any kind."""

    name: str
    description: str

    @property
    def kind(self) -> str: ...

    @property
    def has_truth(self) -> bool: ...

    def write(self, path: str | os.PathLike[str]) -> Path:
        """Write the target itself (the input a user reconstructs from)."""

    def write_truth(self, path: str | os.PathLike[str]) -> Path:
        """Write the ground truth; InputError when the sample has none."""

    def bundle(self, directory: str | os.PathLike[str]) -> dict[str, str]:
        """Write all of the sample's files into ``directory``; returns file name -> what it holds."""


@dataclasses.dataclass(frozen=True)
class SampleInfo:
    """A registry entry: enough to list a sample without building it."""

    name: str
    kind: str
    description: str
    build: Callable[[], BundledSample]


SAMPLES: dict[str, SampleInfo] = {}
CURVE_SAMPLES: dict[str, Callable[[], CurveSample]] = {}
_BY_KIND: dict[str, dict[str, Callable[[], BundledSample]]] = {"curve": CURVE_SAMPLES}


def register(kind: str, name: str, description: str):
    """Decorator: register a builder ``(name, description) -> sample`` under ``name`` (built once, cached)."""
    if kind not in KIND_DIRS:
        raise ValueError(f"unknown sample kind {kind!r}")

    def deco(fn: Callable[[str, str], BundledSample]) -> Callable[[], BundledSample]:
        if name in SAMPLES:
            raise ValueError(f"sample name {name!r} is taken")
        build = functools.cache(functools.partial(fn, name, description))
        SAMPLES[name] = SampleInfo(name, kind, description, build)
        _BY_KIND.setdefault(kind, {})[name] = build
        return build

    return deco


def _load_kinds(kind: str | None = None) -> None:
    """Import the modules that register samples of ``kind`` (all kinds when None); absent ones are skipped."""
    for k, module in KIND_MODULES.items():
        if kind is None or k == kind:
            try:
                importlib.import_module(module)
            except ModuleNotFoundError as exc:
                if exc.name != module:
                    raise


def all_samples() -> dict[str, SampleInfo]:
    """Every registered sample of every kind, by name, in registration order."""
    _load_kinds()
    return dict(SAMPLES)


def sample_names(kind: str | None = None) -> list[str]:
    """Registered names (of one kind, or all), in registration order."""
    _load_kinds(kind)
    return [n for n, info in SAMPLES.items() if kind is None or info.kind == kind]


def get_sample(name: str) -> BundledSample:
    """Build the sample called ``name``; an unknown name raises InputError listing the known ones."""
    if name not in SAMPLES:
        _load_kinds()
    info = SAMPLES.get(name)
    if info is None:
        raise InputError(f"unknown sample {name!r}; known samples: {', '.join(SAMPLES)}")
    return info.build()


def write_points_csv(path: str | os.PathLike[str], points: np.ndarray) -> Path:
    """Write ``(n, 2)`` points as CSV with header ``x,y`` (12 significant digits), atomically."""
    pts = np.asarray(points, dtype=float)
    rows = "\n".join(f"{x:.12g},{y:.12g}" for x, y in pts)
    return write_text(path, f"x,y\n{rows}\n")


def write_points(path: str | os.PathLike[str], points: np.ndarray) -> Path:
    """Write points by suffix: ``.npy`` as a NumPy array, anything else as ``x,y`` CSV; atomic."""
    p = Path(path)
    if p.suffix.lower() == ".npy":
        with atomic_path(p) as tmp, open(tmp, "wb") as fh:
            np.save(fh, np.asarray(points, dtype=float))
        return p
    return write_points_csv(p, points)


def _frozen(a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    out = np.array(a, dtype=np.float64)
    out.setflags(write=False)
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class CurveSample:
    """An ordered planar target curve.

    ``points`` (n, 2) is the input to reconstruct from; ``truth_ctrl`` the control polygon of the B-spline
    of ``degree`` it was sampled from (None when it is not a B-spline); ``clean`` a dense (~4000 points)
    polyline of the noise-free curve, the reference for measuring a reconstruction.
    """

    name: str
    points: np.ndarray
    truth_ctrl: np.ndarray | None
    degree: int
    clean: np.ndarray
    description: str

    def __post_init__(self):
        for field in ("points", "truth_ctrl", "clean"):
            object.__setattr__(self, field, _frozen(getattr(self, field)))

    @property
    def kind(self) -> str:
        return "curve"

    @property
    def has_truth(self) -> bool:
        return self.truth_ctrl is not None

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal of the clean curve (the scale distances are normalized by)."""
        return float(np.linalg.norm(np.ptp(self.clean, axis=0)))

    def write(self, path: str | os.PathLike[str]) -> Path:
        return write_points(path, self.points)

    def write_truth(self, path: str | os.PathLike[str]) -> Path:
        if self.truth_ctrl is None:
            raise InputError(f"sample {self.name!r} has no ground-truth control polygon")
        return write_points(path, self.truth_ctrl)

    def write_clean(self, path: str | os.PathLike[str]) -> Path:
        return write_points(path, self.clean)

    def bundle(self, directory: str | os.PathLike[str]) -> dict[str, str]:
        d = Path(directory)
        files = {f"{self.name}.csv": f"{len(self.points)} target points"}
        self.write(d / f"{self.name}.csv")
        if self.truth_ctrl is not None:
            self.write_truth(d / f"{self.name}.truth.csv")
            files[f"{self.name}.truth.csv"] = (f"{len(self.truth_ctrl)} ground-truth control points "
                                               f"(degree {self.degree})")
        self.write_clean(d / f"{self.name}.clean.csv")
        files[f"{self.name}.clean.csv"] = f"{len(self.clean)}-point clean reference polyline"
        return files


# --- helpers ---------------------------------------------------------------------------------------------------

def _bspline_sample(name: str, description: str, ctrl, degree: int = 3) -> CurveSample:
    """Uniform-parameter samples of the clamped uniform B-spline with control polygon ``ctrl``."""
    ctrl = np.asarray(ctrl, dtype=float)
    points = evaluate(ctrl, np.linspace(0.0, 1.0, N_POINTS), degree)
    clean = evaluate(ctrl, np.linspace(0.0, 1.0, N_CLEAN), degree)
    return CurveSample(name, points, ctrl, degree, clean, description)


def _arc_length_resample(dense: np.ndarray, n: int) -> np.ndarray:
    """``n`` points equally spaced by arc length along a dense polyline (ends kept)."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(t, s, dense[:, 0]), np.interp(t, s, dense[:, 1])])


def _analytic_sample(name: str, description: str, dense: np.ndarray) -> CurveSample:
    """A non-B-spline curve given as a very dense polyline: arc-length samples and clean reference."""
    return CurveSample(name, _arc_length_resample(dense, N_POINTS), None, 3,
                       _arc_length_resample(dense, N_CLEAN), description)


_DENSE = 40001  # evaluation density of analytic curves before arc-length resampling


# --- B-spline targets (ground truth known) -------------------------------------------------------------------

_HOOK = [(1, 0), (1, 7), (3, 10), (7, 9.5), (7.5, 5.5)]
_WAVE = [(0, 3), (1.5, 7.5), (3.5, -0.5), (5, 7.5), (6.5, -0.5), (8.5, 7.5), (10, 3)]
_S_CURVE = [(8.5, 9), (4.5, 10.5), (0.5, 8.5), (1.5, 5.5), (5, 5), (8.5, 4.5), (9.5, 1.5), (5.5, -0.5), (1, 1)]
_PIGTAIL = [(0, 0), (1.5, 4), (4.5, 6.5), (8, 5.5), (8, 1.5), (5, 0.5), (4, 3.5), (6.5, 6.5), (9.5, 8),
            (12, 6.5), (12.5, 3), (14, 0.5)]


@register("curve", "bspline_05", "cubic B-spline, 5 control points: a hook")
def _bspline_05(name, description):
    return _bspline_sample(name, description, _HOOK)


@register("curve", "bspline_07", "cubic B-spline, 7 control points: a wave")
def _bspline_07(name, description):
    return _bspline_sample(name, description, _WAVE)


@register("curve", "bspline_09", "cubic B-spline, 9 control points: an S")
def _bspline_09(name, description):
    return _bspline_sample(name, description, _S_CURVE)


@register("curve", "bspline_12", "cubic B-spline, 12 control points: a pigtail with a loop")
def _bspline_12(name, description):
    return _bspline_sample(name, description, _PIGTAIL)


# --- curves that are not B-splines -----------------------------------------------------------------------------

@register("curve", "sine_arc", "one period of a sine wave (amplitude 3 over length 10)")
def _sine_arc(name, description):
    x = np.linspace(0.0, 10.0, _DENSE)
    return _analytic_sample(name, description, np.column_stack([x, 3.0 * np.sin(2.0 * np.pi * x / 10.0)]))


@register("curve", "spiral", "Archimedean spiral r = 0.5 + 1.5 theta / pi over 1.5 turns")
def _spiral(name, description):
    theta = np.linspace(0.0, 3.0 * np.pi, _DENSE)
    r = 0.5 + 1.5 * theta / np.pi
    return _analytic_sample(name, description, np.column_stack([r * np.cos(theta), r * np.sin(theta)]))


@register("curve", "glyph_s", "open stroke of a letter S: two circular bowls joined by a tangent straight spine")
def _glyph_s(name, description):
    # Unit circles centred at (0, +-d); the spine is their common inner tangent through the origin, which
    # touches the upper circle where sin(angle) = -1/d. The lower bowl is the upper one turned by 180 degrees.
    d, start = 1.25, np.radians(25.0)
    leave = np.pi + np.arcsin(1.0 / d)
    upper_t = np.linspace(start, leave, _DENSE // 3)
    upper = np.column_stack([np.cos(upper_t), d + np.sin(upper_t)])
    spine = np.linspace(upper[-1], -upper[-1], _DENSE // 3)[1:-1]
    lower = -upper[::-1]
    stroke = np.vstack([upper, spine, lower])
    return _analytic_sample(name, description, stroke * np.array([2.6, 2.0]))


@register("curve", "clothoid", "clothoid (Euler spiral) from curvature 0 through one full turn")
def _clothoid(name, description):
    t = np.linspace(0.0, 2.0, _DENSE)
    s, c = fresnel(t)
    return _analytic_sample(name, description, 10.0 * np.column_stack([c, s]))


# --- degraded B-spline data (the paper's Figure 4) ---------------------------------------------------------

NOISE_SIGMA = 0.007  # of the bounding-box diagonal, as in the paper
SPARSE_KEEP = 0.25   # fraction of the samples kept (75 % removed), as in the paper


@register("curve", "bspline_07_noisy", "bspline_07 with Gaussian noise, sigma 0.7 % of the bbox diagonal")
def _bspline_07_noisy(name, description):
    base = _bspline_07()
    rng = np.random.default_rng(20070)
    points = base.points + rng.normal(0.0, NOISE_SIGMA * base.diagonal, base.points.shape)
    return CurveSample(name, points, base.truth_ctrl, base.degree, base.clean, description)


@register("curve", "bspline_07_sparse", "bspline_07 with 75 % of the samples removed at random (ends kept)")
def _bspline_07_sparse(name, description):
    base = _bspline_07()
    n = len(base.points)
    rng = np.random.default_rng(20075)
    inner = rng.choice(np.arange(1, n - 1), size=round(SPARSE_KEEP * n) - 2, replace=False)
    keep = np.concatenate([[0], np.sort(inner), [n - 1]])
    return CurveSample(name, base.points[keep], base.truth_ctrl, base.degree, base.clean, description)


def bundle_all(root: str | os.PathLike[str], kinds: Sequence[str] | None = None) -> dict[str, dict[str, str]]:
    """Write every registered sample (of ``kinds``, default all) into ``root/<kind>s/`` plus a README per kind.

    Returns folder name -> {file name: what it holds}.
    """
    _load_kinds()
    out: dict[str, dict[str, str]] = {}
    for kind, builders in _BY_KIND.items():
        if not builders or (kinds is not None and kind not in kinds):
            continue
        folder = Path(root) / KIND_DIRS[kind]
        listing: dict[str, str] = {}
        lines = [f"# Bundled {kind} samples", "",
                 f"Generated by `samples/regenerate.py` from `gsr_cad/reconstruct/samples.py`; do not edit by hand.",
                 f"Write one anywhere with `gsr sample NAME -o FILE`.", ""]
        for name, build in builders.items():
            sample = build()
            files = sample.bundle(folder)
            listing.update(files)
            lines.append(f"## {name}")
            lines.append("")
            lines.append(sample.description[0].upper() + sample.description[1:] + ".")
            lines.append("")
            lines.extend(f"- `{fname}`: {what}" for fname, what in files.items())
            lines.append("")
        write_text(folder / "README.md", "\n".join(lines))
        out[KIND_DIRS[kind]] = listing
    return out
