"""``python -m gsr_cad`` is the ``gsr`` CLI."""

from .cli import main

raise SystemExit(main())
