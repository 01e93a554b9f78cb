"""``gsr sample NAME -o FILE``: write a bundled sample target (``--list`` shows them all)."""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from ._common import check_output_file


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("sample", help="write a bundled sample target (the paper's examples among them)",
                              description=__doc__.splitlines()[0])
    p.add_argument("name", nargs="?", metavar="NAME", help="sample name (see --list)")
    p.add_argument("-o", "--out", dest="output", metavar="FILE",
                   help="where to write the target (curves: CSV with header x,y, or .npy; surfaces: mesh file)")
    p.add_argument("--output", dest="output", help=argparse.SUPPRESS)  # the old spelling, kept working
    p.add_argument("--truth", metavar="FILE",
                   help="also write the ground truth (control polygon), if the sample has one")
    p.add_argument("--clean", metavar="FILE", help="also write the dense noise-free reference (curves)")
    p.add_argument("--cloud", metavar="FILE", help="also write the target as a point cloud (surfaces)")
    p.add_argument("--list", action="store_true", help="list the sample names with a description and exit")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    from ..reconstruct.samples import all_samples, get_sample

    if args.list:
        samples = all_samples()
        width = max(len(n) for n in samples)
        for info in samples.values():
            print(f"{info.name:<{width}}  {info.kind:<7}  {info.description}")
        return 0
    if not args.name:
        raise InputError("sample needs a NAME (see gsr sample --list)")
    sample = get_sample(args.name)
    if args.output is None:
        raise InputError("sample needs -o FILE (where to write the target)")
    for flag in ("output", "truth", "clean", "cloud"):
        if getattr(args, flag) is not None:
            check_output_file(getattr(args, flag), "-o" if flag == "output" else f"--{flag}")
    for flag, method in (("clean", "write_clean"), ("cloud", "write_cloud")):
        if getattr(args, flag) and not hasattr(sample, method):
            raise InputError(f"--{flag} does not apply to {sample.kind} sample {args.name!r}")
    written = [sample.write(args.output)]
    if args.truth:
        if sample.has_truth:
            written.append(sample.write_truth(args.truth))
        else:
            print(f"note: sample {args.name!r} has no ground truth; {args.truth} not written", file=sys.stderr)
    if args.clean:
        written.append(sample.write_clean(args.clean))
    if args.cloud:
        written.append(sample.write_cloud(args.cloud))
    for path in written:
        print(f"wrote {path}")
    return 0
