"""contact.engineering surface containers in and out: a ZIP of measurements with their metadata.

The layout (as described by SurfaceTopography's ``Container/IO/CE.py`` and ``Schema.py``, and
written by contact.engineering's "download" of digital surface twins):

* a metadata file: ``index.json`` (the newer layout, JSON) or, in older downloads, ``meta.yml``
  (YAML; contact.engineering wrote sizes as ``!!python/tuple``). When both are present
  ``index.json`` is read. Top level: ``surfaces`` (a list), ``versions``, ``created_at`` /
  ``creation_time``;
* per surface: ``name``, ``description``, ``category``, ``tags``, ``creator`` / ``created_by``
  (``name``, ``orcid``), ``publication`` (``license``, ``url``, ``doi_url``, ...), ``properties``
  and ``topographies``, a list of measurements;
* per measurement: ``name``, ``datafile`` (``original``: the uploaded file, and/or
  ``squeezed-netcdf``: the preprocessed heights in SurfaceTopography's NetCDF layout), ``data_source``
  (channel index), ``size`` (``[Lx]`` or ``[Lx, Ly]``, note the order) and ``unit`` (used only where
  the data file states none), ``is_periodic``, ``height_scale``, ``fill_undefined_data_mode``
  (``do-not-fill`` or ``harmonic``), ``detrend_mode`` (``center``, ``height``: tilt, ``curvature``),
  ``instrument`` (``name``, ``type``, ``parameters`` with ``tip_radius`` / ``resolution`` as
  ``{value, unit}``), ``description``, ``tags``, ``measurement_date``, ``creator`` / ``created_by``.

Reading follows SurfaceTopography: the ``original`` file is preferred; its stored height scale,
filling and detrending are applied in that order, each recorded in ``history``; a ``squeezed``
NetCDF is taken as it is (those steps are in it already). The squeezed file is used instead of the
original when the original is in a format xtopo cannot read or asks for a detrend mode xtopo does
not have (``history`` says so).

**Several surfaces.** A container may hold several surfaces. :func:`open_container` returns
*several twins*, a dict ``{surface name: twin}``; :func:`xtopo.open_twin` returns the twin of a
container with one surface, or of the surface chosen with ``surface=`` (name or index).

The archive is untrusted: the YAML is parsed with a safe loader that maps ``!!python/tuple`` to a
list and refuses every other Python tag; member names that are absolute or leave the archive are
refused; declared sizes are checked before anything is decompressed (:mod:`xtopo.io._zip`);
a named data file that is not in the archive is a :class:`~xtopo.errors.ReaderError` naming it.

Writing (:func:`to_container`) stores each measurement as a squeezed NetCDF
(:func:`xtopo.io.to_surfacetopography_netcdf`) with ``index.json`` and ``meta.yml`` holding the
same metadata, so that SurfaceTopography's ``read_container`` reads it back.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import posixpath
import tempfile
import textwrap
import zipfile
from collections.abc import Mapping
from typing import Annotated

import numpy as np
import xarray as xr

from .._tree import make_twin, measurements, unique_name
from .._version import __version__
from ..conventions import (append_history, height_of, is_nonuniform, is_periodic, lateral_dims, length_factor,
                           normalize_units, physical_size, safe_name)
from ..errors import ReaderError, UnitsError, ValidationError, XtopoError, warn
from ..params import Path, checked
from ..preprocess import detrend, fill_missing
from .formats.st_netcdf import instrument_attrs, instrument_info, to_surfacetopography_netcdf
from .netcdf import atomic_write
from .open import open_topography, sha256
from ._zip import MAX_METADATA, check_declared, copy_member, open_zip, read_member, unsafe_name

__all__ = ["open_container", "container_twin", "to_container", "is_container", "DETREND_MODES"]

INDEX = "index.json"
YAML = "meta.yml"
#: data files of one container together, decompressed
MAX_TOTAL = 1 << 33
MAX_MEMBERS = 100_000
#: values (dict entries, list items, scalars) the metadata may hold: aliases cannot blow it up
MAX_NODES = 1_000_000
_MAX_DEPTH = 64
#: contact.engineering / SurfaceTopography detrend modes -> :func:`xtopo.preprocess.detrend` modes
DETREND_MODES = {"center": "mean", "mean": "mean", "height": "plane", "rms-tilt": "plane",
                 "curvature": "curvature", "rms-curvature": "curvature"}
_KEYS = ("original", "squeezed-netcdf")


def is_container(path) -> bool:
    """True if ``path`` is a ZIP archive with contact.engineering metadata (``index.json``/``meta.yml``)."""
    try:
        with open(path, "rb") as f:
            if f.read(4) != b"PK\x03\x04":
                return False
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
    except (OSError, zipfile.BadZipFile, zipfile.LargeZipFile, ValueError):
        return False
    return INDEX in names or YAML in names


# --- metadata ---------------------------------------------------------------------------------

def _yaml_loader():
    """A safe YAML loader that also reads ``!!python/tuple`` (as a list); other Python tags are refused."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.add_constructor("tag:yaml.org,2002:python/tuple",
                           lambda loader, node: loader.construct_sequence(node, deep=True))
    return Loader


