"""Zygo DATX files (Mx software of Zygo optical interferometers; HDF5, read with h5py).

Layout (facts from SurfaceTopography's ``DATX.py`` and Gwyddion's ``datxfile.c``): the top-level
dataset ``/MetaData`` is a table of ``(source, link, destination)`` byte strings; following the
links from ``Root`` through ``Measurement`` and ``Surface`` gives ``Path``, the HDF5 path of the
height map, a 2D dataset of rows along ``y``. Its attributes: ``Unit`` (the height unit),
``No Data`` (the value of undefined points), and the converters ``X Converter`` / ``Y Converter``
(category ``LateralCat``, base unit ``Pixels``, parameters whose second entry is the pixel size in
metres) and ``Z Converter`` (category ``HeightCat``, the height unit). The size is
``N × pixel size``. ``System Type`` and ``System Serial Number`` attributes (on the surface's
groups or under ``/Attributes``) name the instrument.
"""

from __future__ import annotations

import numpy as np

from ...errors import ReaderError
from ._common import channel_format, channel_info, length_unit, measurement
from .hdf5 import open_h5, read_dataset

_MAGIC = b"\x89HDF\r\n\x1a\n"
_MAX_META_ROWS = 100_000


def _text(value) -> str:
    if isinstance(value, np.ndarray):
        value = value.ravel()[0] if value.size else b""
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)


def _sniff(head: bytes, path: str) -> bool:
    if not head.startswith(_MAGIC):
        return False
    with open_h5(path) as f:
        return "MetaData" in f


def _surface_path(path, f) -> str:
    meta = f["MetaData"]
    if meta.shape is None or len(meta.shape) != 1 or meta.shape[0] > _MAX_META_ROWS or len(meta.dtype or ()) < 3:
        raise ReaderError(path, "the DATX /MetaData table is not a list of (source, link, destination) rows")
    links = {}
    for row in meta[()]:
        links.setdefault(_text(row[0]), {})[_text(row[1])] = _text(row[2])
    node = links.get("Root", {})
    for key in ("Measurement", "Surface"):
        target = node.get(key)
        if target is None or target not in links:
            raise ReaderError(path, f"the DATX metadata have no {key!r} link (no surface measurement)")
        node = links[target]
    surface = node.get("Path")
    if not surface or surface not in f:
        raise ReaderError(path, f"the DATX surface path {surface!r} is not in the file")
    return surface


def _converter(path, dset, name, category):
    conv = dset.attrs.get(name)
    if conv is None:
        raise ReaderError(path, f"the DATX surface has no {name!r} attribute")
    conv = np.ravel(conv)[0]
    if _text(conv[0]) != category:
        raise ReaderError(path, f"DATX {name} has category {_text(conv[0])!r}, not {category!r}")
    return _text(conv[1]), np.ravel(np.asarray(conv[-1], dtype=float))


def _find_attr(f, dset, key):
    import h5py

    node = dset.parent
    while True:
        for k, v in node.attrs.items():
            if k.endswith(key):
                return _text(v)
        if node.name == "/":
            break
        node = node.parent
    found = []
    if "Attributes" in f and isinstance(f["Attributes"], h5py.Group):
        f["Attributes"].visititems(lambda _n, obj: found.extend(_text(v) for k, v in obj.attrs.items()
                                                                if k.endswith(key)))
    return found[0] if found else None


def _parse(path):
    with open_h5(path) as f:
        return _surface(path, f)


def _surface(path, f):
    surface = _surface_path(path, f)
    dset = f[surface]
    if len(dset.shape or ()) != 2 or dset.dtype.kind not in "iuf":
        raise ReaderError(path, f"the DATX surface {surface!r} is not a 2D numeric array")
    ny, nx = dset.shape
    sizes = []
    for name in ("Y Converter", "X Converter"):
        unit, params = _converter(path, dset, name, "LateralCat")
        if unit != "Pixels" or params.size < 2 or not np.isfinite(params[1]) or params[1] <= 0:
            raise ReaderError(path, f"DATX {name} gives no pixel size (unit {unit!r}, parameters {params.tolist()})")
        sizes.append(params[1])
    zunit, _ = _converter(path, dset, "Z Converter", "HeightCat")
    unit = _text(dset.attrs.get("Unit", zunit))
    if length_unit(unit) is None:
        raise ReaderError(path, f"the DATX surface unit {unit!r} is not a length")
    info = channel_info(0, "Surface", (ny, nx), (ny * sizes[0], nx * sizes[1]), "m", length_unit(unit), height=True)
    attrs = {"instrument": _find_attr(f, dset, "System Type"), "serial_number": _find_attr(f, dset,
                                                                                           "System Serial Number")}
    no_data = dset.attrs.get("No Data")
    return [info], surface, attrs, None if no_data is None else float(np.ravel(no_data)[0])


def _load(path, info, surface, attrs, no_data):
    with open_h5(path) as f:
        values = read_dataset(path, f[surface], info.name).astype(np.float64)
    mask = ~np.isfinite(values)
    if no_data is not None:
        mask |= values == no_data
    return measurement(path, np.where(mask, np.nan, values), info, mask=mask, vendor="Zygo", **attrs)


channel_format("datx", "Zygo DATX (Mx software, HDF5)", (".datx",), _sniff, "Zygo DATX", _parse, _load, priority=8)
