"""Alicona Imaging AL3D files (InfiniteFocus focus-variation microscopes).

Layout: the 17-byte magic ``"AliconaImaging\\0\\r\\n"``, then 52-byte tags
``key[20] value[30] "\\r\\n"`` (``Version``, ``TagCount`` and ``TagCount`` more),
a 256-byte comment, and at the absolute offset ``DepthImageOffset`` the depth
image: ``Rows`` rows of ``Cols`` float32 heights in metres, each row padded to
a multiple of 8 bytes.  ``PixelSizeXMeter``/``PixelSizeYMeter`` give the
spacing; NaN or ``InvalidPixelValue`` marks invalid pixels.
"""

from __future__ import annotations

import numpy as np

from ...conventions import make_measurement
from .._binary import BinaryReader
from ._common import ChannelInfo, channel_format, clean_text, sniff_magic

_MAGIC = b"AliconaImaging\x00\r\n"
_TAG = 52


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not an Alicona AL3D file")
    r.seek(len(_MAGIC))

    def tag():
        raw = r.read(_TAG, "AL3D tag")
        if raw[50:52] != b"\r\n":
            raise r.error(f"malformed AL3D tag at offset {r.pos - _TAG}")
        return clean_text(raw[:20]), clean_text(raw[20:50])

    tags = dict([tag(), tag()])
    if "TagCount" not in tags:
        raise r.error("AL3D header has no TagCount")
    count = int(tags["TagCount"])
    r.need(count * _TAG, "AL3D tag list")
    tags.update(tag() for _ in range(count))
    tags["Comment"] = clean_text(r.read(256, "AL3D comment")) if r.pos + 256 <= len(r) else ""
    try:
        nx, ny = int(tags["Cols"]), int(tags["Rows"])
        dx, dy = float(tags["PixelSizeXMeter"]), float(tags["PixelSizeYMeter"])
        offset = int(tags["DepthImageOffset"])
    except KeyError as exc:
        raise r.error(f"AL3D header lacks the tag {exc.args[0]!r}") from None
    if nx <= 0 or ny <= 0 or not (dx > 0 and dy > 0):
        raise r.error(f"invalid AL3D grid {nx} x {ny} with pixel size {dx} x {dy} m")
    return [ChannelInfo(0, "Depth", (ny, nx), (ny * dy, nx * dx), "m", "m")], r, tags, dx, dy, offset


def _load(path, info, r, tags, dx, dy, offset):
    ny, nx = info.shape
    row = (nx * 4 + 7) // 8 * 8 // 4  # row length with padding, in floats
    texture = int(tags.get("TextureImageOffset", "0") or 0)
    if texture > offset and not 0 <= texture - (offset + 4 * row * ny) < 4 * row:
        raise r.error(f"the {ny} x {nx} depth image at offset {offset} does not end where the texture image "
                      f"starts ({texture}): Rows/Cols corrupt?")
    z = r.array("f4", row * ny, "AL3D depth image", at=offset).reshape(ny, row)[:, :nx].astype(np.float64)
    undefined = ~np.isfinite(z)
    invalid = float(tags.get("InvalidPixelValue", "nan"))
    if np.isfinite(invalid):
        undefined |= np.abs(z - invalid) <= 1e-6 * abs(invalid)
    return make_measurement(z, spacing=(dy, dx), units="m", mask=undefined, vendor="Alicona Imaging",
                            instrument="Alicona InfiniteFocus", software=tags.get("CreatingApplication"),
                            comment=tags["Comment"] or None, original_units="m")


channel_format("al3d", "Alicona Imaging AL3D depth image", (".al3d",), sniff_magic(_MAGIC), "Alicona AL3D", _parse,
               _load)