def _plain(value, path, budget: list, depth: int = 0):
    """The metadata as plain JSON values (dates as ISO text), refusing too many values or too deep nesting."""
    budget[0] -= 1
    if budget[0] < 0:
        raise ReaderError(path, f"the container metadata hold more than {MAX_NODES} values (YAML alias bomb?)")
    if depth > _MAX_DEPTH:
        raise ReaderError(path, f"the container metadata are nested more than {_MAX_DEPTH} levels deep")
    if isinstance(value, Mapping):
        return {str(k): _plain(v, path, budget, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v, path, budget, depth + 1) for v in value]
    if isinstance(value, (_dt.date, _dt.datetime)):
        return value.isoformat()
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    return str(value)


def _metadata(path, zf) -> dict:
    names = set(zf.namelist())
    if INDEX not in names and YAML not in names:
        raise ReaderError(path, f"not a contact.engineering container: the ZIP archive holds neither {INDEX} nor "
                                f"{YAML}")
    name = INDEX if INDEX in names else YAML
    raw = read_member(path, zf, zf.getinfo(name), "container", limit=MAX_METADATA)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ReaderError(path, f"the container's {name} is not UTF-8 text: {exc}") from None
    if name == INDEX:
        try:
            meta = json.loads(text)
        except (ValueError, RecursionError) as exc:
            raise ReaderError(path, f"the container's {name} is not valid JSON: {exc}") from None
    else:
        import yaml

        try:
            meta = yaml.load(text, Loader=_yaml_loader())  # noqa: S506 (a SafeLoader subclass)
        except (yaml.YAMLError, RecursionError, ValueError, TypeError) as exc:
            raise ReaderError(path, f"the container's {name} is not valid (safe) YAML: "
                                    f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
    meta = _plain(meta, path, [MAX_NODES])
    if not isinstance(meta, dict) or not isinstance(meta.get("surfaces"), list):
        raise ReaderError(path, f"the container's {name} has no list of 'surfaces'")
    for i, surface in enumerate(meta["surfaces"]):
        if not isinstance(surface, dict) or not isinstance(surface.get("topographies", []), list):
            raise ReaderError(path, f"surface {i} of the container's {name} is not a mapping with a list of "
                                    "'topographies'")
        for j, topo in enumerate(surface.get("topographies", [])):
            if not isinstance(topo, dict) or not isinstance(topo.get("datafile"), dict):
                raise ReaderError(path, f"topography {j} of surface {i} in the container's {name} has no "
                                        "'datafile' mapping")
    meta["_file"] = name
    return meta


def _text(value) -> str | None:
    return value if isinstance(value, str) and value else None


def _described(meta: dict, keys: tuple) -> dict:
    """The non-empty text entries ``keys`` of container metadata, then its ``tags`` (JSON)."""
    out = {key: meta[key] for key in keys if _text(meta.get(key))}
    if meta.get("tags"):
        out["tags"] = json.dumps(meta["tags"])
    return out


def _creator(meta: dict) -> dict:
    who = meta.get("created_by") or meta.get("creator")  # a mapping (name, orcid) or a name
    who = who if isinstance(who, dict) else {"name": who}
    return {f"creator_{key}": who[key] for key in ("name", "orcid") if _text(who.get(key))}


def _surface_attrs(meta: dict, surface: dict, path: str, sha: str) -> dict:
    attrs = {"source_container": os.path.basename(path), "source_container_sha256": sha}
    attrs.update(_described(surface, ("description", "category")), **_creator(surface))
    pub = surface.get("publication")
    if isinstance(pub, dict):
        for key, attr in (("license", "license"), ("url", "publication_url"), ("doi_url", "doi"),
                          ("authors", "publication_authors")):
            if _text(pub.get(key)):
                attrs[attr] = pub[key]
    if surface.get("properties"):
        attrs["properties"] = json.dumps(surface["properties"])
    if isinstance(meta.get("versions"), dict) and meta["versions"]:
        attrs["container_versions"] = json.dumps(meta["versions"])
    return attrs


# --- one measurement --------------------------------------------------------------------------

def _size_and_unit(meta: dict, where: str, path) -> tuple:
    """The measurement's ``size`` (as ``(Ly, Lx)``) and ``unit`` in the metadata, None where absent."""
    size, unit = meta.get("size"), meta.get("unit")
    if size is not None:
        ok = isinstance(size, list) and len(size) in (1, 2) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0 for v in size)
        if not ok:
            raise ReaderError(path, f"{where}: 'size' must be a list of one or two positive lengths, got {size!r}")
        size = tuple(float(v) for v in size[::-1])  # contact.engineering: [Lx, Ly]; xtopo: (Ly, Lx)
    if unit is not None:
        try:
            unit = normalize_units(unit)
        except (UnitsError, TypeError) as exc:
            raise ReaderError(path, f"{where}: 'unit' {unit!r} is not a length unit ({exc})") from None
    return size, unit


