"""Igor Pro binary wave files (``.ibw``, version 5), as written by Asylum Research AFMs.

Layout (Igor Technical Note PTN003; byte order from the first ``short``, the
version, which reads 5 in the file's byte order):

* ``BinHeader5`` (64 bytes): version, checksum, ``wfmSize`` (wave header + data),
  ``formulaSize``, ``noteSize``, ``dataEUnitsSize``, ``dimEUnitsSize[4]``,
  ``dimLabelsSize[4]``, ``sIndicesSize``, two option sizes.
* ``WaveHeader5`` (320 bytes): ``npnts`` at 12, ``type`` at 16 (2 float32,
  4 float64, 8/16/32 int8/16/32, +64 unsigned, +1 complex), wave name at 28,
  ``nDim[4]`` at 68, ``sfA[4]`` (step per dimension) at 84, ``sfB[4]`` at 116,
  ``dataUnits`` at 148, ``dimUnits[4][4]`` at 152.
* The data (``npnts`` values, first dimension fastest), then the formula, the note,
  the extended data units, extended dimension units, and the dimension labels
  (32 bytes each: the dimension's own label, then one per element).

Asylum images are ``(x, y, channel)`` waves: ``nDim[0]`` points per line (x),
``nDim[1]`` lines (y), ``nDim[2]`` channels named by the dimension-2 labels
(``HeightTrace``, ``PhaseRetrace``, ...).  The note holds ``key: value`` lines
separated by carriage returns (``ScanSize``, ``Date``, ``Time``, ``MicroscopeModel``).
A wave without dimension units (e.g. one exported by Gwyddion from unit-less data)
states neither a length unit nor, in practice, a size (Igor's default step is 1): pass
``file_units=`` to say what its positions and values are in; without it the wave is read in
metres, flagged with ``units_assumed`` and a :class:`~xtopo.errors.MetadataWarning` is issued.
"""

from __future__ import annotations

import re

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from .._generic import stated_or_given
from ._common import channel_format, channel_info, clean_text, length_unit, measurement, metres_assumed, parse_time

_TYPES = {2: "f4", 4: "f8", 8: "i1", 16: "i2", 32: "i4", 8 | 64: "u1", 16 | 64: "u2", 32 | 64: "u4"}
#: Value units of Asylum channels whose wave unit (usually "m") does not apply.
_SIGNAL_UNITS = ((re.compile(r"phase", re.I), "deg"), (re.compile(r"potential|bias|volt|user", re.I), "V"),
                 (re.compile(r"current", re.I), "A"), (re.compile(r"freq", re.I), "Hz"))


def _sniff(head: bytes, path: str) -> bool:
    if len(head) < 64 + 320:
        return False
    for e in "<>":
        ver = int.from_bytes(head[:2], "little" if e == "<" else "big", signed=True)
        if ver == 5:
            ndim = np.frombuffer(head[64 + 68:64 + 84], dtype=e + "i4")
            typ = int(np.frombuffer(head[64 + 16:64 + 18], dtype=e + "i2")[0])
            return bool(np.all(ndim >= 0)) and typ in _TYPES
    return False


