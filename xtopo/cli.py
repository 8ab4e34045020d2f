"""The ``xtopo`` command line.

Exit codes: 0 success, 1 partial failure (some inputs failed), 2 usage or input error.
"""

from __future__ import annotations

import argparse
import os
import sys

__all__ = ["main"]


def _load_measurements(files, args):
    from .datasets import example_twin
    from .io import open_topography

    if not files:
        tree = example_twin()
        return {name: node.to_dataset() for name, node in tree.children.items()}, "example twin", []
    out, failed = {}, []
    for f in files:
        try:
            out[os.path.basename(f)] = open_topography(f)
        except Exception as exc:  # reported per file; the good ones go on
            failed.append((f, exc))
    return out, f"{len(files)} file(s)", failed


def _cmd_analyze(args) -> int:
    from .io.netcdf import to_netcdf
    from .summary import format_table, summary_table

    measurements, what, failed = _load_measurements(args.files, args)
    for f, exc in failed:
        print(f"xtopo: error: {exc}", file=sys.stderr)
    if not measurements:
        print("xtopo: error: no measurement could be read", file=sys.stderr)
        return 2
    table = summary_table(measurements)
    print(f"xtopo analyze: {len(measurements)} measurements ({what})\n")
    print(format_table(table))
    to_netcdf(table, args.output)
    print(f"\nwrote {args.output}")
    return 1 if failed else 0


def build_parser() -> argparse.ArgumentParser:
    from ._version import __version__

    parser = argparse.ArgumentParser(prog="xtopo", description="Surface topography analysis and contact mechanics.")
    parser.add_argument("--version", action="version", version=f"xtopo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    p = sub.add_parser("analyze", help="analyse measurements (default: the built-in example twin)",
                       description="Read measurement files (or use the built-in example twin when none are "
                                   "given), print a summary table and write the results to NetCDF.")
    p.add_argument("files", nargs="*", help="measurement files (any supported format)")
    p.add_argument("-o", "--output", default="xtopo-analysis.nc", help="output NetCDF file (default: %(default)s)")
    p.set_defaults(func=_cmd_analyze)
    from .cli_commands import add_commands  # issue 7: info, contact, batch, convert

    add_commands(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from .errors import XtopoError

    try:
        return args.func(args)
    except (XtopoError, OSError) as exc:
        print(f"xtopo: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