def _read_file(file: str, meta: dict, size, unit):
    """open_topography on an extracted data file; the container's unit/size where the file states none."""
    channel = meta.get("data_source")
    channel = channel if isinstance(channel, int) and not isinstance(channel, bool) else None
    periodic = bool(meta.get("is_periodic", False))
    # as SurfaceTopography: what the file states wins; the container's unit and size fill in what it lacks
    attempts = [{}, {"file_units": unit}, {"file_units": unit, "physical_size": size}, {"physical_size": size}]
    tried = []
    for options in attempts:
        options = {k: v for k, v in options.items() if v is not None}
        if options in tried:
            continue
        tried.append(options)
        try:
            ds = open_topography(file, channel=channel, periodic=periodic, **options)
        except ReaderError as exc:
            error = exc
            continue
        return ds, ", ".join(f"{k}={v!r}" for k, v in options.items())
    raise error


def _check_size(ds, size, unit, where: str, path) -> None:
    """Warn (as SurfaceTopography does) when the file's size differs from the container's."""
    if size is None or unit is None or is_nonuniform(ds):
        return
    dims = lateral_dims(ds["height"])
    if len(size) != len(dims):
        raise ReaderError(path, f"{where}: 'size' has {len(size)} lengths for a {len(dims)}D measurement")
    f = length_factor(unit, ds["x"].attrs["units"])
    found = [physical_size(ds, d) for d in dims]
    if not np.allclose(found, np.asarray(size) * f, rtol=1e-4):
        warn(f"{path}: {where}: the data file's size {tuple(found)} {ds['x'].attrs['units']} differs from "
             f"the container's {tuple(v * f for v in size)}; the file's size is used", UserWarning)


