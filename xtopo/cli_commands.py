"""``xtopo info | contact | batch | convert``: the subcommands beyond ``analyze``.

Exit codes (as in :mod:`xtopo.cli`): 0 success, 1 partial failure (some items failed,
or a contact solve did not converge), 2 usage or input error (nothing useful done).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from ._format import format_columns, format_quantities
from ._kernels import DEGREES
from .errors import UnitsError, XtopoError

__all__ = ["add_commands", "add_preprocess_options", "add_read_options", "parse_channel", "preprocess",
           "preprocess_steps", "read_options"]


def parse_channel(value):
    """``"2"`` → 2; names stay strings."""
    try:
        return int(value)
    except ValueError:
        return value


def add_read_options(p) -> None:
    """``--file-units``, ``--height-units``, ``--physical-size``: what generic files do not store."""
    g = p.add_argument_group("files that store no size or unit (plain text, npy, MATLAB, HDF5)")
    g.add_argument("--file-units", metavar="UNIT", help="length unit of positions and heights (e.g. um)")
    g.add_argument("--height-units", metavar="UNIT",
                   help="unit of the stored height values, when it differs from --file-units")
    g.add_argument("--physical-size", type=float, nargs="+", metavar="L",
                   help="physical size, in --file-units: Lx (line scan) or Ly Lx (area scan)")


def _length(value: str) -> float:
    """A length with its unit (``20nm``, ``0.5 um``; metres without one) → metres (``--tip-radius``)."""
    import re

    from .conventions import length_factor  # deferred: xtopo --help loads no numpy

    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\d\s].*)?", value)
    if not m:
        raise argparse.ArgumentTypeError(f"must be a length such as 20nm or 1.5e-8 (metres), got {value!r}")
    try:
        x = float(m.group(1)) * (length_factor(m.group(2).strip(), "m") if m.group(2) else 1.0)
    except UnitsError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"must be a length above 0, got {value!r}")
    return x


def add_probe_options(p) -> None:
    """``--tip-radius`` and ``--resolution``: the reliability cutoff (paper §4.9) of files that store none."""
    g = p.add_argument_group("reliability (paper §4.9) of files that store no tip radius or resolution")
    g.add_argument("--tip-radius", type=_length, nargs="+", metavar="R",
                   help="probe tip radius with its unit (e.g. 20nm): one for every file, or one per file")
    g.add_argument("--resolution", type=_length, nargs="+", metavar="D",
                   help="lateral resolution with its unit (e.g. 0.5um): one for every file, or one per file")


def read_options(args, index: int | None = None) -> dict:
    """The :func:`xtopo.io.open_topography` options given by :func:`add_read_options` and
    :func:`add_probe_options` (those given only; tip radius and resolution in metres).

    ``--tip-radius``/``--resolution`` with one value per file: ``index`` picks the file's; without it the
    options hold the list (as :mod:`xtopo.batch` takes it) or the one value.
    """
    size = getattr(args, "physical_size", None)
    options = {"file_units": getattr(args, "file_units", None), "height_units": getattr(args, "height_units", None),
               "physical_size": None if not size else size[0] if len(size) == 1 else tuple(size)}
    n = len(getattr(args, "files", None) or [])
    for key in ("tip_radius", "resolution"):
        values = getattr(args, key, None)
        if not values:
            continue
        if len(values) not in (1, n):
            raise XtopoError(f"--{key.replace('_', '-')} takes one value for every file or one per file; got "
                             f"{len(values)} for {n} files")
        options[key] = values[0] if len(values) == 1 else values[index] if index is not None else list(values)
    return {k: v for k, v in options.items() if v is not None}


def add_preprocess_options(p) -> None:
    """``--detrend MODE`` and ``--fill-missing``: the preprocessing of paper §3.2 for commands that analyse."""
    g = p.add_argument_group("preprocessing (paper §3.2; each step is recorded in the history attribute)")
    g.add_argument("--detrend", choices=tuple(DEGREES), default=None,
                   help="subtract the least-squares mean, plane (tilt) or quadratic (curvature) from the heights "
                        "(default: none; instrument data are usually tilted)")
    g.add_argument("--fill-missing", action="store_true",
                   help="fill missing data (after --detrend): harmonic interpolation for maps, linear for line "
                        "scans")


def preprocess_steps(args) -> tuple:
    """The steps :func:`add_preprocess_options` asked for, in the form :mod:`xtopo.batch` takes them
    (:func:`xtopo.preprocess.checked_steps`): detrend, then fill missing data.

    Detrending first fits the background to the measured heights only (the fill would otherwise enter it).
    """
    from .preprocess import checked_steps  # deferred: xtopo --help loads no numpy

    return checked_steps([("detrend", getattr(args, "detrend", None)),
                          ("fill_missing", getattr(args, "fill_missing", False))], "--detrend/--fill-missing")


def preprocess(ds, args):
    """``ds`` after the steps :func:`add_preprocess_options` asked for (:func:`preprocess_steps`)."""
    from .preprocess import apply_steps  # deferred: xtopo --help loads no numpy

    return apply_steps(ds, preprocess_steps(args))


def add_iso_options(p) -> None:
    """``--iso``, ``--lambda-s``, ``--lambda-c``: the ISO parameter sets (issue 22) for commands that show them."""
    g = p.add_argument_group("ISO parameters (ISO 21920-2 profiles along x; ISO 16610 Gaussian filters)")
    g.add_argument("--iso", action="store_true", help="also compute and show the ISO parameters")
    g.add_argument("--lambda-c", metavar="LENGTH", default=None,
                   help="L-filter cut-off λc, with its unit ('0.8 mm'; a bare number is in metres) or 'auto' "
                        "(ISO 4288 class by Ra); the sampling length. Default: no L-filter (form-removed profile, "
                        "5 sections of the whole length)")
    g.add_argument("--lambda-s", metavar="LENGTH", default=None,
                   help="S-filter nesting index λs ('2.5 um', or 'auto' for the ISO 3274 value); default: none")


def _length_option(value):
    """A ``--lambda-*`` value: a bare number is a float (metres), anything else goes to the filter as given."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return value


