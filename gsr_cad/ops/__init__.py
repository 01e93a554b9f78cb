"""Modelling operations: frozen dataclasses around pure functions, registered by name."""
