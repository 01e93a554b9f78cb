"""Reconstruction problems and the public API (re-exported by :mod:`gsr_cad`)."""

from .config import CurveConfig, SurfaceConfig
from .curve import reconstruct_curve
from .export import export, validate
from .inputs import curve_target, load_curve_points, surface_target
from .meshio import load_mesh, save_mesh, save_obj
from .result import CurveResult, Result, SurfaceResult
from .surface import reconstruct_surface

__all__ = ["CurveConfig", "SurfaceConfig", "reconstruct_curve", "reconstruct_surface", "Result", "CurveResult",
           "SurfaceResult", "export", "validate", "curve_target",
           "load_curve_points", "surface_target", "load_mesh", "save_mesh", "save_obj"]