def _measurement_attrs(meta: dict, ds) -> dict:
    out = {"title": _text(meta.get("name"))}
    out.update(_described(meta, ("description", "measurement_kind")))
    if _text(meta.get("measurement_date")) and not ds.attrs.get("acquisition_time"):
        out["acquisition_time"] = meta["measurement_date"]
    out.update(_creator(meta))
    out.update(instrument_attrs(meta.get("instrument"), (("instrument", "name"), ("instrument_type", "type")),
                                ds["height"].attrs["units"]))
    return {k: v for k, v in out.items() if v is not None}


def _pipeline(ds, meta: dict, where: str, path):
    """SurfaceTopography's order for an original file: height scale, filling, detrending."""
    scale = meta.get("height_scale")
    if scale is not None:
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not math.isfinite(scale) or scale == 0:
            raise ReaderError(path, f"{where}: 'height_scale' must be a finite nonzero number, got {scale!r}")
        h = ds["height"]
        ds = ds.assign(height=h.copy(data=h.data * float(scale)))
        ds = append_history(ds, f"height_scale={float(scale)!r} (contact.engineering metadata)")
    fill = meta.get("fill_undefined_data_mode") or "do-not-fill"
    if fill == "harmonic":
        if bool(np.any(~np.isfinite(height_of(ds).values))):
            ds = fill_missing(ds)
        else:
            ds = append_history(ds, "fill_undefined_data_mode='harmonic': nothing to fill")
    mode = meta.get("detrend_mode")
    if mode is not None:
        ds = detrend(ds, DETREND_MODES[mode])
        ds = append_history(ds, f"(detrend_mode={mode!r} of the contact.engineering metadata)")
    return ds


def _unsupported(meta: dict) -> str | None:
    """Why xtopo cannot apply the metadata's pipeline (None: it can)."""
    mode = meta.get("detrend_mode")
    if mode is not None and mode not in DETREND_MODES:
        return f"detrend_mode {mode!r} (xtopo has {', '.join(sorted(DETREND_MODES))})"
    fill = meta.get("fill_undefined_data_mode")
    if fill not in (None, "do-not-fill", "harmonic"):
        return f"fill_undefined_data_mode {fill!r} (xtopo has 'do-not-fill', 'harmonic')"
    return None


class _Archive:
    """An open container: its metadata and safe, size-checked extraction of members."""

    def __init__(self, path):
        if not os.path.isfile(path):
            raise ReaderError(path, "no such file")
        self.path, self.sha = path, sha256(path)
        self.zf = open_zip(path, "container")
        try:
            infos = self.zf.infolist()
            if len(infos) > MAX_MEMBERS:
                raise ReaderError(path, f"the archive has {len(infos)} members, more than {MAX_MEMBERS}")
            self.infos = {i.filename: i for i in infos}
            self.meta = _metadata(path, self.zf)
        except BaseException:
            self.zf.close()
            raise
        self.tmp = tempfile.TemporaryDirectory(prefix="xtopo-container-")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.zf.close()
        self.tmp.cleanup()

    def info(self, member: str, where: str):
        if unsafe_name(member):
            raise ReaderError(self.path, f"{where}: data file name {member!r} is absolute or leaves the archive "
                                         "(path traversal); refused")
        try:
            return self.infos[member]
        except KeyError:
            raise ReaderError(self.path, f"{where}: the data file {member!r} named in the container's "
                                         f"{self.meta['_file']} is not in the archive") from None

    def extract(self, info) -> str:
        """The member under its own (sanitised) base name, so its suffix is kept; the caller deletes it."""
        target = os.path.join(self.tmp.name, safe_name(posixpath.basename(info.filename.replace("\\", "/"))))
        copy_member(self.path, self.zf, info, target, "container")
        return target


