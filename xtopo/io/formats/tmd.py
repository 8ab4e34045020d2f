"""TrueMap TMD v2.0 files (TrueGage TrueMap software).

Layout (little endian): the 32-byte magic ``"Binary TrueMap Data File v2.0\\r\\n\\0"``,
a NUL-terminated comment, then ``nx, ny`` (uint32), ``Lx, Ly, x0, y0`` (float32,
mm) and ``nx*ny`` float32 heights in mm, row by row.
"""

from __future__ import annotations

from ...conventions import make_measurement
from .._binary import BinaryReader
from ._common import ChannelInfo, channel_format, clean_text, sniff_magic

_MAGIC = b"Binary TrueMap Data File v2.0"
_MAX_COMMENT = 4096


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not a TrueMap TMD v2.0 file")
    data = r.data
    end = data.find(b"\0", 32, 32 + _MAX_COMMENT)
    if end < 0:
        raise r.error("unterminated comment in TMD header")
    comment = clean_text(data[32:end])
    nx, ny, lx, ly, x0, y0 = r.unpack("2I4f", "TMD header", at=end + 1)
    if nx == 0 or ny == 0 or not (lx > 0 and ly > 0):
        raise r.error(f"invalid TMD grid {nx} x {ny} over {lx} x {ly} mm")
    return [ChannelInfo(0, "Height", (ny, nx), (ly, lx), "mm", "mm")], r, dict(x0=x0, y0=y0, comment=comment)


def _load(path, info, r, h):
    z = r.array("f4", info.shape[0] * info.shape[1], "TMD height data").reshape(info.shape)
    return make_measurement(z, size=info.size, units="mm", vendor="TrueGage (TrueMap)", comment=h["comment"] or None,
                            x_offset=h["x0"], y_offset=h["y0"], original_units="mm")


channel_format("tmd", "TrueMap TMD v2.0 surface", (".tmd",), sniff_magic(_MAGIC), "TrueMap TMD", _parse, _load)
