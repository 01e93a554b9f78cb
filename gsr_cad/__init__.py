"""gsr_cad: measured points -> editable CAD (control polygon / control mesh and its modelling history)."""

__version__ = "0.1.0"
