"""Reconstruction problems and the public API (re-exported by :mod:`gsr_cad`)."""

from .config import CurveConfig, SurfaceConfig
from .curve import reconstruct_curve
from .inputs import curve_target, load_curve_points, surface_target
from .meshio import load_mesh, save_mesh, save_obj
from .result import Result
from .surface import reconstruct_surface

__all__ = ["CurveConfig", "SurfaceConfig", "reconstruct_curve", "reconstruct_surface", "Result", "curve_target",
           "load_curve_points", "surface_target", "load_mesh", "save_mesh", "save_obj"]
