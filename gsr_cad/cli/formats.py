"""The export formats, as the CLI uses them: the core API of :mod:`gsr_cad.reconstruct.export`.

``export_all`` and ``validate_all`` are :func:`~gsr_cad.reconstruct.export.export` and
:func:`~gsr_cad.reconstruct.export.validate` under the names the subcommands use.
"""

from __future__ import annotations

from ..reconstruct.export import (GROUP, MANIFEST, Format, check_formats, default_formats, format_names,
                                  read_manifest, registry)
from ..reconstruct.export import export as export_all
from ..reconstruct.export import validate as validate_all

__all__ = ["GROUP", "MANIFEST", "Format", "check_formats", "default_formats", "export_all", "format_names",
           "read_manifest", "registry", "validate_all"]