def iso_options(args) -> dict | None:
    """The report's ``iso`` argument from ``--iso``/``--lambda-s``/``--lambda-c`` (None without ``--iso``)."""
    if not getattr(args, "iso", False):
        return None
    return {"lambda_s": _length_option(args.lambda_s), "lambda_c": _length_option(args.lambda_c)}


def iso_report(measurements: dict, args):
    """The ISO table of ``measurements`` (:func:`xtopo.analysis._iso_sets.iso_table`), printed.

    Returns ``(table, errors)``: ``(None, {})`` without ``--iso``; ``errors`` names the
    measurements whose ISO parameters failed (printed to stderr).
    """
    from .analysis._iso_sets import format_iso_table, iso_table  # deferred: xtopo --help loads no numpy
    from .summary import text_table

    options = iso_options(args)
    if options is None:
        return None, {}
    table, errors = iso_table(measurements, **options)
    print(f"\nISO parameters (lambda_s={args.lambda_s or 'none'}, lambda_c={args.lambda_c or 'none'}):")
    if table.data_vars:
        print(text_table(*format_iso_table(table)))
    for name, msg in errors.items():
        print(f"xtopo: error: ISO parameters of {name}: {msg}", file=sys.stderr)
    return table, errors


def _err(msg: str) -> None:
    print(f"xtopo: error: {msg}", file=sys.stderr)


def _fmt_size(size, units) -> str:
    if not size:
        return "?"
    if any(s is None for s in size):
        return " × ".join("?" if s is None else f"{s:.4g}" for s in size) + (f" {units}" if units else "")
    return format_quantities(size, units or "", sep=" × ")


# --------------------------------------------------------------------------- info


