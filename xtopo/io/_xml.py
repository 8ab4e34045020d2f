"""Safe parsing of XML from untrusted files.

:func:`parse_xml` refuses any document type declaration (``<!DOCTYPE``) or
entity declaration (``<!ENTITY``) before handing the text to
:mod:`xml.etree.ElementTree`, so neither external entities (XXE: reading local
files or URLs) nor entity expansion bombs ("billion laughs") can occur.  Valid
measurement XML (X3P ``main.xml``, vendor headers) never needs a DTD.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from ..errors import ReaderError

__all__ = ["parse_xml", "local_name", "child", "child_text", "MAX_XML_BYTES"]

#: Largest XML document accepted (bytes).
MAX_XML_BYTES = 64 << 20

_FORBIDDEN = re.compile(rb"<!\s*(DOCTYPE|ENTITY|ELEMENT|ATTLIST)", re.IGNORECASE)


def parse_xml(data: bytes, path, what: str = "XML document") -> ET.Element:
    """Parse ``data`` into an element tree, refusing DTDs and entity declarations.

    Parameters
    ----------
    data : bytes
        The XML text.
    path : str
        File named in error messages.
    what : str
        What the XML is (``"main.xml"``), named in error messages.

    Raises
    ------
    ReaderError
        If the document is too large, declares a DTD/entities, or is not well-formed.
    """
    if len(data) > MAX_XML_BYTES:
        raise ReaderError(path, f"{what} is {len(data)} bytes, more than the {MAX_XML_BYTES} accepted")
    data = bytes(data)
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):  # UTF-16 (with BOM): transcoded so the declaration scan sees ASCII
        data = data.decode("utf-16").encode("utf-8")
    if _FORBIDDEN.search(data):
        raise ReaderError(path, f"{what} contains a DTD or entity declaration (<!DOCTYPE/<!ENTITY); refused "
                                "because such declarations enable external-entity and expansion attacks")
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise ReaderError(path, f"{what} is not well-formed XML: {exc}") from None


def local_name(tag: str) -> str:
    """Tag without its ``{namespace}`` prefix."""
    return tag.rsplit("}", 1)[-1]


def child(elem, *names):
    """The first descendant along the path ``names`` (namespace-agnostic), or ``None``."""
    for name in names:
        if elem is None:
            return None
        elem = next((c for c in elem if local_name(c.tag) == name), None)
    return elem


def child_text(elem, *names, default=None):
    """Stripped text of :func:`child` (``default`` where absent or empty)."""
    c = child(elem, *names)
    if c is None or c.text is None or not c.text.strip():
        return default
    return c.text.strip()
