"""Bridges to CAD hosts, installed as gsr_cad.exporters; nothing else in gsr_cad imports them.

One module per format, each with an :class:`~gsr_cad.exporters.base.Exporter` registered under the
``gsr_cad.exporters`` entry-point group (``pyproject.toml``) and found by ``gsr_cad.cli.formats``:
``step`` (OCP), ``dxf`` (ezdxf), ``svg``, ``fcmacro`` (FreeCAD macro), ``scad`` (OpenSCAD) and
``cadquery`` (a CadQuery script) for curves. ``hosts`` finds and runs the CAD programs that judge the
exported files.
"""
