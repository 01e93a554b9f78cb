"""Geometry kernel (numpy/scipy only): curves, polygon meshes, Catmull-Clark subdivision, distances."""
