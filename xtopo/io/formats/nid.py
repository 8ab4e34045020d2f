"""Nanosurf easyScan / DriveAFM data files (``.nid``).

Layout: an INI-style text header (UTF-8) terminated by ``#!``, then the binary
channel data.  ``[DataSet]`` lists groups (``GroupCount``, ``Gr<g>-Name`` such as
"Scan forward", ``Gr<g>-Count``) and the channels present in each
(``Gr<g>-Ch<c>=DataSet-<g>:<c>``); the data blocks follow in that order
(group by group, channel number increasing).  Each ``[DataSet-<g>:<c>]`` section
gives ``Points`` (x pixels), ``Lines`` (y pixels), ``Dim0Range``/``Dim1Range`` with
``Dim0Unit``/``Dim1Unit`` (physical size), ``Dim2Name``/``Dim2Unit`` (the signal) and
``Dim2Min``/``Dim2Range`` (the value range the integers span), ``SaveBits``,
``SaveSign`` and ``SaveOrder`` (``Intel`` = little-endian).  A raw value maps to::

    value = Dim2Min + Dim2Range · (raw − raw_min) / 2^bits

with ``raw_min = −2^(bits−1)`` for signed and 0 for unsigned data.
Rows are kept in file order.
"""

from __future__ import annotations

import re

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from ._common import channel_format, channel_info, length_unit, measurement, to_float, to_int, value_unit

_MARK = b"#!"


def _sniff(head: bytes, path: str) -> bool:
    return head.lstrip(b"\xef\xbb\xbf").startswith(b"[DataSet]")


def _ini(text: str) -> dict[str, dict[str, str]]:
    sections: dict[str, dict[str, str]] = {}
    cur = None
    for line in re.split(r"\r\n|\n|\r", text):
        s = line.strip()
        if s.startswith("[") and s.endswith("]"):
            cur = sections.setdefault(s[1:-1], {})
        elif cur is not None and "=" in s:
            k, v = s.split("=", 1)
            cur.setdefault(k.strip(), v.strip())
    return sections


def _parse(path):
    data = read_bytes(path)
    end = data.find(_MARK, 0, 1 << 23)
    if end < 0:
        raise ReaderError(path, "NID header has no '#!' end marker (truncated or not a Nanosurf file)")
    ini = _ini(data[:end].decode("utf-8", errors="replace"))
    top = ini.get("DataSet", {})
    ngroups = to_int(path, top.get("GroupCount"), "GroupCount")
    if ngroups > 1000:
        raise ReaderError(path, f"implausible NID GroupCount {ngroups}")
    infos, blocks = [], []
    offset = end + len(_MARK)
    for g in range(ngroups):
        count = to_int(path, top.get(f"Gr{g}-Count", 0), f"Gr{g}-Count")
        gname = top.get(f"Gr{g}-Name", f"group {g}")
        for c in range(min(count, 1000)):
            ref = top.get(f"Gr{g}-Ch{c}")
            if not ref:
                continue
            sec = ini.get(ref)
            if sec is None:
                raise ReaderError(path, f"NID header lists {ref!r} but has no such section")
            nx = to_int(path, sec.get("Points"), f"Points of {ref}", minimum=1)
            ny = to_int(path, sec.get("Lines"), f"Lines of {ref}", minimum=1)
            bits = to_int(path, sec.get("SaveBits", 32), f"SaveBits of {ref}")
            if bits not in (8, 16, 32):
                raise ReaderError(path, f"unsupported NID SaveBits {bits} in {ref}")
            if sec.get("SaveMode", "Binary") != "Binary":
                raise ReaderError(path, f"NID SaveMode {sec.get('SaveMode')!r} in {ref} is not supported")
            signed = sec.get("SaveSign", "Signed").lower() == "signed"
            endian = "<" if sec.get("SaveOrder", "Intel").lower() == "intel" else ">"
            lx = to_float(path, sec.get("Dim0Range"), f"Dim0Range of {ref}")
            ly = to_float(path, sec.get("Dim1Range"), f"Dim1Range of {ref}")
            xu = length_unit(sec.get("Dim0Unit", "m"))
            if xu is None or length_unit(sec.get("Dim1Unit", "m")) != xu:
                raise ReaderError(path, f"NID lateral units {sec.get('Dim0Unit')!r}/{sec.get('Dim1Unit')!r} "
                                        f"of {ref} are not one length unit")
            vmin = to_float(path, sec.get("Dim2Min", 0), f"Dim2Min of {ref}")
            vrange = to_float(path, sec.get("Dim2Range"), f"Dim2Range of {ref}")
            unit = value_unit(sec.get("Dim2Unit", ""))
            label = f"{sec.get('Dim2Name') or ref} ({gname})"
            infos.append(channel_info(len(infos), label, (ny, nx), (ly, lx), xu, unit))
            dtype = f"{endian}{'i' if signed else 'u'}{bits // 8}"
            raw_min = -(1 << (bits - 1)) if signed else 0
            blocks.append(dict(offset=offset, dtype=dtype, nx=nx, ny=ny, scale=vrange / float(1 << bits),
                               zero=vmin - raw_min * vrange / float(1 << bits)))
            offset += nx * ny * bits // 8
    return infos, data, ini, blocks


def _load(path, info, data, ini, blocks):
    b = blocks[info.index]
    raw = BinaryReader(data, path).array(b["dtype"], b["nx"] * b["ny"], what=f"NID channel {info.name!r}",
                                         at=b["offset"])
    values = raw.reshape(b["ny"], b["nx"]) * b["scale"] + b["zero"]
    scan = ini.get("DataSet\\DataSetInfos\\Scan", ini.get("DataSet-Info", {}))
    glob = ini.get("DataSet\\DataSetInfos\\Global", ini.get("DataSet-Info", {}))
    date, time = scan.get("Date", ""), scan.get("Time", "")
    attrs = dict(
        instrument=glob.get("Head type") or None,
        vendor="Nanosurf",
        acquisition_date=f"{date} {time}".strip() or None,
        imaging_mode=glob.get("Op. mode") or None,
        cantilever=glob.get("Cantilever type") or None,
        software_version=glob.get("Software ver.") or None,
    )
    m = re.fullmatch(r"(\d\d)-(\d\d)-(\d{4})", date)
    if m and (int(m.group(1)) > 12 or int(m.group(2)) > 12) and re.fullmatch(r"\d\d:\d\d:\d\d", time):
        # the header does not state the field order; only unambiguous dates become ISO 8601
        a, bb, y = int(m.group(1)), int(m.group(2)), m.group(3)
        day, month = (a, bb) if a > 12 else (bb, a)
        attrs["acquisition_time"] = f"{y}-{month:02d}-{day:02d}T{time}"
    return measurement(path, values, info, **attrs)


channel_format("nid", "Nanosurf NID image", (".nid",), _sniff, "NID", _parse, _load)
