"""Zygo MetroPro DAT files (interferometers).

Layout (big endian; Zygo MetroPro reference guide): magic ``88 1B 03 6F/70/71``,
header format (uint16) at 4, header size (uint32, 834 or 4096) at 6; intensity
origin/size ``ac_org_width, ac_org_height, ac_n_buckets`` (uint16) at 52/54/56,
``ac_n_bytes`` at 60; phase (height) raster ``cn_org_width, cn_org_height``
(uint16) at 68/70, ``cn_n_bytes`` at 72; ``time_stamp`` (int32, POSIX) at 76,
comment[82] at 80, ``intf_scale_factor S``, ``wavelength_in λ`` (m),
``obliquity_factor O``, ``magnification``, ``lateral_res`` (m/pixel) as float32
at 164/168/176/180/184, ``phase_res`` (int16) at 218, objective name[12] at 246,
part name[40] at 258.  After the header come the intensity data
(``ac_n_bytes``) and the phase data, int32 row by row; values ≥ 2147483640
are invalid.  ``h = raw * S * O * λ / R`` with ``R`` = 4096, 32768, 131072 for
``phase_res`` 0, 1, 2.
"""

from __future__ import annotations

import numpy as np

from ...conventions import make_measurement
from .._binary import BinaryReader
from ._common import ChannelInfo, channel_format, clean_text, sniff_magic, unix_time

_MAGICS = (b"\x88\x1b\x03\x6f", b"\x88\x1b\x03\x70", b"\x88\x1b\x03\x71")
_PHASE_RES = {0: 4096, 1: 32768, 2: 131072}
_INVALID = 2147483640
#: the header fields read, from offset 0 (the layout above; ``x``: bytes skipped)
_HEADER = "4sHI42x3H2xI4x2HIi82s2x6f30xh22xH2x12s40s"
_NAMES = ("magic format header_size ac_w ac_h ac_buckets ac_bytes nx ny cn_bytes time comment S wavelength _na O "
          "magnification lateral_res phase_res serial objective part").split()


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGICS, not_this="not a Zygo MetroPro DAT file", endian=">")
    h = dict(zip(_NAMES, r.unpack(_HEADER, "MetroPro header", at=0)))
    h.update({k: clean_text(h[k]) for k in ("comment", "objective", "part")})
    if h["phase_res"] not in _PHASE_RES:
        raise r.error(f"unknown MetroPro phase resolution code {h['phase_res']}")
    if h["nx"] == 0 or h["ny"] == 0:
        raise r.error("the MetroPro file holds no phase (height) data")
    if h["cn_bytes"] != 4 * h["nx"] * h["ny"]:
        raise r.error(f"the phase data size field ({h['cn_bytes']} bytes) does not match the "
                      f"{h['nx']} x {h['ny']} phase grid of 4-byte values (corrupt header)")
    d = h["lateral_res"]
    return [ChannelInfo(0, "Height", (h["ny"], h["nx"]), (h["ny"] * d, h["nx"] * d) if d > 0 else None, "m", "m")], r, h


def _load(path, info, r, h):
    if info.size is None:
        raise r.error("lateral_res is zero: the lateral calibration of this MetroPro file is unknown")
    start = h["header_size"] + h["ac_bytes"]
    raw = r.array("i4", h["nx"] * h["ny"], "MetroPro phase data", at=start).reshape(h["ny"], h["nx"])
    undefined = raw >= _INVALID
    scale = h["S"] * h["O"] * h["wavelength"] / _PHASE_RES[h["phase_res"]]
    z = np.where(undefined, np.nan, raw.astype(np.float64) * scale)
    return make_measurement(
        z, size=info.size, units="m", mask=undefined, vendor="Zygo", instrument="Zygo interferometer (MetroPro)",
        acquisition_time=unix_time(h["time"]), wavelength=h["wavelength"], wavelength_units="m",
        magnification=h["magnification"], objective=h["objective"] or None, part_name=h["part"] or None,
        comment=h["comment"] or None, serial=str(h["serial"]) if h["serial"] else None, original_units="m")


channel_format("metropro", "Zygo MetroPro DAT interferometer data", (".dat",), sniff_magic(*_MAGICS), "Zygo MetroPro",
               _parse, _load)