def _cmd_info(args) -> int:
    import xtopo.io as xio  # deferred: xtopo --help loads no numpy
    from .conventions import height_of, lateral_dims, physical_size
    from .summary import format_percent

    path = args.file
    if not os.path.isfile(path):
        _err(f"{path}: {'is a directory, not a file' if os.path.isdir(path) else 'no such file'}")
        return 2
    print(f"file: {path} ({os.path.getsize(path)} bytes)")
    infos = xio.channels(path, **read_options(args))
    print(f"channels: {len(infos)}")
    for c in infos:
        print(f"  [{c.index}] {c.name}: {' × '.join(str(n) for n in c.shape)} points, "
              f"size {_fmt_size(c.size, c.units)}, data in {c.height_units or '?'} "
              f"({'height' if c.is_height else 'other'})")
    ds = xio.open_topography(path, channel=args.channel, units=None, **read_options(args))
    h = height_of(ds)  # NaN where the mask says a point is missing
    dims = lateral_dims(h)
    u = h.attrs.get("units", "?")
    print(f"measurement: {'area' if len(dims) == 2 else 'line'} scan, "
          + " × ".join(f"{d}={ds.sizes[d]}" for d in dims) + " points, "
          + "size " + _fmt_size([physical_size(ds, d) for d in dims], u))
    hv = h.values
    finite = hv[~(hv != hv)]
    if finite.size:
        print(f"heights: {format_quantities([finite.min(), finite.max()], u)}, missing "
              f"{hv.size - finite.size} points ({format_percent(100 * (1 - finite.size / hv.size))})")
    print("metadata:")
    for key in sorted(set(ds.attrs) - {"history"}):
        val = str(ds.attrs[key])
        print(f"  {key}: {val if len(val) <= 100 else val[:97] + '...'}")
    _, iso_errors = iso_report({os.path.basename(path): ds}, args)
    return 1 if iso_errors else 0


# --------------------------------------------------------------------------- contact


def _scene_kwargs(args) -> dict:
    periodic = None if args.periodic is None else args.periodic == "yes"
    return {k: v for k, v in (("modulus", args.modulus), ("hardness", args.hardness), ("periodic", periodic))
            if v is not None}


def _solve_kwargs(args) -> dict:
    return {k: v for k, v in (("tol", args.tol), ("maxiter", args.maxiter)) if v is not None}


_OPTIONS = {"load": "--loads", "mean_pressure": "--mean-pressures"}


def _control(args) -> tuple[str, list]:
    """``("load", --loads)`` or ``("mean_pressure", --mean-pressures)``, the values checked before any file is
    read, as the library checks them (:func:`xtopo.contact.solve.control_value`) but with messages that name
    the option given."""
    from .contact.models import scene_models  # deferred: xtopo --help loads no numpy
    from .contact.solve import control_value

    control, values = ("load", args.loads) if args.loads is not None else ("mean_pressure", args.mean_pressures)
    models = scene_models(args.modulus, args.hardness)  # checked by the parser (_positive_float)
    return control, [control_value(control, v, models, label=f"{_OPTIONS[control]} value") for v in values]


def _cmd_contact(args) -> int:
    from .batch import _contact_item  # deferred: xtopo --help loads no numpy
    from .io import open_topography
    from .io.netcdf import to_netcdf

    control, values = _control(args)
    ds = preprocess(open_topography(args.file, channel=args.channel, **read_options(args)), args)
    res = _contact_item(ds, values, control=control, scene=_scene_kwargs(args), solve=_solve_kwargs(args),
                        maps=args.maps)
    print(f"xtopo contact: {args.file}, {len(values)} {control.replace('_', ' ')}(s)\n")
    cols = [control] + [c for c in ("load", "mean_pressure", "area_fraction", "penetration", "iterations",
                                    "converged") if c in res and c != control]
    print(format_columns([(c, res[c].values.tolist(), None if c == "converged" else res[c].attrs.get("units"))
                          for c in cols]))
    to_netcdf(res, args.output, compress=True)
    maps = "with the" if args.maps else "scalars only; --maps keeps the"
    print(f"\nwrote {args.output} ({maps} pressure/gap/displacement/contact maps)")
    if "converged" in res and not bool(res["converged"].all()):
        failed = [f"{v:g}" for v, ok in zip(res[control].values, res["converged"].values) if not ok]
        _err(f"the solves at {_OPTIONS[control]} {' '.join(failed)} did not converge (see 'converged'); raise "
             "--maxiter or loosen --tol")
        return 1
    return 0