def _parse(path, file_units=None):
    data = read_bytes(path)
    if len(data) < 2:
        raise ReaderError(path, "file too short for an Igor binary wave")
    endian = "<" if data[:2] == b"\x05\x00" else ">" if data[:2] == b"\x00\x05" else None
    if endian is None:
        raise ReaderError(path, f"unsupported Igor binary wave version (first bytes {data[:2]!r}); "
                                "only version 5 is read")
    r = BinaryReader(data, path, endian)
    hdr = r.unpack("hhiiii4i4iiii", "IBW binary header", at=0)
    wfm_size, formula_size, note_size, data_eunits_size = hdr[2:6]
    dim_eunits = hdr[6:10]
    dim_labels = hdr[10:14]
    # WaveHeader5 from offset 12 to 168: npnts, type, name, nDim, sfA (sfB skipped), dataUnits, dimUnits[4]
    npnts, typ, name, *fields = r.unpack("ih10x32s8x4i4d32x4s4s4s4s4s", "IBW wave header", at=64 + 12)
    name, ndim, sfa = clean_text(name), list(fields[:4]), fields[4:8]
    data_units, *dim_units = (clean_text(u) for u in fields[8:])
    if typ & 1:
        raise ReaderError(path, "complex Igor waves are not topographies")
    if typ not in _TYPES:
        raise ReaderError(path, f"unsupported Igor wave type {typ}")
    dtype = np.dtype(_TYPES[typ]).newbyteorder(endian)
    shape = [n for n in ndim if n > 0]
    if not shape or int(np.prod(shape, dtype=np.int64)) != npnts:
        raise ReaderError(path, f"Igor wave dimensions {ndim} do not match its {npnts} points")
    if len(shape) < 2:
        raise ReaderError(path, "the Igor wave is one-dimensional; xtopo reads images (x, y[, channel])")
    if len(shape) > 3:
        raise ReaderError(path, f"4-dimensional Igor waves are not supported (dims {ndim})")
    data_start = 64 + 320
    for size, what in ((wfm_size, "wfmSize"), (formula_size, "formulaSize"), (note_size, "noteSize"),
                       (data_eunits_size, "dataEUnitsSize"), *((s, "dimEUnitsSize") for s in dim_eunits),
                       *((s, "dimLabelsSize") for s in dim_labels)):
        if size < 0 or size > len(data):
            raise ReaderError(path, f"IBW header field {what}={size} is impossible for a {len(data)}-byte file")
    if wfm_size - 320 < npnts * dtype.itemsize:
        raise ReaderError(path, f"IBW wfmSize {wfm_size} is too small for {npnts} points")
    pos = 64 + wfm_size + formula_size
    r.seek(min(pos, len(data)))
    note = r.read(note_size, "wave note").decode("latin-1", errors="replace") if pos <= len(data) else ""
    if data_eunits_size:
        data_units = clean_text(r.read(data_eunits_size, "extended data units"))
    for i in range(4):
        if dim_eunits[i]:
            dim_units[i] = clean_text(r.read(dim_eunits[i], "extended dimension units"))
    raw = [r.read(n, "dimension labels") for n in dim_labels][2]  # all read: a truncated list is an error
    labels = [clean_text(raw[k:k + 32]) for k in range(0, len(raw), 32)]
    nchan = shape[2] if len(shape) == 3 else 1
    # the first label names the dimension itself, the others the channels
    chan_names = labels[1:1 + nchan] if len(labels) >= nchan + 1 else []
    notes = {}
    for line in re.split(r"\r\n|\r|\n", note):
        k, sep, v = line.partition(":")
        if sep and k.strip():
            notes.setdefault(k.strip(), v.strip())
    nx, ny = shape[0], shape[1]
    lunit = length_unit(dim_units[0]) or length_unit(dim_units[1])
    assumed = lunit is None
    lunit = stated_or_given(path, lunit, file_units, "file_units") or "m"
    size = (abs(sfa[1]) * ny, abs(sfa[0]) * nx)
    infos = []
    for i in range(nchan):
        cname = chan_names[i] if i < len(chan_names) and chan_names[i] else ""
        cname = cname or (name if nchan == 1 and name else f"channel {i}")
        unit = next((u for rx, u in _SIGNAL_UNITS if rx.search(cname)), data_units or lunit)
        infos.append(channel_info(i, cname, (ny, nx), size, lunit, unit, height=True if nchan == 1 else None))
    return infos, dict(r=r, dtype=dtype, npnts=npnts, start=data_start, shape=shape, notes=notes, lunit=lunit,
                       assumed=assumed, wave=name)


def _load(path, info, p, file_units=None):
    arr = p["r"].array(p["dtype"], p["npnts"], what="IBW wave data", at=p["start"])
    nx, ny = p["shape"][0], p["shape"][1]
    arr = arr.reshape(-1, ny, nx)[info.index]  # first dimension fastest: (channel, y, x)
    notes = p["notes"]
    model = notes.get("MicroscopeModel")
    date = f"{notes.get('Date', '')} {notes.get('Time', '')}"
    attrs = dict(
        instrument=model,
        vendor="Asylum Research (Oxford Instruments)" if model or "ScanSize" in notes else None,
        acquisition_time=parse_time(date, "%Y-%m-%d %I:%M:%S %p", "%Y-%m-%d %H:%M:%S"),
        imaging_mode=notes.get("ImagingMode"),
        wave_name=p["wave"] or None,
        software_version=notes.get("Version"),
    )
    if p["assumed"] and file_units is None:
        attrs.update(metres_assumed(path, "Igor wave"))
    return measurement(path, arr, info, value_units=info.height_units or p["lunit"], **attrs)


channel_format("ibw", "Igor Pro binary wave (Asylum Research AFM)", (".ibw",), _sniff, "IBW", _parse, _load, priority=5,
               options=("file_units",))
