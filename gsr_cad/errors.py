"""The error tree: everything gsr_cad raises on purpose is a GsrError.

The CLI turns any GsrError into one line ``error: ...`` and exit code 2.
"""


class GsrError(Exception):
    """Base of all deliberate gsr_cad errors."""


class InputError(GsrError, ValueError):
    """Bad user input: missing/malformed file, NaN, too few points, wrong dimension."""


class ConfigError(InputError):
    """An absurd parameter (negative population, zero generations, ...)."""


class TopologyError(InputError):
    """A mesh that is degenerate, non-manifold or otherwise unusable."""


class OpError(GsrError):
    """An operation that cannot apply to the geometry it is given (repair drops such ops)."""


class ExportError(GsrError):
    """An export or host round trip that failed (unwritable directory, missing host, bad result file)."""


class GsrWarning(UserWarning):
    """Something repaired or ignored on the user's behalf; the CLI shows it as one ``warning: ...`` line."""