def _measurement(archive: _Archive, meta: dict, where: str):
    path = archive.path
    datafile = meta["datafile"]
    keys = [k for k in _KEYS if _text(datafile.get(k))]
    if not keys:
        raise ReaderError(path, f"{where}: 'datafile' names neither an original nor a squeezed-netcdf file")
    infos = {k: archive.info(datafile[k], where) for k in keys}
    notes = []
    why = _unsupported(meta)
    if why and "squeezed-netcdf" not in infos:
        raise ReaderError(path, f"{where}: xtopo cannot apply {why} and the container has no squeezed NetCDF")
    if why:
        notes.append(f"the squeezed NetCDF is used: xtopo cannot apply {why}")
        keys = ["squeezed-netcdf"]
    size, unit = _size_and_unit(meta, where, path)
    for n, key in enumerate(keys):
        file = archive.extract(infos[key])
        try:
            ds, given = _read_file(file, meta, size, unit)
            ds = ds.load()  # before its file goes
            break
        except XtopoError as exc:
            reason = exc.reason if isinstance(exc, ReaderError) else str(exc)  # not the temporary file's name
            if n + 1 == len(keys):
                raise ReaderError(path, f"{where}: data file {datafile[key]!r}: {reason}") from exc
            notes.append(f"the squeezed NetCDF is used: the original {datafile[key]!r} cannot be read ({reason})")
        finally:
            os.unlink(file)  # the readers loaded it: keep at most one extracted file on disk
    ds.attrs.update(source_file=posixpath.basename(datafile[key]), source_container=os.path.basename(path),
                    container_datafile=key)
    if given:
        ds = append_history(ds, f"{given} from the contact.engineering metadata (the data file states none)")
    for note in notes:
        ds = append_history(ds, note)
    _check_size(ds, size, unit, where, path)
    if key == "original":
        ds = _pipeline(ds, meta, where, path)
    else:
        ds = append_history(ds, "squeezed NetCDF read as stored (its height scale, filling and detrending were "
                                "applied before it was written)")
    ds.attrs.update(_measurement_attrs(meta, ds))
    return ds


def _surface_name(surface: dict, index: int) -> str:
    return _text(surface.get("name")) or f"surface{index}"


def _twin(archive: _Archive, index: int) -> xr.DataTree:
    surface = archive.meta["surfaces"][index]
    name = _surface_name(surface, index)
    nodes = {}
    topographies = surface.get("topographies", [])
    if not topographies:
        raise ReaderError(archive.path, f"surface {name!r} of the container has no topographies")
    for j, meta in enumerate(topographies):
        label = _text(meta.get("name")) or posixpath.basename(str(next(iter(meta["datafile"].values()), j)))
        where = f"surface {name!r}, topography {j} ({label!r})"
        ds = _measurement(archive, meta, where)
        nodes[unique_name(safe_name(os.path.splitext(label)[0]), nodes)] = ds
    return make_twin(nodes, name=name, **_surface_attrs(archive.meta, surface, archive.path, archive.sha))


def _budget(archive: _Archive, surfaces) -> None:
    """Refuse a container whose data files declare more than :data:`MAX_TOTAL` bytes before extracting any."""
    total = 0
    for i in surfaces:
        for meta in archive.meta["surfaces"][i].get("topographies", []):
            for key in _KEYS:
                member = _text(meta["datafile"].get(key))
                if member and member in archive.infos:
                    total += check_declared(archive.path, archive.infos[member], "container")
    if total > MAX_TOTAL:
        raise ReaderError(archive.path, f"the container's data files declare {total} bytes, more than the {MAX_TOTAL} "
                                        "accepted (zip bomb?)")


_FILE = Path("file path")


@checked
def open_container(path: Annotated[str, _FILE]) -> dict[str, xr.DataTree]:
    """Read every surface of a contact.engineering container (ZIP) as a twin.

    Parameters
    ----------
    path : str or os.PathLike
        The container (e.g. a contact.engineering download).

    Returns
    -------
    dict of str to xarray.DataTree
        One twin per surface, by surface name (made unique), in the container's order.
        See :mod:`xtopo.io.container` for what is read and applied.

    Raises
    ------
    ReaderError
        An unreadable or hostile archive, invalid metadata, or a data file that is missing or unreadable
        (the message names the container, the surface, the topography and the file).
    """
    with _Archive(path) as archive:
        surfaces = range(len(archive.meta["surfaces"]))
        _budget(archive, surfaces)
        out = {}
        for i in surfaces:
            out[unique_name(_surface_name(archive.meta["surfaces"][i], i), out)] = _twin(archive, i)
    return out


