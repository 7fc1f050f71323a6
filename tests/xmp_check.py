"""The one reader of delivered XMP for the tests: a TIFF's XMP packet (tag 700) parsed by a strict XML parser
(expat, through xml.etree.ElementTree: an ill-formed packet fails the test that reads it), its ``dc:`` and
``dualrgb:`` fields returned. Every test that delivers reads its TIFFs through :func:`read_xmp`.

exiftool (an independent reader; used where installed, the tests say so when it is not): :func:`exiftool_text`
reads one tag's value as exiftool prints it (``-b``: raw, no print conversion).
"""
from __future__ import annotations

import shutil
import subprocess
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import tifffile

from dualrgb.app.processing.outputs import XMP_NAMESPACE

RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
DC = "http://purl.org/dc/elements/1.1/"
XMP = "http://ns.adobe.com/xap/1.0/"
XML_LANG = "{http://www.w3.org/XML/1998/namespace}lang"
EXIFTOOL = shutil.which("exiftool")
NO_EXIFTOOL = "exiftool is not installed (Debian: libimage-exiftool-perl); the read-back by tifffile + expat ran"


@dataclass
class XmpFields:
    """What a delivered XMP packet says: Dublin Core identifier and title, xmp: tool, the dualrgb: properties (local
    name -> text) and the ExtraColumns bag (property -> the exact column name)."""

    identifier: str | None
    title: str | None
    creator_tool: str | None
    description: str | None = None
    dualrgb: dict[str, str] = field(default_factory=dict)
    columns: dict[str, str] = field(default_factory=dict)

    @property
    def extra(self) -> dict[str, str]:
        """The extra fields by their exact column names."""
        return {column: self.dualrgb[prop] for prop, column in self.columns.items()}


def xmp_bytes(path: Path) -> bytes:
    with tifffile.TiffFile(path) as t:
        tag = t.pages[0].tags.get(700)
        assert tag is not None, f"{path}: no XMP (tag 700)"
        return bytes(tag.value)


def parse_xmp(packet: bytes) -> XmpFields:
    """The fields of an XMP packet; expat raises on anything that is not well-formed XML."""
    root = ET.fromstring(packet)                 # strict: expat, "not well-formed (invalid token)" on \x0b, \x01
    desc = root.find(f".//{{{RDF}}}Description")
    assert desc is not None, "no rdf:Description in the XMP packet"
    title = desc.find(f"{{{DC}}}title/{{{RDF}}}Alt/{{{RDF}}}li")
    if title is not None:
        assert title.get(XML_LANG) == "x-default"
    description = desc.find(f"{{{DC}}}description/{{{RDF}}}Alt/{{{RDF}}}li")
    if description is not None:
        assert description.get(XML_LANG) == "x-default"
    out = XmpFields(_text(desc.find(f"{{{DC}}}identifier")), _text(title), _text(desc.find(f"{{{XMP}}}CreatorTool")),
                    _text(description))
    for child in desc:
        ns, _, name = child.tag[1:].partition("}")
        if ns != XMP_NAMESPACE:
            continue
        if name == "ExtraColumns":
            for li in child.iter(f"{{{RDF}}}li"):
                out.columns[_text(li.find(f"{{{XMP_NAMESPACE}}}Property")) or ""] = _text(
                    li.find(f"{{{XMP_NAMESPACE}}}Column")) or ""
        else:
            out.dualrgb[name] = child.text or ""
    return out


def _text(elem: ET.Element | None) -> str | None:
    return None if elem is None else (elem.text or "")


def read_xmp(path: Path) -> XmpFields:
    """The XMP fields of a delivered TIFF, parsed strictly."""
    return parse_xmp(xmp_bytes(path))


def exiftool_text(path: Path, tag: str) -> str:
    """One tag as exiftool reads it (``-b``: the raw value, UTF-8), e.g. ``XMP-dc:Title``, ``IFD0:ImageDescription``.
    Note: exiftool reads values of an unknown namespace that look like a fraction ('1987/12') as numbers."""
    r = subprocess.run([EXIFTOOL, "-b", "-charset", "utf8", f"-{tag}", str(path)], capture_output=True, timeout=60,
                       check=True)
    return r.stdout.decode("utf-8")
