"""Reconstruction problems and the public API."""