@checked
def container_twin(path: Annotated[str, _FILE], surface=None) -> xr.DataTree:
    """The twin of one surface of a contact.engineering container (see :func:`xtopo.open_twin`).

    Parameters
    ----------
    path : str or os.PathLike
        The container.
    surface : str or int, optional
        The surface's name or index; needed when the container holds several.
    """
    with _Archive(path) as archive:
        surfaces = archive.meta["surfaces"]
        names = [_surface_name(s, i) for i, s in enumerate(surfaces)]
        if not surfaces:
            raise ReaderError(archive.path, "the container holds no surfaces")
        if surface is None:
            if len(surfaces) > 1:
                raise ValidationError(f"{archive.path} holds {len(surfaces)} surfaces ({', '.join(map(repr, names))}); "
                                      "choose one with surface= (name or index), or read all with "
                                      "xtopo.io.open_container")
            index = 0
        elif isinstance(surface, int) and not isinstance(surface, bool):
            if not -len(surfaces) <= surface < len(surfaces):
                raise ValidationError(f"surface={surface} is out of range: {archive.path} holds {len(surfaces)} "
                                      "surface(s)")
            index = surface % len(surfaces)
        elif isinstance(surface, str) and surface in names:
            index = names.index(surface)
        else:
            raise ValidationError(f"surface={surface!r} is not in {archive.path}; its surfaces are "
                                  f"{', '.join(map(repr, names))} (or give an index)")
        _budget(archive, [index])
        return _twin(archive, index)


# --- writing ------------------------------------------------------------------------------------

def _date(value) -> str | None:
    """``value`` as an ISO date (YYYY-MM-DD) if it starts with one."""
    try:
        return _dt.date.fromisoformat(str(value)[:10]).isoformat()
    except ValueError:
        return None


def _described_meta(attrs, keys: tuple) -> dict:
    """The text entries ``keys`` of ``attrs``, their ``tags`` and creator (``created_by``) as container metadata."""
    out = {key: attrs[key] for key in keys if isinstance(attrs.get(key), str)}
    if isinstance(attrs.get("tags"), str) and attrs["tags"]:  # read as JSON (_described); a plain text is one tag
        try:
            out["tags"] = json.loads(attrs["tags"])
        except ValueError:
            out["tags"] = [attrs["tags"]]
    if attrs.get("creator_name"):
        out["created_by"] = {key: str(attrs[f"creator_{key}"]) for key in ("name", "orcid")
                             if attrs.get(f"creator_{key}")}
    return out


def _topography_meta(name: str, ds: xr.Dataset, member: str) -> dict:
    h = height_of(ds)
    unit = h.attrs["units"]
    dims = lateral_dims(h)
    meta = {"name": name, "datafile": {"squeezed-netcdf": member}}  # the node name comes back as the node name
    if not is_nonuniform(ds):  # SurfaceTopography refuses a size for a nonuniform scan (its positions say it)
        meta["size"] = [physical_size(ds, d) for d in dims[::-1]]  # contact.engineering: [Lx, Ly]
    meta.update({"unit": unit, "is_periodic": bool(is_periodic(ds)), "data_source": 0,
                 "has_undefined_data": bool(np.any(~np.isfinite(h.values)))})
    # measurement_kind: xtopo's own key (parallel profiles, ...); SurfaceTopography ignores it
    meta.update(_described_meta(ds.attrs, ("description", "measurement_kind")))
    date = _date(ds.attrs.get("acquisition_time", ""))
    if date:
        meta["measurement_date"] = date
    instrument = instrument_info(ds.attrs, (("instrument", "name"), ("instrument_type", "type")), unit)
    if instrument:
        meta["instrument"] = instrument
    return meta


