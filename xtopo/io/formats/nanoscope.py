"""Bruker / Digital Instruments / Veeco NanoScope files (``.spm``, ``.di``, ``.001``, ``.002``, ...).

Layout (NanoScope ≥ 4.3, little-endian):

* A text header of ``\\Key: value`` lines grouped into sections that start with
  ``\\*Section name`` and end with ``\\*File list end``.  The first section's
  ``\\Data length`` is the header size in bytes.
* One ``\\*Ciao image list`` section per channel with ``Data offset``, ``Data length``,
  ``Bytes/pixel`` (2 or 4, signed integers), ``Samps/line`` (x pixels),
  ``Number of lines`` (y pixels), ``Scan Size: <x> <y> <unit>`` and the channel's
  ``@2:Image Data: S [id] "name"``.
* Values of type ``V`` read ``V [soft scale] (hard scale/LSB) hard value``.  The
  channel scale ``@2:Z scale: V [Sens. Zsens] (0.0050354 V/LSB) 2.910461 V`` gives
  the full signal range (``hard value``) that the whole integer range
  ``2^(8·bytes)`` maps to, and names the sensitivity ``@Sens. Zsens: V 20.83 nm/V``
  that converts volts to the physical unit::

      height = raw / 2^(8·bytes) · hard value [V] · sensitivity [nm/V]

  (The per-LSB number in parentheses is the DAC resolution of the hardware
  channel and is not the data scale: it agrees with ``hard value / 2^(8·bytes)``
  only when the full range is displayed.)  A sensitivity without a unit (phase,
  amplitude) leaves the hard value's unit (``º``, ``mV``, ``V``).

Rows are kept in file order: ``y`` grows with the line number in the file.
"""

from __future__ import annotations

import re

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from .._text import is_number
from ._common import (channel_format, channel_info, length_unit, measurement, parse_time, sniff_magic, to_float, to_int,
                      unique_name, unit_factor, value_unit)

_END = b"\\*File list end"
_VALUE_RE = re.compile(r"^([VCS])\s+(?:\[([^\]]*)\]\s*)?(?:\(([^)]*)\)\s*)?(.*)$")
_NUM_UNIT_RE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def _parse_header(path, data: bytes) -> list[tuple[str, dict]]:
    end = data.find(_END, 0, 1 << 22)
    if end < 0:
        raise ReaderError(path, "NanoScope header has no '\\*File list end' marker (truncated or not NanoScope)")
    text = data[:end].decode("latin-1", errors="replace")
    sections: list[tuple[str, dict]] = []
    for raw in re.split(r"\r\n|\n|\r", text):
        line = raw.strip()
        if len(line) < 2 or line[0] not in "\\?":
            continue
        line = line[1:]
        if line.startswith("*"):
            sections.append((line[1:].strip().lower(), {}))
            continue
        if not sections:
            continue
        start = 3 if re.match(r"@\d:", line) else 0
        colon = line.find(":", start)
        if colon < 0:
            continue
        sections[-1][1][line[:colon].strip().lower()] = line[colon + 1:].strip()
    if not sections or sections[0][0] != "file list":
        raise ReaderError(path, "NanoScope header does not start with a '\\*File list' section")
    return sections


def _value(text: str, bare: bool = False):
    """``(soft scale name, hard value, hard unit)`` of a ``V [..] (..) value unit`` field (``bare``: or of a
    ``value unit`` without the type letter, as a sensitivity ``@Sens. X: V 20.8 nm/V`` may be)."""
    m = _VALUE_RE.match(text or "")
    nm = _NUM_UNIT_RE.match(m.group(4) if m else (text or "") if bare else "")
    soft = m.group(2) if m else None
    return (soft, float(nm.group(1)), nm.group(2)) if nm else (soft, None, "")


def _scan_size(path, text: str, what: str):
    """``(sx, sy, unit)`` from ``500 500 nm`` or ``15000 nm`` (square)."""
    parts = (text or "").split()
    k = next((i for i, p in enumerate(parts) if not is_number(p)), len(parts))  # numbers, then the unit
    if k == 0 or k == len(parts):
        raise ReaderError(path, f"cannot parse NanoScope scan size {text!r} ({what})")
    lu = length_unit(parts[k])
    if lu is None:
        raise ReaderError(path, f"NanoScope scan size unit {parts[k]!r} is not a length ({what})")
    return float(parts[0]), float(parts[min(k - 1, 1)]), lu


