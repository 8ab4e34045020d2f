"""JPK Instruments (Bruker) image files: ``.jpk`` scans and ``.jpk-qi-image`` QI maps.

Both are TIFF files.  The first directory is a preview and carries the scan:
``32832``/``32833`` grid origin, ``32834``/``32835`` grid lengths ``uLength``/``vLength``
(m), ``32838``/``32839`` pixel counts, ``32771`` start date, ``32768`` software
version.  Every further directory is one channel: ``32848`` name,
``32849`` retrace flag, ``32850`` display name, and *slots*, the calibrations the
channel can be shown in: ``32896`` number of slots, ``32897`` the default slot's
name; slot ``k`` has its tags at ``0x8090 + 0x30·k`` (+0 name, +1 type, +0x10
calibration name, +0x12 unit, +0x13 scaling type, +0x14 multiplier, +0x15 offset).
A slot's linear scaling maps the stored integer directly to its unit
(``value = multiplier · raw + offset``); the ``raw`` slot has none.  The stored
samples are uncompressed strips (``BitsPerSample``/``SampleFormat``).

The reader shows each channel in its default slot.  Rows are kept in file order.
"""

from __future__ import annotations

from ...errors import ReaderError
from .._binary import read_bytes
from .._tiff import TiffFile, head_tags
from ._common import channel_format, channel_info, measurement, parse_time, to_float, unique_name, value_unit

_GRID = (32832, 32833, 32834, 32835, 32838, 32839)
_MAX_SLOTS = 64


def _sniff(head: bytes, path: str) -> bool:
    tags = head_tags(head)
    return all(t in tags for t in (32834, 32835, 32838, 32839))


def _dtype(tif: TiffFile, ifd: int, path) -> str:
    bits = tif.value(ifd, 258, 32)
    fmt = tif.value(ifd, 339, 1)
    key = (int(fmt) if not hasattr(fmt, "__len__") else int(fmt[0]),
           int(bits) if not hasattr(bits, "__len__") else int(bits[0]))
    table = {(1, 16): "u2", (1, 32): "u4", (2, 16): "i2", (2, 32): "i4", (3, 32): "f4", (3, 64): "f8"}
    if key not in table:
        raise ReaderError(path, f"unsupported JPK sample format/bits {key} in directory {ifd}")
    return table[key]


def _slot(tif: TiffFile, ifd: int, path):
    """``(name, unit, multiplier, offset)`` of the default slot of channel directory ``ifd``."""
    n = tif.value(ifd, 32896, 0)
    default = tif.value(ifd, 32897, "")
    if not isinstance(n, int) or not 0 <= n <= _MAX_SLOTS:
        raise ReaderError(path, f"implausible JPK slot count {n!r} in directory {ifd}")
    for k in range(n):
        base = 0x8090 + 0x30 * k
        if tif.value(ifd, base) != default:
            continue
        scaling = tif.value(ifd, base + 0x13, "NullScaling")
        if scaling == "LinearScaling":
            mult = to_float(path, tif.value(ifd, base + 0x14), f"slot {default!r} multiplier")
            off = to_float(path, tif.value(ifd, base + 0x15, 0.0), f"slot {default!r} offset")
        else:
            mult, off = 1.0, 0.0
        unit = value_unit(tif.value(ifd, base + 0x12, "") or "")
        return default, unit, mult, off
    return "raw", "", 1.0, 0.0


def _parse(path):
    data = read_bytes(path)
    tif = TiffFile(data, path)
    if not tif.ifds or not all(tif.has(0, t) for t in _GRID[2:]):
        raise ReaderError(path, "TIFF without the JPK grid tags 32834/32835/32838/32839")
    lx = to_float(path, tif.value(0, 32834), "grid uLength")
    ly = to_float(path, tif.value(0, 32835), "grid vLength")
    nx, ny = tif.value(0, 32838), tif.value(0, 32839)
    if not (isinstance(nx, int) and isinstance(ny, int) and nx > 0 and ny > 0):
        raise ReaderError(path, f"invalid JPK grid size {nx!r} x {ny!r}")
    infos, chans = [], []
    seen = set()
    for ifd in range(1, len(tif.ifds)):
        if not tif.has(ifd, 32848):
            continue
        ident = tif.value(ifd, 32848, "") or f"channel {ifd}"
        label = tif.value(ifd, 32850, "") or ident
        if tif.value(ifd, 32849, 0):
            label += " (retrace)"
        name = unique_name(label, seen)
        slot, unit, mult, off = _slot(tif, ifd, path)
        infos.append(channel_info(len(infos), name, (ny, nx), (ly, lx), "m", unit, hint=ident))
        chans.append(dict(ifd=ifd, ident=ident, slot=slot, unit=unit, mult=mult, off=off))
    return infos, tif, chans


def _load(path, info, tif, chans):
    ch, (ny, nx) = chans[info.index], info.shape
    w, h = tif.value(ch["ifd"], 256), tif.value(ch["ifd"], 257)
    if (w, h) != (nx, ny):
        raise ReaderError(path, f"JPK channel {info.name!r} is {w}x{h} pixels, the grid {nx}x{ny}")
    raw = tif.strips(ch["ifd"], _dtype(tif, ch["ifd"], path), (ny, nx), what=f"JPK channel {info.name!r}")
    values = raw.astype(float) * ch["mult"] + ch["off"]
    start = " ".join(str(tif.value(0, 32771, "") or "").split()[:2])
    return measurement(
        path, values, info,
        instrument=_instrument(tif),
        vendor="JPK Instruments (Bruker)",
        acquisition_time=parse_time(start, "%Y-%m-%d %H:%M:%S.%f", "%Y-%m-%d %H:%M:%S"),
        software_version=tif.value(0, 32768, None),
        imaging_mode=tif.value(0, 32850, None),
        calibration_slot=ch["slot"],
        channel_id=ch["ident"],
    )


def _instrument(tif: TiffFile):
    """``data-description.instrument`` from the text tags of the first directory, if any."""
    for tag in sorted(tif.ifds[0]):
        if tif.ifds[0][tag][0] != 2 or tag < 32768:
            continue
        text = tif.value(0, tag, "")
        for line in text.splitlines():
            key, sep, val = line.partition(" : ")
            if sep and key.strip() in ("data-description.instrument", "metadata.INSTRUMENT_NAME"):
                return val.strip() or None
    return None


channel_format("jpk", "JPK Instruments image / QI map (TIFF based)", (".jpk", ".jpk-qi-image"), _sniff, "JPK", _parse,
               _load, priority=20)
