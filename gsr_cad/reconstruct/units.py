"""Lengths for people: model units or percent of the target's bounding-box diagonal.

Internally every tolerance and distance is a fraction of the target's bounding-box diagonal (the paper's
normalisation, independent of the target's size). At the boundary a length is written either as a plain
number in model units (``0.05``: 0.05 mm when the target is in mm) or with ``%`` of the diagonal (``0.1%``);
:func:`resolve_lengths` turns such settings into fractions once the target (and so its diagonal) is
known, and :func:`model_metrics` / :func:`format_length` turn fractions back into model units.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ..errors import ConfigError
from .config import UNITS

LENGTH_NAMES = ("tolerance", "max_distance")
"""Config fields that are lengths even without ``length`` metadata (and any ``*_tolerance`` field)."""


@dataclasses.dataclass(frozen=True)
class Length:
    """A length as given: ``value`` in model units, or in percent of the diagonal when ``percent``."""

    value: float
    percent: bool = False

    def fraction(self, diagonal: float) -> float:
        """This length as a fraction of ``diagonal`` (the target's bounding-box diagonal, model units)."""
        if not (math.isfinite(diagonal) and diagonal > 0):
            raise ConfigError(f"cannot convert a length without a positive diagonal, got {diagonal!r}")
        return self.value / 100.0 if self.percent else self.value / diagonal

    def __str__(self) -> str:
        return f"{self.value:g}%" if self.percent else f"{self.value:g}"


def parse_length(text: str | float | Length) -> Length:
    """``"0.05"`` (model units) or ``"0.1%"`` (of the diagonal) -> :class:`Length`; ConfigError otherwise."""
    if isinstance(text, Length):
        return text
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return _checked(Length(float(text)), text)
    if not isinstance(text, str):
        raise ConfigError(f"a length must be a number or 'N%', not {text!r}")
    body = text.strip()
    percent = body.endswith("%")
    try:
        value = float(body[:-1] if percent else body)
    except ValueError:
        raise ConfigError(f"not a length: {text!r} (give model units, e.g. 0.05, or percent of the "
                          f"bounding-box diagonal, e.g. 0.1%)") from None
    return _checked(Length(value, percent), text)


def _checked(length: Length, given: Any) -> Length:
    if not (math.isfinite(length.value) and length.value >= 0):
        raise ConfigError(f"a length must be a finite number >= 0, not {given!r}")
    return length


def is_length_field(field: dataclasses.Field) -> bool:
    """Whether a config field holds a length (``length`` metadata, or its name says so)."""
    return bool(field.metadata.get("length")) or field.name in LENGTH_NAMES or field.name.endswith("_tolerance")


def resolve_lengths(overrides: Mapping[str, Any], diagonal: float, config_cls: type) -> dict[str, Any]:
    """``overrides`` with every length field's :class:`Length` (or ``"N%"`` / number string) as a fraction
    of ``diagonal``; other values unchanged."""
    lengths = {f.name for f in dataclasses.fields(config_cls) if is_length_field(f)}
    out = dict(overrides)
    for name in lengths & set(out):
        value = out[name]
        if isinstance(value, (Length, str)):
            out[name] = parse_length(value).fraction(diagonal)
    return out


def unit_label(units: str | None) -> str:
    """How a length in ``units`` is written ("mm", or "model units")."""
    return UNITS.get(units or "model", str(units))


def _g(x: float) -> str:
    return f"{x:.3g}" if x == 0 or 1e-3 <= abs(x) < 1e5 else f"{x:.2e}"


def format_length(fraction: float, diagonal: float, units: str | None = "model") -> str:
    """``fraction`` of the diagonal in both forms: ``"0.052 mm (0.104 % of the diagonal)"``."""
    return f"{_g(fraction * diagonal)} {unit_label(units)} ({_g(100.0 * fraction)} %)"


def is_distance_metric(key: str, value: Any) -> bool:
    """Whether a metrics entry is a distance held as a fraction of the diagonal."""
    numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
    return numeric and not key.endswith("_model") and (
        "distance" in key or key.startswith(("data_to_fit", "fit_to_data")))


def model_metrics(metrics: Mapping[str, Any], diagonal: float, units: str | None = "model") -> dict[str, Any]:
    """The entries to add to a result's metrics: ``units``, ``diagonal`` (model units) and, for each
    distance ``k`` (a fraction of the diagonal), ``k_model`` in model units."""
    out: dict[str, Any] = {"units": units or "model", "diagonal": float(diagonal)}
    for key, value in metrics.items():
        if is_distance_metric(key, value):
            out[f"{key}_model"] = float(value) * float(diagonal)
    return out