def _parse(path):
    data = read_bytes(path)
    sections = _parse_header(path, data)
    # sensitivities ("@Sens. X") may sit in any non-image section
    sens = {}
    globals_ = {}
    for name, sec in sections:
        if name in ("ciao image list", "ciao force image list"):
            continue
        for k, v in sec.items():
            globals_.setdefault(k, v)
            if k.startswith("@sens."):
                sens[k[1:]] = v
    scan = next((sec for name, sec in sections if name == "ciao scan list"), {})
    images = [sec for name, sec in sections if name == "ciao image list"]
    default_bpp = to_int(path, globals_.get("bytes/pixel", "2"), "Bytes/pixel", default=2)
    channels = []
    names_seen = set()
    for i, sec in enumerate(images):
        what = f"image section {i}"
        nx = to_int(path, sec.get("samps/line", scan.get("samps/line")), f"Samps/line ({what})", minimum=1)
        ny = to_int(path, sec.get("number of lines", scan.get("lines")), f"Number of lines ({what})", minimum=1)
        bpp = to_int(path, sec.get("bytes/pixel", default_bpp), f"Bytes/pixel ({what})", minimum=1)
        if bpp not in (1, 2, 4):
            raise ReaderError(path, f"unsupported NanoScope Bytes/pixel {bpp} ({what})")
        offset = to_int(path, sec.get("data offset"), f"Data offset ({what})")
        size_text = sec.get("scan size", scan.get("scan size"))
        sx, sy, lunit = _scan_size(path, size_text, what)
        # a single scan size with an aspect ratio: y size follows from the ratio
        if len((size_text or "").split()) == 2 and ny != nx:
            sy = sx * ny / nx
        m = re.search(r'\[([^\]]*)\]\s*"([^"]*)"', sec.get("@2:image data", "") or sec.get("image data", ""))
        ident, label = (m.group(1), m.group(2)) if m else ("", "")
        label = label or ident or f"channel {i}"
        if sec.get("line direction", "").lower() == "retrace":
            label += " (retrace)"
        name = unique_name(label, names_seen)
        zkey = "@2:z scale" if "@2:z scale" in sec else "@4:z scale"
        if zkey not in sec:
            raise ReaderError(path, f"NanoScope {what} has no '@2:Z scale' (files before version 4.3 "
                                    "are not supported)")
        soft, hard_value, hard_unit = _value(sec[zkey])
        if hard_value is None:
            raise ReaderError(path, f"cannot parse NanoScope Z scale {sec[zkey]!r} ({what})")
        hard_unit = value_unit(hard_unit)
        scale = hard_value / float(1 << (8 * bpp))
        unit = hard_unit
        if soft:
            _, sval, sunit = _value(sens.get(soft.lower(), ""), bare=True)
            if sval is not None:
                scale *= sval
                if "/" in sunit:
                    num, den = sunit.split("/", 1)
                    f = unit_factor(hard_unit, value_unit(den)) if hard_unit else 1.0
                    if f is None:
                        raise ReaderError(path, f"NanoScope sensitivity {soft!r} in {sunit!r} does not fit "
                                                f"the Z scale unit {hard_unit!r} ({what})")
                    scale *= f
                    unit = value_unit(num)
        channels.append(dict(
            info=channel_info(i, name, (ny, nx), (sy, sx), lunit, unit, hint=f"{ident} {label}"),
            ident=ident, nx=nx, ny=ny, bpp=bpp, offset=offset, scale=scale, unit=unit, lunit=lunit))
    return [c["info"] for c in channels], data, globals_, channels


def _load(path, info, data, glob, channels):
    ch = channels[info.index]
    dtype = {1: "i1", 2: "<i2", 4: "<i4"}[ch["bpp"]]
    raw = BinaryReader(data, path).array(dtype, ch["nx"] * ch["ny"], what=f"NanoScope channel {ch['info'].name!r}",
                                         at=ch["offset"]).reshape(ch["ny"], ch["nx"])
    tip = to_float(path, glob.get("tip radius", ""), "Tip Radius", default=float("nan"))
    tip_nm = tip if np.isfinite(tip) and tip > 0 else None
    attrs = dict(
        instrument=glob.get("description") or glob.get("microscope"),
        vendor="Bruker (Digital Instruments / Veeco NanoScope)",
        acquisition_time=parse_time(glob.get("date", ""), "%I:%M:%S %p %a %b %d %Y", "%H:%M:%S %a %b %d %Y"),
        nanoscope_version=glob.get("version"),
        operating_mode=(re.findall(r'"([^"]*)"', glob.get("@microscopelist", "")) or [None])[0],
        channel_id=ch["ident"] or None,
    )
    if tip_nm is not None:
        # "Tip Radius" carries no unit in the header; Bruker states it in nm
        attrs["tip_radius"] = tip_nm * (unit_factor("nm", ch["lunit"]) or 1.0)
    return measurement(path, raw, info, height_scale=ch["scale"], **attrs)


channel_format("nanoscope", "Bruker/Digital Instruments NanoScope AFM image (.spm, .di, .00x)",
               (".spm", ".di", ".000", ".001", ".002", ".003", ".004", ".005", ".006", ".007", ".008", ".009"),
               sniff_magic(b"\\*File list", b"?*File list"), "NanoScope", _parse, _load)
