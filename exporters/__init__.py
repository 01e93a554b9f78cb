"""Bridges to CAD hosts, installed as gsr_cad.exporters; nothing else in gsr_cad imports them.

The exporters are siblings on one floor, one module per format, each registered under the
``gsr_cad.exporters`` entry-point group (``pyproject.toml``) and found by :mod:`gsr_cad.reconstruct.export`:
``step`` (OCP), ``dxf`` (ezdxf), ``svg``, ``freecad`` (format "fcmacro"), ``openscad`` ("scad"),
``cadquery`` and ``blender``. No exporter imports another; they share the floor below:

- ``base``: the exporter protocol and the validation checks;
- ``model``: what a result becomes (B-spline, labelled history, limit mesh, patches), built once per result
  from its single replay;
- ``encode``: the one literal encoder through which data enters generated host code;
- ``hostside``: the host code itself, as real files;
- ``hosts`` (finding and running the hosts) and ``checks`` (reading files back with OCP and FreeCAD).
"""
