"""The ``xtopo`` command line.

Exit codes: 0 success, 1 partial failure (some inputs failed), 2 usage or input error.
"""

from __future__ import annotations

import argparse
import os
import sys

from ._progress import progress_bar
from ._version import __version__
from .cli_commands import (add_commands, add_iso_options, add_preprocess_options, add_probe_options, add_read_options,
                           iso_options, iso_report, preprocess, read_options)
from .errors import XtopoError

__all__ = ["main"]


def _progress(args):
    """Progress bars of a command: off with -q, else on when stderr is a terminal (None: auto)."""
    return False if getattr(args, "quiet", False) else None


def _load_measurements(files, args):
    from .datasets import example_twin  # deferred: xtopo --version/--help load no numpy
    from .io import open_topography

    if not files:
        tree = example_twin()
        return {name: preprocess(node.to_dataset(), args) for name, node in tree.children.items()}, "example twin", []
    from .io.container import is_container

    out, failed = {}, []
    for i, f in progress_bar(list(enumerate(files)), desc="reading files", unit="file", enabled=_progress(args)):
        try:
            if is_container(f):  # a contact.engineering download: its measurements, preprocessed as it says
                for name, ds in _container_measurements(f, getattr(args, "surface", None)).items():
                    out[name if name not in out else f"{os.path.basename(f)}:{name}"] = preprocess(ds, args)
            else:
                out[os.path.basename(f)] = preprocess(open_topography(f, **read_options(args, i)), args)
        except Exception as exc:  # reported per file; the good ones go on
            failed.append((f, exc))
    return out, f"{len(files)} file(s)", failed


def _container_measurements(path, surface) -> dict:
    """The measurements of one surface of a contact.engineering container (``--surface``: name, else index)."""
    from .errors import ValidationError
    from .twins import open_twin

    try:
        try:
            tree = open_twin(path, surface=surface)
        except ValidationError:
            if surface is None or not surface.lstrip("-").isdigit():
                raise
            tree = open_twin(path, surface=int(surface))  # not a surface's name: its index
    except ValidationError as exc:
        raise ValidationError(str(exc).replace("surface=", "--surface").replace(
            " (name or index), or read all with xtopo.io.open_container", " (name or index)")) from None
    return {name: node.to_dataset() for name, node in tree.children.items()}


def _read_inputs(args):
    """The measurements of ``args.files`` (or the example twin); read errors are printed."""
    measurements, what, failed = _load_measurements(args.files, args)
    for f, exc in failed:
        print(f"xtopo: error: {exc}", file=sys.stderr)
    if not measurements:
        print("xtopo: error: no measurement could be read", file=sys.stderr)
    return measurements, what, failed


def _average_line(name: str, r) -> str:
    """One line on a twin average: how many measurements it holds, where, and which added nothing.

    ``count`` is the number of measurements at one collocation point; measurements of different
    scales overlap little, so its maximum says nothing about how many entered the average.
    """
    coord = r.average.dims[0]
    ok = r["count"] > 0
    names = [str(m) for m in r["measurement"].values]
    used = r["curves"].notnull().any(coord).values
    line = f"{name:5s} average of {int(used.sum())} of {len(names)} measurements"
    if ok.any():
        lo, hi = float(r[coord].where(ok).min()), float(r[coord].where(ok).max())
        line += f" at {int(ok.sum())} points, {coord} from {lo:.3g} to {hi:.3g} {r[coord].attrs.get('units', '')}"
    if not used.all():
        left = ", ".join(n for n, u in zip(names, used) if not u)
        line += f"\n      no reliable point from {left} (tip radius/resolution cutoff above the scan's scales)"
    return line


def _cmd_analyze(args) -> int:
    import xarray as xr

    from .io.netcdf import tree_to_netcdf  # deferred: xtopo --version/--help load no numpy
    from .stitching import ANALYSES, analyze_twin
    from .summary import format_table
    from .twins import twin

    measurements, what, failed = _read_inputs(args)
    if not measurements:
        return 2
    results = analyze_twin(twin(measurements), progress=_progress(args))
    print(f"xtopo analyze: {len(measurements)} measurements ({what})\n")
    print(format_table(results.to_dataset()))
    for name in ANALYSES:
        print(_average_line(name, results[name].to_dataset()))
    iso, iso_errors = iso_report(measurements, args)
    if iso is not None:
        results["iso"] = xr.DataTree(iso)
    tree_to_netcdf(results, args.output)
    groups = ", ".join(ANALYSES) + (", iso" if iso is not None else "")
    print(f"\nwrote {args.output} (groups: summary at the root, {groups})")
    if args.report:
        from .report import report  # deferred: xtopo --version/--help load no numpy

        report(measurements, args.report, title=f"xtopo analysis: {what}", iso=iso_options(args),
               progress=_progress(args))
        print(f"wrote {args.report}")
    return 1 if failed or iso_errors else 0