def _surfaces(twins) -> list[tuple[str, xr.DataTree]]:
    if isinstance(twins, xr.DataTree):
        twins = [twins]
    if isinstance(twins, Mapping):
        items = list(twins.items())
    elif isinstance(twins, (list, tuple)):
        items = [(str(t.attrs.get("title") or f"surface{i}") if isinstance(t, xr.DataTree) else str(i), t)
                 for i, t in enumerate(twins)]
    else:
        raise ValidationError(f"to_container expects a twin (xarray.DataTree), or a dict or list of twins, got "
                              f"{type(twins).__name__}")
    for name, t in items:
        if not isinstance(t, xr.DataTree):
            raise ValidationError(f"surface {name!r}: expected a twin (xarray.DataTree), got {type(t).__name__}")
    if not items:
        raise ValidationError("to_container needs at least one twin")
    return [(str(n), t) for n, t in items]


@checked
def to_container(twins, path: Annotated[str, _FILE]) -> str:
    """Write twins as a contact.engineering container (ZIP) that SurfaceTopography and contact.engineering read.

    Each measurement is stored as a squeezed NetCDF in SurfaceTopography's layout (its heights as
    they are in the twin: any preprocessing already applied), described in ``index.json`` and
    ``meta.yml`` (same content): name, size, unit, periodicity, instrument, tip radius and
    resolution, description, creator and date. A nonuniform line scan gets no ``size`` (its
    positions are stored; SurfaceTopography refuses a size for it), and since ``index.json``'s schema
    requires one, a container holding such a scan has ``meta.yml`` only. Written atomically (a
    temporary file, then ``os.replace``).

    Parameters
    ----------
    twins : xarray.DataTree, or dict of str to DataTree, or list of DataTree
        One twin (one surface), or several (one surface each, named by the keys or their ``title``).
    path : str or os.PathLike
        The ZIP file to write.

    Returns
    -------
    str
        The path written.
    """
    items = _surfaces(twins)
    surfaces = []
    with tempfile.TemporaryDirectory(prefix="xtopo-container-") as tmp:
        files = []
        for i, (sname, tree) in enumerate(items):
            prefix = "" if len(items) == 1 else f"{i}-"
            topographies, taken = [], set()
            for name, ds in measurements(tree).items():
                member = unique_name(f"{prefix}{safe_name(name)}-squeezed", taken)
                taken.add(member)
                member += ".nc"
                if ds.attrs.get("grid") == "nonuniform" and ds.attrs.get("periodic"):
                    ds = ds.assign_attrs(periodic=0)
                to_surfacetopography_netcdf(ds.compute(), os.path.join(tmp, member))
                files.append(member)
                topographies.append(_topography_meta(name, ds, member))
            if not topographies:
                raise ValidationError(f"surface {sname!r} has no measurements")
            surfaces.append({"name": sname, "topographies": topographies,
                             **_described_meta(tree.attrs, ("description", "category"))})
        meta = {"versions": {"xtopo": __version__}, "surfaces": surfaces,
                "created_at": _dt.datetime.now(_dt.timezone.utc).isoformat()}

        def write(target):
            import yaml

            with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zf:
                for member in files:
                    zf.write(os.path.join(tmp, member), member)
                if all("size" in t for s in surfaces for t in s["topographies"]):
                    # index.json's schema requires a size, which SurfaceTopography refuses for nonuniform
                    # scans: a container holding one has meta.yml only (which is read without the schema)
                    zf.writestr(INDEX, json.dumps(meta, indent=2))
                zf.writestr(YAML, yaml.safe_dump(meta, allow_unicode=True, sort_keys=False))
                zf.writestr("README.txt", textwrap.dedent(f"""\
                    A contact.engineering surface container written by xtopo {__version__}.
                    {len(surfaces)} surface(s), {len(files)} measurement(s); each measurement is a NetCDF file
                    in SurfaceTopography's layout (heights as analysed: any preprocessing applied).
                    The metadata are in index.json and, with the same content, meta.yml.
                    """))

        return atomic_write(path, write)
