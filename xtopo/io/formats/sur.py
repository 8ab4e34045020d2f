"""Digital Surf SUR files (MountainsMap's native single-surface format).

Layout: a 512-byte header (little endian for ``format == 0``, big endian for
``format == 257``) followed by a comment and a private zone of the sizes the
header states, then ``nx*ny`` signed integers of ``bits`` (16/32) bits, row by
row.  Height ``= raw * dz + ZOffset`` in the ``dz`` unit; lateral spacings
``dx``, ``dy`` are in their own units.  With ``special_points == 1`` the value
``zmin - 2`` marks non-measured points.  ``inversion`` 1/2/3 negates heights
(2: and mirrors left-right, 3: and mirrors top-bottom).
"""

from __future__ import annotations

import numpy as np

from ...conventions import length_factor, make_measurement, normalize_units
from .._binary import BinaryReader
from ._common import ChannelInfo, channel_format, clean_text, iso_time, sniff_magic

_HEADER = ("12s4H30s30s5H8sH2i2iI3f16s16s16s16s16s16s16s16s16s3f3H12s7Hf10s2H128s3f34s")
_NAMES = ("magic format nobjects version type object_name operator_name material acquisition range "
          "special_points absolute _r1 bits zmin zmax nx ny npoints dx dy dz xname yname zname "
          "dx_unit dy_unit dz_unit x_unit y_unit z_unit x_ratio y_ratio z_ratio imprint inversion "
          "leveling _r2 second minute hour day month year dayof duration _r3 comment_size "
          "private_size client_zone x_offset y_offset z_offset _r4").split()
_ACQUISITION = {1: "stylus", 2: "optical", 3: "thermocouple", 5: "stylus with skid", 6: "AFM", 7: "STM",
                8: "video", 9: "interferometric", 10: "structured light"}


def _unit(raw: bytes) -> str:
    text = clean_text(raw).replace("\xe6", "µ")  # old files: micro sign in an MS-DOS code page
    return normalize_units(text)


def _parse(path):
    r = BinaryReader.from_file(path, magic=b"DIGITAL SURF",
                               not_this="not a Digital Surf SUR file (magic 'DIGITAL SURF' missing)")
    fmt = int.from_bytes(r.data[12:14], "little")
    r.endian = ">" if fmt == 257 else "<"
    h = dict(zip(_NAMES, r.unpack(_HEADER, "SUR header", at=0)))
    if h["type"] not in (1, 2):
        raise r.error(f"SUR object type {h['type']} (series or binary image) is not supported; "
                      "export a single profile or surface")
    if h["bits"] not in (16, 32):
        raise r.error(f"unsupported SUR point size {h['bits']} bits (16 or 32 expected)")
    if h["nx"] <= 0 or h["ny"] <= 0:
        raise r.error(f"invalid SUR grid {h['nx']} x {h['ny']}")
    zu = _unit(h["dz_unit"])
    fx = length_factor(_unit(h["dx_unit"]), zu)
    fy = length_factor(_unit(h["dy_unit"]), zu) if h["ny"] > 1 else fx
    dx, dy = abs(h["dx"]) * fx, abs(h["dy"]) * fy
    name = clean_text(h["zname"]) or "Z"
    if h["ny"] == 1:
        return [ChannelInfo(0, name, (h["nx"],), (h["nx"] * dx,), zu, zu)], r, h, dx, dy
    return [ChannelInfo(0, name, (h["ny"], h["nx"]), (h["ny"] * dy, h["nx"] * dx), zu, zu)], r, h, dx, dy


def _load(path, info, r, h, dx, dy):
    zu, nx, ny = info.units, h["nx"], h["ny"]
    start = 512 + h["comment_size"] + h["private_size"]
    raw = r.array("i2" if h["bits"] == 16 else "i4", nx * ny, "SUR height data", at=start)
    undefined = (raw == h["zmin"] - 2) if h["special_points"] == 1 else np.zeros(raw.shape, bool)
    heights = raw.astype(np.float64) * float(h["dz"]) + float(h["z_offset"])
    heights[undefined] = np.nan
    shape = (ny, nx) if ny > 1 else (nx,)
    heights, undefined = heights.reshape(shape), undefined.reshape(shape)
    inv = h["inversion"]
    if inv in (1, 2, 3):
        heights = -heights
        if inv == 2:
            heights, undefined = heights[..., ::-1], undefined[..., ::-1]
        elif inv == 3 and ny > 1:
            heights, undefined = heights[::-1], undefined[::-1]
    comment = clean_text(r.data[512:512 + h["comment_size"]])
    return make_measurement(
        heights, spacing=(dy, dx) if ny > 1 else dx, units=zu, mask=undefined,
        name=clean_text(h["object_name"]) or None, vendor="Digital Surf",
        instrument=clean_text(h["operator_name"]) or None,
        acquisition_time=iso_time(h["year"], h["month"], h["day"], h["hour"], h["minute"], h["second"]),
        acquisition_type=_ACQUISITION.get(h["acquisition"]), comment=comment or None,
        original_units=f"x {_unit(h['dx_unit'])}, y {_unit(h['dy_unit'])}, z {zu}")


channel_format("sur", "Digital Surf SUR surface/profile", (".sur",), sniff_magic(b"DIGITAL SURF"), "Digital Surf SUR",
               _parse, _load)