# --------------------------------------------------------------------------- batch


def _report_batch(result, store_dir) -> int:
    from .io.netcdf import to_netcdf  # deferred: xtopo --help loads no numpy

    failed = json.loads(result.attrs.get("failed_items", "[]"))
    n_items = int(result["error"].size)
    out = os.path.join(store_dir, "result.nc")
    to_netcdf(result, out)
    print(f"xtopo batch: {n_items - len(failed)}/{n_items} items done "
          f"({result.attrs['chunks_computed']} chunks computed, {result.attrs['chunks_reused']} reused)")
    print(f"wrote {out}")
    for line in failed:
        _err(line)
    if failed and len(failed) == n_items:
        return 2
    return 1 if failed else 0


def _batch_common(args) -> dict:
    # the bar only on a terminal: not in pipes, logs and CI (issue 26)
    progress = not args.quiet and sys.stdout.isatty()
    return dict(scheduler=args.scheduler, workers=args.workers, store=args.output, progress=progress,
                chunks=args.chunk_size, read_options=read_options(args), preprocess=preprocess_steps(args))


def _positive_int(value: str) -> int:
    n = int(value)
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {n}")
    return n


def _positive_float(value: str) -> float:
    """A finite number above 0 (``--modulus``, ``--hardness``, ``--tol``)."""
    try:
        x = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {value!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number above 0, got {value}")
    return x


def _cmd_batch_contact(args) -> int:
    from .batch import contact  # deferred: xtopo --help loads no numpy

    common = _batch_common(args)
    control, values = _control(args)
    result = contact(args.files, **{f"{control}s": values}, **_scene_kwargs(args), **_solve_kwargs(args),
                     maps=args.maps, **common)
    return _report_batch(result, args.output)


def _cmd_batch_analyze(args) -> int:
    from .batch import analyze  # deferred: xtopo --help loads no numpy

    result = analyze(args.files, analyses=args.analyses, **_batch_common(args))
    return _report_batch(result, args.output)


# --------------------------------------------------------------------------- convert


def _cmd_convert(args) -> int:
    import xtopo.io as xio  # deferred: xtopo --help loads no numpy

    ds = preprocess(xio.open_topography(args.file, channel=args.channel, units=args.units, **read_options(args)),
                    args)
    writer = xio.to_surfacetopography_netcdf if args.layout == "surfacetopography" else xio.to_netcdf
    writer(ds, args.output)
    print(f"wrote {args.output} ({args.layout} layout)")
    return 0


# --------------------------------------------------------------------------- parsers


def _add_control_options(p) -> None:
    """``--loads`` or ``--mean-pressures`` (exactly one)."""
    g = p.add_argument_group("what is imposed (exactly one)").add_mutually_exclusive_group(required=True)
    g.add_argument("--loads", type=float, nargs="+", metavar="LOAD",
                   help="normal loads in units of E* × m² (files are read in metres): 1e-14 on a 1 µm × 1 µm "
                        "scan is a mean pressure of 0.01 E*; line scans: force per unit length, in E* × m")
    g.add_argument("--mean-pressures", type=float, nargs="+", metavar="P",
                   help="mean pressures (load / nominal area) in units of E* (of --modulus), whatever the size "
                        "and length unit of the scan; e.g. 0.01")


def _add_scene_options(p) -> None:
    g = p.add_argument_group("contact scene")
    g.add_argument("--modulus", type=_positive_float, default=1.0,
                   help="effective contact modulus E* in Pa (default %(default)s: pressures in units of E*)")
    g.add_argument("--hardness", type=_positive_float, default=None,
                   help="hardness (pressure cap), same units as --modulus")
    g.add_argument("--periodic", choices=("yes", "no"), default=None,
                   help="override the periodicity stored with the measurement")
    g.add_argument("--tol", type=_positive_float, default=None, help="solver tolerance (default: the solver's)")
    g.add_argument("--maxiter", type=_positive_int, default=None,
                   help="maximum solver iterations (default: the solver's)")


def _add_batch_options(p) -> None:
    p.add_argument("files", nargs="+", help="measurement files")
    g = p.add_argument_group("execution")
    g.add_argument("--scheduler", default="local",
                   help="'local' (a local cluster of --workers processes; default), 'threads', 'processes', "
                        "'sync', or a Dask scheduler address such as tcp://host:8786")
    g.add_argument("--workers", type=_positive_int, default=None, help="local workers (default: one per CPU)")
    g.add_argument("--chunk-size", type=_positive_int, default=None, metavar="N",
                   help="measurements per task (default 1)")
    g.add_argument("-o", "--output", required=True, metavar="STORE",
                   help="store directory: one NetCDF file per finished chunk plus result.nc; rerunning with "
                        "the same store resumes (only missing chunks are computed)")
    g.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_preprocess_options(p)
    add_read_options(p)


def add_commands(sub) -> None:
    """Register ``info``, ``contact``, ``batch contact|analyze`` and ``convert`` on ``sub``."""
    one = argparse.ArgumentParser(add_help=False)  # what info, contact and convert share: one file, how to read it
    one.add_argument("file", help="measurement file (any supported format)")
    one.add_argument("--channel", type=parse_channel, help="channel index or name (default: the first height channel)")
    add_read_options(one)
    p = sub.add_parser("info", parents=[one], help="channels, sizes and metadata of a measurement file",
                       description="Print the channels, grid, physical size and metadata of a measurement file.")
    add_iso_options(p)
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("contact", parents=[one], help="contact mechanics of one measurement at several loads",
                       description="Solve the contact of a rigid flat with the measured topography at each "
                                   "load (or mean pressure); print the scalars and write the results (maps included) to NetCDF.")
    _add_control_options(p)
    p.add_argument("--maps", action="store_true",
                   help="keep the pressure/gap/displacement/contact maps of every step (large; compressed)")
    p.add_argument("-o", "--output", default="xtopo-contact.nc", help="output NetCDF file (default: %(default)s)")
    _add_scene_options(p)
    add_preprocess_options(p)
    p.set_defaults(func=_cmd_contact)

    pb = sub.add_parser("batch", help="many measurements on a Dask cluster (resumable)",
                        description="Run contact or analyses for many files as chunked Dask tasks, locally or "
                                    "on a cluster. Results stream into a store directory; an interrupted run "
                                    "resumes. Exit code 1 when some items failed (they are listed).")
    bsub = pb.add_subparsers(dest="batch_command", metavar="WHAT")
    pb.set_defaults(func=lambda args: (pb.print_help(), 2)[1])
    p = bsub.add_parser("contact", help="contact at several loads for each file",
                        description="Contact of every file at every load (dims measurement × load).")
    _add_control_options(p)
    p.add_argument("--maps", action="store_true", help="keep pressure/gap maps (large); default scalars only")
    _add_scene_options(p)
    _add_batch_options(p)
    p.set_defaults(func=_cmd_batch_contact)
    p = bsub.add_parser("analyze", help="analyses of each file",
                        description="Run analyses (default: scalars) on every file (dim measurement).")
    p.add_argument("--analyses", nargs="+", default=["scalars"], metavar="NAME",
                   help="xtopo.analysis modules to run (default: scalars)")
    add_probe_options(p)
    _add_batch_options(p)
    p.set_defaults(func=_cmd_batch_analyze)

    p = sub.add_parser("convert", parents=[one], help="convert a measurement file to NetCDF",
                       description="Read any supported file and write it as xtopo NetCDF (CF/ACDD) or in the "
                                   "SurfaceTopography/contact.engineering NetCDF layout.")
    p.add_argument("-o", "--output", required=True, help="output NetCDF file")
    p.add_argument("--layout", choices=("xtopo", "surfacetopography"), default="xtopo",
                   help="file layout (default: %(default)s)")
    p.add_argument("--units", default="m", help="length unit of the output (default: %(default)s)")
    add_preprocess_options(p)
    add_probe_options(p)
    p.set_defaults(func=_cmd_convert)
