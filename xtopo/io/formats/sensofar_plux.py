"""Sensofar PLUX files (SensoSCAN / SensoVIEW, S neox and S lynx profilers): a zip archive.

Layout (facts from SurfaceTopography's ``PLUX.py`` and surfalize's ``plux.py``): ``index.xml``
holds ``GENERAL`` (``IMAGE_SIZE_X``, ``IMAGE_SIZE_Y``, the pixel sizes ``FOV_X``, ``FOV_Y`` in µm,
and ``DATE``), ``INFO`` (``ITEM_n`` elements with ``NAME`` and ``VALUE``: ``Device``, ``Objective``,
``Technique``, ...) and one ``LAYER_n`` element per height layer whose ``FILENAME_Z`` names the
member holding it: ``IMAGE_SIZE_Y × IMAGE_SIZE_X`` little-endian float32 heights in µm, row by row,
NaN where undefined. The size is ``N × FOV``. The XML is parsed without DTDs or entities.
"""

from __future__ import annotations

import numpy as np

from ...errors import ReaderError
from .._binary import MAX_PIXELS
from .._xml import child_text, local_name, parse_xml
from .._zip import MAX_METADATA, open_zip
from ._common import channel_format, channel_info, measurement, parse_time, to_float, to_int, zip_member

_WHAT = "Sensofar PLUX"


def _sniff(head: bytes, path: str) -> bool:
    return head.startswith(b"PK\x03\x04") and b"index.xml" in head and b"main.xml" not in head


def _parse(path):
    with open_zip(path, _WHAT) as zf:
        root = parse_xml(zip_member(path, zf, "index.xml", _WHAT, "the zip archive has no index.xml, so it is not a "
                                    "Sensofar PLUX file", limit=MAX_METADATA), path, "PLUX index.xml")
    nx = to_int(path, child_text(root, "GENERAL", "IMAGE_SIZE_X"), "GENERAL/IMAGE_SIZE_X", minimum=1)
    ny = to_int(path, child_text(root, "GENERAL", "IMAGE_SIZE_Y"), "GENERAL/IMAGE_SIZE_Y", minimum=1)
    if nx * ny > MAX_PIXELS:
        raise ReaderError(path, f"implausible PLUX image size {nx} x {ny}")
    dx = to_float(path, child_text(root, "GENERAL", "FOV_X"), "GENERAL/FOV_X")
    dy = to_float(path, child_text(root, "GENERAL", "FOV_Y"), "GENERAL/FOV_Y")
    if not (dx > 0 and dy > 0):
        raise ReaderError(path, f"invalid PLUX pixel size {dx} x {dy} µm")
    items = {}
    for elem in root:
        if local_name(elem.tag) == "INFO":
            for item in elem:
                name, value = child_text(item, "NAME"), child_text(item, "VALUE")
                if name and value:
                    items.setdefault(name, value)
    layers = [(local_name(e.tag), child_text(e, "FILENAME_Z")) for e in root
              if local_name(e.tag).startswith("LAYER_") and child_text(e, "FILENAME_Z")]
    if not layers:
        raise ReaderError(path, "the PLUX index.xml names no height layer (LAYER_n/FILENAME_Z)")
    infos = [channel_info(i, name.replace("LAYER_", "Layer "), (ny, nx), (ny * dy, nx * dx), "um", "um", height=True)
             for i, (name, _member) in enumerate(layers)]
    return infos, [m for _n, m in layers], items, child_text(root, "GENERAL", "DATE", default="")


def _load(path, info, members, items, date):
    ny, nx = info.shape
    with open_zip(path, _WHAT) as zf:
        raw = zip_member(path, zf, members[info.index], _WHAT,
                         f"the PLUX archive lacks the layer member {members[info.index]!r}", expected=4 * nx * ny)
    z = np.frombuffer(raw, dtype="<f4").astype(np.float64).reshape(ny, nx)
    return measurement(path, z, info, mask=~np.isfinite(z), vendor="Sensofar", instrument=items.get("Device"),
                       objective=items.get("Objective"), technique=items.get("Technique"), comment=items.get("Comment"),
                       acquisition_time=parse_time(date, "%Y-%m-%dT%H:%M:%S", "%Y-%m-%d %H:%M:%S",
                                                   "%d/%m/%Y %H:%M:%S", "%a %b %d %H:%M:%S %Y"))


channel_format("plux", "Sensofar PLUX (zip with index.xml and float32 layers)", (".plux",), _sniff, _WHAT, _parse,
               _load)
