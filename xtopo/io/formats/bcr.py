"""BCR-STM / BCRF files (SPIP / Image Metrology interchange format).

A text header of ``headersize`` characters (default 2048; latin-1, or UTF-16 LE
for the ``*_unicode`` variants, i.e. 2 bytes per character) with lines
``key = value`` (``%``/``#`` start comments), followed by the raster, row by
row: int16 for ``bcrstm`` (height ``= raw * bit2nm`` nm-scaled, 32767 = void),
float32 for ``bcrf`` (values above 1.7e38, or ``voidpixels``, are void).
``xlength``/``ylength`` are the scanning range in ``xunit``/``yunit`` (default nm);
heights are in ``zunit`` (default nm); ``intelmode = 1`` means little endian.

Physical size: the format's reference (SPIP/Image Metrology, "BCR-STM File Format") defines
``xlength`` and ``ylength`` as "the scanning range", i.e. the distance the scanner travels from
the first sample of a line to the last: ``(n - 1) Δ`` for ``n`` pixels, so xtopo reads the pixel
size as ``Δ = xlength / (n - 1)`` and the size of the measurement (paper §3.1, ``L = n Δ``) as
``xlength · n / (n - 1)``.  A real pair confirms it: ``bcrf-1.bcrf`` and ``mnt-1.mnt`` (the same
960 x 600 measurement, the Mountains document storing the step itself) agree in ``Δ`` to 1e-15
with this reading and differ by 0.1 % with ``Δ = xlength / n``, the reading of Gwyddion's
``bcrfile.c`` and SurfaceTopography's BCR reader (they set the size to ``xlength``).
"""

from __future__ import annotations

import numpy as np

from ...conventions import length_factor, make_measurement, normalize_units
from .._binary import BinaryReader, read_bytes
from ._common import ChannelInfo, channel_format, sniff_magic

_MAGIC = "fileformat = bcr"
_FORMATS = ("bcrstm", "bcrf", "bcrstm_unicode", "bcrf_unicode")


def _header(text: str) -> dict:
    out = {}
    for line in text.split("\n"):
        line = line.strip().strip("\0")
        if not line or line[0] in "%#" or "=" not in line:
            continue
        key, _, value = line.partition("=")
        out[key.strip().lower()] = value.strip()
    return out


def _parse(path):
    data = read_bytes(path)
    r = BinaryReader(data, path, "<")
    if data.startswith(_MAGIC.encode("utf-16-le")):
        encoding, width = "utf-16-le", 2
    elif data.startswith(_MAGIC.encode("latin-1")):
        encoding, width = "latin-1", 1
    else:
        raise r.error("not a BCR-STM/BCRF file")
    probe = _header(data[:2048 * width].decode(encoding, errors="replace"))
    size = int(probe.get("headersize", "2048")) * width
    r.need(size, "BCR header")
    h = _header(data[:size].decode(encoding, errors="replace"))
    if h.get("fileformat") not in _FORMATS:
        raise r.error(f"unknown BCR file format {h.get('fileformat')!r}")
    r.endian = "<" if int(h.get("intelmode", "1")) else ">"
    nx, ny = int(h["xpixels"]), int(h["ypixels"])
    if nx <= 0 or ny <= 0:
        raise r.error(f"invalid BCR grid {nx} x {ny}")
    xu, yu, zu = (normalize_units(h.get(f"{a}unit", "nm")) for a in "xyz")
    span = [(float(h[k]) * length_factor(u, zu), n) for k, u, n in (("ylength", yu, ny), ("xlength", xu, nx))]
    extent = tuple(length * n / (n - 1) if n > 1 else length for length, n in span)
    return [ChannelInfo(0, "Height", (ny, nx), extent, zu, zu)], r, h, size, f"x {xu}, y {yu}, z {zu}"


def _load(path, info, r, h, start, units):
    ny, nx = info.shape
    stm = h["fileformat"].startswith("bcrstm")
    itemsize = 2 if stm else 4
    if len(r) - start - nx * ny * itemsize >= nx * itemsize:
        raise r.error(f"the file holds {len(r) - start} bytes of data but the {nx} x {ny} grid needs "
                      f"{nx * ny * itemsize} (corrupt xpixels/ypixels, or data appended)")
    raw = r.array("i2" if stm else "f4", nx * ny, "BCR height data", at=start).astype(np.float64)
    if stm:
        undefined = raw == 32767
        z = raw * float(h.get("bit2nm", "1"))
    else:
        undefined = ~np.isfinite(raw) | (raw > 1.7e38)
        if "voidpixels" in h:
            void = float(h["voidpixels"])
            undefined |= np.isclose(raw, void, rtol=1e-6)
        z = raw
    return make_measurement(z.reshape(ny, nx), size=info.size, units=info.units, mask=undefined.reshape(ny, nx),
                            original_units=units, bcr_format=h["fileformat"])


channel_format("bcr", "BCR-STM / BCRF image (SPIP interchange)", (".bcr", ".bcrf"),
               sniff_magic(_MAGIC.encode("latin-1"), _MAGIC.encode("utf-16-le")), "BCR", _parse, _load)
