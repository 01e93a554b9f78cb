"""Host-side code: real modules run by Blender, FreeCAD, CadQuery or OpenSCAD, never imported by gsr_cad.

Each Python module here holds one line ``DATA = {}``; the exporters write a copy of the module with that
line replaced by a literal of the result's data (:func:`gsr_cad.exporters.encode.fill_python`) and change
nothing else, so the code that runs in a host is exactly the code in this folder.
"""
