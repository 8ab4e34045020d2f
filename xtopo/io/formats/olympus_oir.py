"""Olympus (Evident) OIR files of laser scanning microscopes (OLS5000 ...) and packed ``.poir`` archives.

Layout (little endian; facts from SurfaceTopography's ``OIR.py``): the magic ``"OLYMPUSRAWFORMAT"``
and a 96-byte header; then chunks ``size`` (int32; -1 ends the file), ``type`` (int32):

* 0, a list of metadata blocks filling ``size`` bytes; 1, one metadata block. A block is its type
  (uint32), eight uint32 header fields and a body; strings are uint32-length-prefixed. Bodies: types
  1-4 and 14 one string (XML: 2 holds the image properties); 5 and 11 ``n`` pairs of strings;
  6, 7, 8, 12, 13 ``n`` × (string, uint32) (6: the topography prefix such as ``t001_0_1``; 8: the
  UUIDs of the topography channels); 9 ``n`` × (uint32, string, string); 10 ``n`` × (string, uint32,
  string, string).
* 2, a BMP preview (``"BMP"``, a byte, ``"BM"``, its size) filling ``size`` bytes.
* 3, a data block: a ``size``-byte header (uint32 0, the data size, the block's name as a string:
  ``<prefix>_<channel UUID>_0``), then the data size again, uint32 4, and the data.

The properties XML (``lsmimage:imageProperties``) gives the image ``width`` and ``height``, the
creation date, the microscope name, and per channel (``commonphase:channel id=UUID``) the image type
(``HEIGHT`` channels are read), the bytes per pixel (``depth``, else ``bitCounts`` rounded up to
bytes; 1 or 2), the pixel ``length`` x, y, z and their ``pixelUnit``; optional calibration factors
``pixelCalibration`` x, y, z multiply them. Heights are ``raw × length z × calibration z`` in the z
unit, the size ``N × length × calibration``.

A ``.poir`` file is a zip archive of OIR files; their height channels are listed one after the other.
XML is parsed without DTDs or entities; zip members are size-checked.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from .._xml import child, child_text, local_name, parse_xml
from .._zip import open_zip, read_member
from ._common import (channel_format, channel_info, length_unit, measurement, parse_time, sniff_magic, to_float, to_int,
                      unit_factor)

_MAGIC = b"OLYMPUSRAWFORMAT"
_HEADER = 96
_MAX_STRING = 64 << 20
_MAX_ENTRIES = 1 << 20
# metadata block bodies: "S" a string, "I" a uint32; a list is repeated a counted number of times
_BLOCKS = {1: "S", 2: "S", 3: "S", 4: "S", 14: "S", 5: ["S", "S"], 11: ["S", "S"], 6: ["S", "I"], 7: ["S", "I"],
           8: ["S", "I"], 12: ["S", "I"], 13: ["S", "I"], 9: ["I", "S", "S"], 10: ["S", "I", "S", "S"]}


def _string(r, what="OIR string"):
    n = r.unpack("I", f"{what} length")
    if n > _MAX_STRING:
        raise r.error(f"implausible OIR {what} length {n}")
    return r.read(n, what).decode("utf-8", errors="replace").strip("\0")


def _block(r, blocks):
    typ = r.unpack("I", "OIR metadata block type")
    if typ not in _BLOCKS:
        raise r.error(f"unknown OIR metadata block type {typ} at offset {r.pos - 4}")
    r.unpack("8I", "OIR metadata block header")
    spec = _BLOCKS[typ]
    if isinstance(spec, str):
        body = _string(r)
    else:
        n = r.unpack("I", "OIR metadata entry count")
        if n > _MAX_ENTRIES:
            raise r.error(f"implausible OIR metadata entry count {n}")
        body = [[_string(r) if k == "S" else r.unpack("I", "OIR metadata entry") for k in spec] for _ in range(n)]
    blocks.setdefault(typ, body)


def _chunks(r):
    """``(metadata blocks by type, data blocks by name -> (offset, size))`` of an OIR file."""
    r.seek(_HEADER)
    blocks, data = {}, {}
    while r.pos + 4 <= len(r):
        size = r.unpack("i", "OIR chunk size")
        if size == -1 or r.pos + 4 > len(r):
            break
        typ = r.unpack("i", "OIR chunk type")
        if size < 0 or r.pos + size > len(r):
            raise r.error(f"OIR chunk at offset {r.pos - 8} declares {size} bytes; {len(r) - r.pos} are left")
        end = r.pos + size
        if typ == 0:
            while r.pos < end:
                _block(r, blocks)
        elif typ == 1:
            _block(r, {})  # per-frame properties: not needed
        elif typ == 3:
            r.unpack("2I", "OIR data block header")
            name = _string(r, "OIR data block name")
            nbytes, _four = r.unpack("2I", "OIR data block size", at=end)
            r.need(nbytes, f"OIR data block {name!r}")
            data[name] = (r.pos, nbytes)
            end = r.pos + nbytes
        elif typ not in (2, 5):
            break  # a chunk type nobody has described: the rest is not needed
        if r.pos > end:
            raise r.error(f"OIR chunk ending at offset {end} overruns its size")
        r.seek(end)
    return blocks, data


def _channels_of(path, blocks, data, label=""):
    props = blocks.get(2)
    if not props:
        raise ReaderError(path, "the OIR file has no image properties block")
    root = parse_xml(props.encode("utf-8"), path, "OIR image properties")
    if local_name(root.tag) != "imageProperties":
        raise ReaderError(path, "the OIR file holds no laser scanning image (no lsmimage:imageProperties)")
    info = child(root, "imageInfo")
    nx = to_int(path, child_text(info, "width"), "imageInfo/width", minimum=1)
    ny = to_int(path, child_text(info, "height"), "imageInfo/height", minimum=1)
    calibration = child(root, "acquisition", "microscopeConfiguration", "pixelCalibration")
    cal = [to_float(path, child_text(calibration, a), f"pixelCalibration/{a}") if child_text(calibration, a)
           else 1.0 for a in "xyz"]
    prefix = (blocks.get(6) or [[""]])[0][0]
    topography = {entry[0] for entry in blocks.get(8, [])}
    meta = {"acquisition_time": parse_time((child_text(root, "general", "creationDateTime") or "")[:19],
                                           "%Y-%m-%dT%H:%M:%S"),
            "instrument": child_text(root, "microscope", "name")}
    out = []
    group = child(info, "phase", "group")
    for elem in (group if group is not None else []):
        if local_name(elem.tag) != "channel" or child_text(elem, "imageDefinition", "imageType") != "HEIGHT":
            continue
        uuid = elem.get("id", "")
        if topography and uuid not in topography:
            raise ReaderError(path, f"OIR height channel {uuid} is not among the topography channels")
        depth = child_text(elem, "imageDefinition", "depth")
        depth = int(depth) if depth else (to_int(path, child_text(elem, "imageDefinition", "bitCounts"),
                                                 "bitCounts", minimum=1) + 7) // 8
        if depth not in (1, 2):
            raise ReaderError(path, f"OIR height channel {uuid} has {depth} bytes per pixel (1 or 2 are read)")
        units = [length_unit(child_text(elem, "pixelUnit", a)) for a in "xyz"]
        if None in units:
            raise ReaderError(path, f"OIR height channel {uuid} has no length units ({units})")
        lengths = [to_float(path, child_text(elem, "length", a), f"length/{a}") for a in "xyz"]
        dx, dy = (lengths[i] * cal[i] * unit_factor(units[i], units[2]) for i in (0, 1))
        if not (dx > 0 and dy > 0):
            raise ReaderError(path, f"invalid OIR pixel size {dx} x {dy} {units[2]}")
        block = data.get(f"{prefix}_{uuid}_0")
        if block is None:
            raise ReaderError(path, f"the OIR file has no data block for height channel {uuid}")
        name = f"{label}Height" + (f" {len(out) + 1}" if out else "")
        out.append((channel_info(0, name, (ny, nx), (ny * dy, nx * dx), units[2], units[2], height=True),
                    dict(block=block, depth=depth, zscale=lengths[2] * cal[2], meta=meta)))
    return out


def _oir(path, data: bytes, label=""):
    if not data.startswith(_MAGIC):
        raise ReaderError(path, "not an Olympus OIR file (magic 'OLYMPUSRAWFORMAT' missing)")
    r = BinaryReader(data, path, "<")
    blocks, blocks_data = _chunks(r)
    return [(info, {**extra, "reader": r}) for info, extra in _channels_of(path, blocks, blocks_data, label)]


def _all(path):
    raw = read_bytes(path)
    if raw.startswith(_MAGIC):
        found = _oir(path, raw)
    else:
        found = []
        with open_zip(path, "Olympus POIR") as zf:
            names = [n for n in zf.namelist() if n.lower().endswith(".oir")]
            if not names:
                raise ReaderError(path, "the zip archive holds no .oir file, so it is not a packed OIR file")
            for n in names:
                try:
                    found += _oir(path, read_member(path, zf, zf.getinfo(n), "Olympus POIR"), f"{n}: ")
                except ReaderError as exc:
                    if "no laser scanning image" not in exc.reason:  # camera-only members hold no heights
                        raise
    if not found:
        raise ReaderError(path, "the OIR file holds no HEIGHT channel")
    return [dataclasses.replace(info, index=i) for i, (info, _) in enumerate(found)], [extra for _, extra in found]


def _load(path, info, extras):
    extra = extras[info.index]
    ny, nx = info.shape
    offset, nbytes = extra["block"]
    dtype = "u1" if extra["depth"] == 1 else "<u2"
    if nbytes != nx * ny * extra["depth"]:
        raise ReaderError(path, f"OIR data block of {nbytes} bytes does not hold {nx} x {ny} pixels of "
                                f"{extra['depth']} bytes")
    values = extra["reader"].array(dtype, nx * ny, "OIR height data", at=offset).reshape(ny, nx)
    return measurement(path, values.astype(np.float64), info, height_scale=extra["zscale"], vendor="Olympus",
                       **extra["meta"])


def _sniff_poir(head: bytes, path: str) -> bool:
    return head.startswith(b"PK\x03\x04") and b".oir" in head.lower()


channel_format("oir", "Olympus OIR laser scanning microscope file", (".oir",), sniff_magic(_MAGIC), "Olympus OIR", _all,
               _load)
channel_format("poir", "Olympus packed OIR (zip of OIR files)", (".poir",), _sniff_poir, "Olympus OIR", _all, _load,
               priority=9)
