"""gsr_cad: measured points -> editable CAD (control polygon / control mesh and its modelling history).

The public API is :func:`reconstruct_curve`, :func:`reconstruct_surface`, :class:`Result` (its typed forms
:class:`CurveResult` and :class:`SurfaceResult`), :func:`export` and :func:`validate` (loaded on first use,
so ``import gsr_cad.errors`` stays light); errors are :class:`gsr_cad.errors.GsrError` subclasses.
"""

from __future__ import annotations

from typing import Any

from .errors import ConfigError, ExportError, GsrError, InputError, OpError, TopologyError

__version__ = "0.1.0"

_API = ("CurveConfig", "SurfaceConfig", "reconstruct_curve", "reconstruct_surface", "Result", "CurveResult",
        "SurfaceResult", "load_mesh", "export", "validate")
__all__ = [*_API, "GsrError", "InputError", "ConfigError", "TopologyError", "OpError", "ExportError"]


def __getattr__(name: str) -> Any:
    if name in _API:
        from . import reconstruct

        return getattr(reconstruct, name)
    raise AttributeError(f"module 'gsr_cad' has no attribute {name!r}")
