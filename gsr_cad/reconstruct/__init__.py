"""Reconstruction problems and the public API (re-exported by :mod:`gsr_cad`). Names load on first use, so that
a command imports only its own problem (``gsr surface`` never imports the curve code, nor ``gsr curve`` the
surface code: each costs a few tenths of a second at every start)."""

from __future__ import annotations

import importlib
from typing import Any

from .export import export, validate  # bound here: a lazy ``export`` would be shadowed by its module's own name

_WHERE = {"CurveConfig": "config", "SurfaceConfig": "config", "reconstruct_curve": "curve",
          "reconstruct_surface": "surface", "curve_target": "inputs",
          "load_curve_points": "inputs", "surface_target": "inputs", "load_mesh": "meshio", "save_mesh": "meshio",
          "save_obj": "meshio", "Result": "result", "CurveResult": "result", "SurfaceResult": "result"}

__all__ = ["CurveConfig", "SurfaceConfig", "reconstruct_curve", "reconstruct_surface", "Result", "CurveResult",
           "SurfaceResult", "export", "validate", "curve_target",
           "load_curve_points", "surface_target", "load_mesh", "save_mesh", "save_obj"]


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
