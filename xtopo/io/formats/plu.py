"""Sensofar PLU files (SensoSCAN confocal / interferometric profilers).

Layout (little endian): date text[128] (``ctime`` style), POSIX time (uint32),
comment[256]; calibration ``rows, cols, N_tall`` (uint32), ``dy_multip,
µm/pixel x, µm/pixel y, x0, y0, µm/pixel z, z0`` (float32); measurement
configuration ``type, algorithm, method, objective, area_type`` (uint32);
40 bytes of scan settings; ``restore, num_layers, version, hardware,
num_images`` (uint8), 3 reserved bytes, ``factor_delmacio`` (uint32).  Then for
each layer: ``rows, cols`` (uint32) and ``rows*cols`` float32 heights in µm,
row by row; the value 1000001 marks undefined points.
"""

from __future__ import annotations

import numpy as np

from ...conventions import make_measurement
from .._binary import BinaryReader, read_bytes
from ._common import ChannelInfo, channel_format, clean_text, parse_time

_UNDEFINED = 1000001.0
_TYPES = {1: "profile", 3: "topography"}
_DATE_FORMAT = "%a %b %d %H:%M:%S %Y"  # ctime, e.g. "Tue Mar 15 10:12:01 2011"
_HARDWARE = {0: "PLu", 1: "PLu 2300 XGA", 2: "PLu 2300 XGA T5", 3: "PLu 2300 SXGA", 4: "PLu 3300", 5: "DCM 3D",
             6: "PLu neox", 7: "DCM 3D rev. 2", 8: "PLu Apex (prototype)", 9: "S neox", 10: "DCM8",
             11: "PLu Apex"}


def _sniff(head: bytes, path: str) -> bool:
    # no magic: a ctime date string at 0 and a plausible calibration block
    if len(head) < 508:
        return False
    r = BinaryReader(head, path, "<")
    date = clean_text(head[:128])
    rows, cols = r.unpack("2I", at=388)
    typ = r.unpack("I", at=428)
    return (parse_time(date, _DATE_FORMAT) is not None and typ in _TYPES
            and 0 < rows <= 100000 and 0 < cols <= 100000)


def _parse(path):
    data = read_bytes(path)
    r = BinaryReader(data, path, "<")
    h = {"date": clean_text(data[:128]), "comment": clean_text(data[132:388])}
    r.seek(388)
    (h["rows"], h["cols"], _nt, _dym, h["dx"], h["dy"], _x0, _y0, _dz, _z0) = r.unpack("3I7f", "PLU calibration")
    h["type"], _alg, _method, h["objective"], _area = r.unpack("5I", "PLU configuration")
    if h["type"] not in _TYPES:
        raise r.error(f"PLU measurement type {h['type']} is not a profile or topography")
    _restore, h["layers"], h["version"], h["hardware"], h["images"] = r.unpack("5B", "PLU configuration", at=488)
    r.seek(500)
    if not (h["dx"] > 0 and h["dy"] > 0):
        raise r.error(f"invalid PLU pixel size {h['dx']} x {h['dy']} µm")
    rows, cols = r.unpack("2I", "PLU layer size")
    if rows == 1:
        return [ChannelInfo(0, "Height", (cols,), (cols * h["dx"],), "um", "um")], r, h
    return [ChannelInfo(0, "Height", (rows, cols), (rows * h["dy"], cols * h["dx"]), "um", "um")], r, h


def _load(path, info, r, h):
    rows, cols = (1, *info.shape) if len(info.shape) == 1 else info.shape
    z = r.array("f4", rows * cols, "PLU height data").astype(np.float64)
    undefined = (z == _UNDEFINED) | ~np.isfinite(z)
    shape = (rows, cols) if rows > 1 else (cols,)
    version_ok = h["version"] != 0 and h["version"] <= 0xFB
    return make_measurement(
        z.reshape(shape), spacing=(h["dy"], h["dx"]) if rows > 1 else h["dx"], units="um",
        mask=undefined.reshape(shape), vendor="Sensofar",
        instrument=_HARDWARE.get(h["hardware"]) if version_ok else None,
        acquisition_time=parse_time(h["date"], _DATE_FORMAT),
        objective_code=h["objective"], comment=h["comment"] if h["comment"] not in ("", "(None)") else None,
        original_units="um")


channel_format("plu", "Sensofar PLU confocal/interferometric topography", (".plu", ".apx"), _sniff, "Sensofar PLU",
               _parse, _load, priority=5)
