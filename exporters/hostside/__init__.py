"""Host-side code: real modules run by Blender, FreeCAD, CadQuery or OpenSCAD, never imported by gsr_cad.

Each script module here holds one line ``DATA = {}``; the exporters write a copy of the module with that
line replaced by a literal of the result's data (:func:`gsr_cad.exporters.encode.fill_python`) and each line
``from HELPER import ...  # gsr:inline`` by the code of the pure-Python helper module ``HELPER`` of this
folder (``curve_knots``: the curve forms' knots, shared by the FreeCAD macro and the Blender curve script),
and change nothing else, so the code that runs in a host is exactly the code in this folder.
"""
