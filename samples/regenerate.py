"""Rewrite the bundled sample files under samples/ from gsr_cad.reconstruct.samples.

Run after changing a generator: ``python samples/regenerate.py`` (or ``--root DIR`` to write elsewhere).
Each registered kind goes to its own folder (``curves/``, ``surfaces/``) with a README listing its files.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gsr_cad.reconstruct.samples import KIND_DIRS, bundle_all


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent,
                        help="folder to write into (default: this samples/ folder)")
    parser.add_argument("--kind", action="append", choices=sorted(KIND_DIRS),
                        help="only samples of this kind (repeatable; default: every kind)")
    args = parser.parse_args(argv)
    for folder, files in bundle_all(args.root, args.kind).items():
        print(f"{args.root / folder}: {len(files)} files + README.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
