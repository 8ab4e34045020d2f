"""Olympus LEXT files (OLS laser scanning confocal microscopes): a multi-directory TIFF.

Layout (facts from Gwyddion's ``lextfile.c``, SurfaceTopography's ``LEXT.py`` and surfalize's
``lext.py``): the ``ImageDescription`` (tag 270) of the first directory holds an XML block
``<TiffTagDescData>`` with the scaling of each channel, ``HeightInfo/HeightDataPerPixelX``, ``...Y``
(pm per pixel) and ``...Z`` (pm per digit). The other directories are channels named by their own
``ImageDescription`` (``HEIGHT``, ``INTENSITY``, ``INVALID``, ...; the first directory is the colour
image). Optional calibration factors ``ImageCommonSettingsInfo/MakerCalibrationValueX/Y/Z`` (× 1e-6)
sit in an XML block ``<ExifTagDescData>`` in the EXIF ``DeviceSettingDescription`` (tag 41995 of the
EXIF directory, tag 34665). Heights are ``digit × DataPerPixelZ × calibration`` pm, the pixel size
``DataPerPixelX × calibration`` pm, the size ``N ×`` pixel size. A 1-bit ``INVALID`` image marks the
pixels that were not measured (bit set). XML is parsed without DTDs or entities.
"""

from __future__ import annotations

import numpy as np

from ...errors import ReaderError
from .._binary import read_bytes
from .._tiff import TiffFile, head_tags, is_tiff
from .._xml import child_text, parse_xml
from ._common import channel_format, channel_info, measurement, parse_time, to_float

_MAGIC = b"<TiffTagDescData"
_DESCRIPTION, _EXIF, _DEVICE_SETTINGS = 270, 34665, 41995
_SIGNALS = {"HEIGHT": "Height", "INTENSITY": "Intensity"}


def _sniff(head: bytes, path: str) -> bool:
    if not is_tiff(head):
        return False
    if _MAGIC in head:
        return True
    tag = head_tags(head).get(_DESCRIPTION)
    if tag is None or tag[0] != 2 or tag[1] <= 4:
        return False
    offset = int.from_bytes(tag[2], "little" if head[:2] == b"II" else "big")
    with open(path, "rb") as f:
        f.seek(offset)
        return _MAGIC in f.read(min(tag[1], 1 << 16))


def _xml_block(path, text, magic, what):
    start = text.find(magic)
    if start < 0:
        return None
    return parse_xml(text[start:].rstrip("\0 \r\n").encode("utf-8"), path, what)


def _calibration(path, tif):
    """The maker calibration factors (x, y, z) from the EXIF block; 1 where absent."""
    factors = [1.0, 1.0, 1.0]
    exif = tif.value(0, _EXIF)
    if exif is None:
        return factors
    sub = tif.sub_directory(int(exif))
    if not tif.has(sub, _DEVICE_SETTINGS):
        return factors
    raw = tif.raw(sub, _DEVICE_SETTINGS)  # ASCII (2) or UNDEFINED (7): bytes either way
    root = _xml_block(path, raw.decode("latin-1"), "<ExifTagDescData", "LEXT EXIF settings")
    for i, axis in enumerate("XYZ"):
        text = child_text(root, "ImageCommonSettingsInfo", f"MakerCalibrationValue{axis}")
        if text is not None:
            value = 1e-6 * to_float(path, text, f"MakerCalibrationValue{axis}")
            if value > 0:
                factors[i] = value
    return factors


def _parse(path):
    tif = TiffFile(read_bytes(path), path)
    root = _xml_block(path, tif.value(0, _DESCRIPTION, ""), _MAGIC.decode(), "LEXT TiffTagDescData")
    if root is None:
        raise ReaderError(path, "TIFF without the Olympus LEXT <TiffTagDescData> block")
    per = [to_float(path, child_text(root, "HeightInfo", f"HeightDataPerPixel{a}"), f"HeightDataPerPixel{a}")
           for a in "XYZ"]
    cal = _calibration(path, tif)
    dx, dy, dz = (p * c for p, c in zip(per, cal))
    if not (dx > 0 and dy > 0 and dz > 0):
        raise ReaderError(path, f"invalid LEXT scaling: {dx} x {dy} pm per pixel, {dz} pm per digit")
    pages, invalid = [], None
    for i in range(1, len(tif.ifds)):
        title = str(tif.value(i, _DESCRIPTION, "")).strip().upper()
        if title in _SIGNALS and tif.value(i, 277, 1) == 1:
            pages.append((_SIGNALS[title], i))
        elif title == "INVALID":
            invalid = i
    if not any(name == "Height" for name, _ in pages):
        raise ReaderError(path, "the LEXT file has no HEIGHT image")
    infos = []
    for name, i in pages:
        nx, ny = int(tif.value(i, 256)), int(tif.value(i, 257))
        infos.append(channel_info(len(infos), name, (ny, nx), (ny * dy, nx * dx), "pm",
                                  "pm" if name == "Height" else "1", height=name == "Height"))
    when = parse_time(tif.value(0, 306, ""), "%Y:%m:%d %H:%M:%S")
    return infos, tif, [i for _, i in pages], invalid, dz, {"acquisition_time": when,
                                                           "software": tif.value(0, 305) or None}


def _image(tif, ifd, shape, what):
    bits = tif.value(ifd, 258, 8)
    fmt = tif.value(ifd, 339, 1)
    kinds = {(8, 1): "u1", (16, 1): "u2", (32, 1): "u4", (16, 2): "i2", (32, 2): "i4", (32, 3): "f4"}
    if (bits, fmt) not in kinds:
        raise ReaderError(tif.path, f"unsupported LEXT {what} sample type: {bits} bits, format {fmt}")
    return tif.strips(ifd, kinds[bits, fmt], shape, what)


def _invalid_mask(tif, ifd, shape):
    ny, nx = shape
    if tif.value(ifd, 258, 1) != 1 or (int(tif.value(ifd, 256)), int(tif.value(ifd, 257))) != (nx, ny):
        return None
    row = (nx + 7) // 8
    packed = tif.strips(ifd, "u1", (ny, row), "INVALID mask")
    return np.unpackbits(packed, axis=1)[:, :nx].astype(bool)


def _load(path, info, tif, ifds, invalid, dz, meta):
    values = _image(tif, ifds[info.index], info.shape, info.name).astype(np.float64)
    is_height = info.name == "Height"
    mask = _invalid_mask(tif, invalid, info.shape) if invalid is not None else None
    return measurement(path, values, info, height_scale=dz if is_height else 1.0, mask=mask, vendor="Olympus",
                       instrument="Olympus LEXT laser scanning confocal microscope", **meta)


channel_format("lext", "Olympus LEXT laser confocal microscope file (TIFF)", (".lext",), _sniff, "Olympus LEXT", _parse,
               _load, priority=12)