def _cmd_report(args) -> int:
    from .params import preflight  # deferred: xtopo --version/--help load no numpy
    from .report import report

    names = {} if args.analyses is None else {"analyses": [] if args.analyses == "none" else
                                              [a.strip() for a in args.analyses.split(",") if a.strip()]}
    options = preflight(report, names, "--analyses")  # before any file is read
    measurements, what, failed = _read_inputs(args)
    if not measurements:
        return 2
    report(measurements, args.output, title=args.title or f"xtopo report: {what}", iso=iso_options(args),
           progress=_progress(args), **options)
    print(f"wrote {args.output} ({len(measurements)} measurements, {what})")
    return 1 if failed else 0


def _add_inputs(p, func, output: str, what: str) -> None:
    """The options ``analyze`` and ``report`` share: the files (or the example twin), how to read them, -o, -q."""
    p.add_argument("files", nargs="*", help="measurement files (any supported format) or contact.engineering "
                                            "downloads (ZIP)")
    p.add_argument("-o", "--output", default=output, help=f"{what} (default: %(default)s)")
    p.add_argument("--surface", help="surface of a contact.engineering download with several (name or index)")
    add_preprocess_options(p)
    add_read_options(p)
    add_iso_options(p)
    add_probe_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars (shown only on a terminal)")
    p.set_defaults(func=func)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="xtopo", description="Surface topography analysis and contact mechanics.")
    parser.add_argument("--version", action="version", version=f"xtopo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    p = sub.add_parser("analyze", help="analyse measurements (default: the built-in example twin)",
                       description="Read measurement files (or use the built-in example twin when none are "
                                   "given), print a summary table and write the results to NetCDF.")
    _add_inputs(p, _cmd_analyze, "xtopo-analysis.nc", "output NetCDF file")
    p.add_argument("--report", metavar="HTML", help="also write a standalone HTML report (see `xtopo report`)")
    r = sub.add_parser("report", help="write a standalone HTML report (default: the built-in example twin)",
                       description="Read measurement files (or use the built-in example twin), and write one "
                                   "HTML page with the summary table, the stitched averages of every analysis "
                                   "of xtopo.stitching.ANALYSES and a map of every measurement. Opens offline "
                                   "in any browser.")
    _add_inputs(r, _cmd_report, "xtopo-report.html", "output HTML file")
    r.add_argument("--title", help="page title")
    r.add_argument("--analyses", help="stitched averages to show, comma-separated (names of xtopo.stitching."
                                      "ANALYSES, e.g. psd,acf,vbm,sdrp), or 'none' (default: all of them)")

    add_commands(sub)
    return parser


class _Stdout:
    """``sys.stdout`` that goes quiet once its reader has gone (``xtopo analyze | head``).

    The command still finishes its job (the output files): a closed pipe is the reader's
    choice, not an error of the command. The file descriptor is pointed at ``os.devnull``
    so that the interpreter's final flush does not fail either.
    """

    def __init__(self, stream):
        self._stream = stream
        self._gone = False

    def _call(self, method, *args):
        """``self._stream.method(*args)`` until the reader has gone; then nothing (None)."""
        if self._gone:
            return None
        try:
            return getattr(self._stream, method)(*args)
        except BrokenPipeError:
            self._gone = True
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):  # no file descriptor (e.g. a StringIO)
            pass

    def write(self, text):
        written = self._call("write", text)
        return len(text) if written is None else written

    def flush(self):
        self._call("flush")

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning on the command line: its text, not the library line that raised it."""
    print(f"xtopo: warning: {message}", file=sys.stderr if file is None else file)


def main(argv=None) -> int:
    import warnings

    stdout = sys.stdout
    sys.stdout = _Stdout(stdout)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return _main(argv)
    finally:
        sys.stdout.flush()
        sys.stdout = stdout


def _main(argv) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from . import accessors  # noqa: F401  (registers .topo; skipped when the package was imported by the command)

    try:
        return args.func(args)
    except (XtopoError, OSError) as exc:
        print(f"xtopo: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
