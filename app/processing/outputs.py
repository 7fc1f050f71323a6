"""Output files: 16-bit TIFFs with real TIFF metadata (resolution, Make/Model, DateTime, Software,
ImageDescription, DocumentName, Copyright; an EXIF IFD: app.processing.exif), embedded ICC profiles and XMP;
CSVs of patch values and matrices. Every file is written
through ``common.atomic_files.atomic_output`` (temp file, fsync, rename): a reader sees the old file or the new.

ICC profiles (all version 2.4: ArgyllCMS 2.3 reads no v4 profile and SLUB's checkit_tiff flags v4 as outdated;
LittleCMS' built-in sRGB that Pillow's ImageCms creates is v4.4, so none comes from there)
    * sRGB and ProPhoto RGB (ROMM RGB): :func:`matrix_trc_icc` writes a minimal ICC v2.4 display profile:
      header, desc, cprt, wtpt, r/g/bXYZ colorants (the colour space's RGB->XYZ matrix adapted to the ICC D50 PCS
      with Bradford) and r/g/bTRC as a 4096-entry sampled curve of the space's decoding function (sRGB's IEC
      61966-2-1 curve, ROMM's linear toe + 1.8 gamma). The tests check both through LittleCMS against
      colour-science's own conversion, and ArgyllCMS' ``iccdump`` reads them.
    * eciRGB v2 (L* curve) and Adobe RGB (1998)-compatible (gamma 563/256) the same way;
    * the linear XYZ master: :func:`xyz_icc`, the same kind of profile with X/Xn, Y/Yn, Z/Zn as its "R, G, B"
      (colorants the Bradford adaptation of the reference white to D50; linear curves), so an RGB TIFF of XYZ is
      read by colour-managed software as the colours it holds - in LittleCMS's default path too;
    * the camera-RGB masters: :func:`camera_icc`, a linear input profile (app.workflow.delivery.camera_profiles).

XMP
    An XMP packet (tag 700) with Dublin Core ``dc:identifier`` / ``dc:title`` / ``dc:description`` (the exact
    Unicode of the 7-bit ImageDescription: what MWG-style readers - exempi, ``exiftool -use MWG``, Lightroom -
    show as the description), ``dc:creator`` / ``dc:rights`` / ``dc:date`` / ``dc:format`` and
    ``xmpMM:History`` (:class:`DublinCore`), ``xmp:CreatorTool`` /
    ``xmp:CreateDate`` and the ``dualrgb:`` namespace (operator, calibration id, light dose, mode, ...), as
    exiftool and Adobe tools read it.

XYZ scale: the characterisation predicts XYZ on the ground-truth scale (eq 4.2: a perfect white has Y = 100
under D65). RGB encodings divide by the white's Y and adapt (Bradford) from that white to the RGB space's
white, so a perfect white becomes RGB (1, 1, 1) (app.processing.encode computes the arrays).
"""
from __future__ import annotations

import csv
import logging
import re
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from dualrgb.app.processing.exif import CaptureExif
from dualrgb.common.atomic_files import atomic_output
from dualrgb.common.clock import output_time
from dualrgb.simulation.matrix_fit import CharacterisationMatrix

log = logging.getLogger(__name__)

ICC_D50 = np.array([0.9642, 1.0, 0.8249])
SPACES = {"sRGB": "sRGB", "ProPhoto RGB": "ProPhoto RGB", "ECI RGB v2": "ECI RGB v2",
          "Adobe RGB (1998)": "Adobe RGB (1998)"}
ADOBE_GAMMA = 563 / 256                   # Adobe RGB (1998) Color Image Encoding, 2005: 2.19921875 (u8.8 0x0233)
XMP_NAMESPACE = "http://ns.dualrgb.org/1.0/"
RESOLUTION_UNIT_INCH = 2


# ---------------------------------------------------------------- colour conversion
def _colourspace(name: str):
    import colour

    try:
        return colour.RGB_COLOURSPACES[name]
    except KeyError:
        raise ValueError(f"unknown RGB colour space {name!r}; expected one of {', '.join(SPACES)}") from None


def _bradford(src_xyz: np.ndarray, dst_xyz: np.ndarray) -> np.ndarray:
    from colour.adaptation import matrix_chromatic_adaptation_VonKries

    return matrix_chromatic_adaptation_VonKries(np.asarray(src_xyz, float), np.asarray(dst_xyz, float), "Bradford")


def xyz_to_rgb_matrix(space: str, white_xyz: Sequence[float] | np.ndarray) -> np.ndarray:
    """3x3 M with linear RGB = M @ (XYZ / white_Y), adapting ``white_xyz`` to the space's white."""
    import colour

    cs = _colourspace(space)
    white = np.asarray(white_xyz, dtype=float) / float(white_xyz[1])
    dst = colour.xy_to_XYZ(cs.whitepoint)
    M = cs.matrix_XYZ_to_RGB @ _bradford(white, dst)
    # the published matrices (e.g. IEC 61966-2-1's 4-digit sRGB one) map the white to 1 +- 1e-4: normalise so
    # a perfect white is exactly RGB (1, 1, 1)
    return M / (M @ white)[:, None]


# ---------------------------------------------------------------- ICC profiles
SRGB_DESCRIPTION = "sRGB IEC61966-2.1 (dualrgb v2 matrix/TRC)"
# Built here from each space's published primaries, white and transfer function (colour-science's definitions):
# no vendor profile is copied, so none of their licences applies. "compatible": Adobe RGB (1998) is Adobe's
# trademark, and a profile not made by Adobe is named as compatible with it (as ClayRGB and others do).
DESCRIPTIONS = {"sRGB": SRGB_DESCRIPTION,
                "ECI RGB v2": "eciRGB v2 (ECI, ISO 22028-4; dualrgb matrix/TRC, L* curve)",
                "Adobe RGB (1998)": "Adobe RGB (1998)-compatible (dualrgb matrix/TRC, gamma 563/256)"}


def _s15(v: float) -> bytes:
    return struct.pack(">i", int(round(v * 65536.0)))


def _xyz_tag(xyz: Sequence[float] | np.ndarray) -> bytes:
    return b"XYZ " + b"\0" * 4 + b"".join(_s15(v) for v in xyz)


def _desc_tag(text: str) -> bytes:
    a = text.encode("ascii", "replace") + b"\0"
    return (b"desc" + b"\0" * 4 + struct.pack(">I", len(a)) + a + struct.pack(">II", 0, 0) + struct.pack(">HB", 0, 0)
            + b"\0" * 67)


def _text_tag(text: str) -> bytes:
    return b"text" + b"\0" * 4 + text.encode("ascii", "replace") + b"\0"


def _curv_tag(samples: np.ndarray) -> bytes:
    v = np.round(np.clip(samples, 0, 1) * 65535).astype(">u2")
    return b"curv" + b"\0" * 4 + struct.pack(">I", len(v)) + v.tobytes()


def matrix_trc_icc(space: str, description: str | None = None, n_curve: int = 4096) -> bytes:
    """A minimal ICC v2.4 matrix/TRC RGB display profile for a colour-science RGB colour space."""
    import colour

    cs = _colourspace(space)
    white = colour.xy_to_XYZ(cs.whitepoint)
    M = _bradford(white, ICC_D50) @ cs.matrix_RGB_to_XYZ       # RGB -> XYZ (D50 PCS)
    if space == "Adobe RGB (1998)":
        trc = _gamma_tag(ADOBE_GAMMA)
    else:
        x = np.linspace(0.0, 1.0, n_curve)
        trc = _curv_tag(np.asarray(cs.cctf_decoding(x), dtype=float))
    return _matrix_trc_profile(M, trc, description or f"{space} (dualrgb matrix/TRC)")


def _gamma_tag(gamma: float) -> bytes:
    """A ``curv`` of one entry: a pure power ``gamma`` (u8.8), padded to 4 bytes."""
    return b"curv" + b"\0" * 4 + struct.pack(">IH", 1, int(round(gamma * 256))) + b"\0" * 2


def xyz_icc(white_xyz: Sequence[float]) -> bytes:
    """The ICC v2.4 profile of the linear XYZ master, whose R, G, B are X / Xn, Y / Yn, Z / Zn (``white_xyz``:
    Xn, Yn, Zn) with 65535 = 1: the colorants adapt the white to the D50 PCS (Bradford, relative colorimetric, as
    the display profiles) and the curves are linear (gamma 1.0).

    Why normalised to the white, with no headroom: LittleCMS (2.13 on) keeps a 16-bit transform from a linear
    profile exact only when it recognises the profile as linear - the grey axis (v, v, v) must give Y = v (it
    estimates a gamma from it); otherwise its default path resamples the transform on a 33-point grid, and in
    linear data the first grid cell spans every shadow (a 2x-headroom profile rendered 0.83 mean / 8.4 max dE00
    off; tests/app/test_interop_tools.py). X / Xn, Y / Yn, Z / Zn make (1, 1, 1) the white, whose Y is exactly 1."""
    white = np.asarray(white_xyz, dtype=float)
    M = _bradford(white / white[1], ICC_D50) @ np.diag(white / white[1])
    return _matrix_trc_profile(M, _gamma_tag(1.0), "CIE XYZ / white (X/Xn, Y/Yn, Z/Zn), linear (dualrgb)")


def camera_icc(matrix: np.ndarray, white_xyz: Sequence[float], linear_one: float, description: str) -> bytes:
    """An ICC v2.4 input ('scnr') profile for linear camera R, G, B of one light (``linear_one`` of 65535 = the
    flat field's white): linear curves, colorants ``matrix`` (3, 3) (row c: the XYZ, on the calibration's scale,
    of channel c at 1.0) relative to ``white_xyz`` and adapted to the D50 PCS (Bradford).

    It is an approximation (app.workflow.delivery.camera_profiles says how the 3x3 is fitted): the calibrated colours
    are
    in the XYZ and RGB masters; this only keeps colour-managed software from showing linear camera data as sRGB."""
    white = np.asarray(white_xyz, dtype=float)
    M = _bradford(white / white[1], ICC_D50) @ (np.asarray(matrix, dtype=float).T / white[1])
    return _matrix_trc_profile(M * (65535.0 / float(linear_one)), _gamma_tag(1.0), description, b"scnr")


def _matrix_trc_profile(M: np.ndarray, trc: bytes, description: str, device_class: bytes = b"mntr") -> bytes:
    """An ICC v2.4 RGB matrix/TRC profile (``device_class`` 'mntr' display, 'scnr' input): colorants the columns of
    ``M`` (RGB -> PCS XYZ, D50), one ``trc`` curve. Preferred CMM, platform and device manufacturer are 0 (none:
    what the ICC specification asks for when there is none; SLUB's checkit_tiff refuses anything else that is not
    a registered signature)."""
    tags = [
        (b"desc", _desc_tag(description)),
        (b"cprt", _text_tag("No copyright, use freely")),
        (b"wtpt", _xyz_tag(ICC_D50)),
        (b"rXYZ", _xyz_tag(M[:, 0])),
        (b"gXYZ", _xyz_tag(M[:, 1])),
        (b"bXYZ", _xyz_tag(M[:, 2])),
        (b"rTRC", trc),
        (b"gTRC", trc),
        (b"bTRC", trc),
    ]
    offset = 128 + 4 + 12 * len(tags)
    table = struct.pack(">I", len(tags))
    data = b""
    placed: dict[bytes, int] = {}
    for sig, body in tags:
        if body in placed:                       # the three TRCs share one curve
            table += sig + struct.pack(">II", placed[body], len(body))
            continue
        pad = (-len(data)) % 4
        data += b"\0" * pad
        pos = offset + len(data)
        placed[body] = pos
        table += sig + struct.pack(">II", pos, len(body))
        data += body
    data += b"\0" * ((-len(data)) % 4)
    size = 128 + len(table) + len(data)
    now = output_time()                          # SOURCE_DATE_EPOCH when set: reproducible bytes
    header = (struct.pack(">I", size) + b"\0" * 4 + bytes([2, 0x40, 0, 0]) + device_class + b"RGB " + b"XYZ "
              + struct.pack(">6H", now.year, now.month, now.day, now.hour, now.minute, now.second)
              + b"acsp" + b"\0" * 4 + struct.pack(">I", 0) + b"\0" * 4 + b"\0" * 4 + b"\0" * 8
              + struct.pack(">I", 1)                     # relative colorimetric
              + b"".join(_s15(v) for v in ICC_D50) + b"dRGB" + b"\0" * 16 + b"\0" * 28)
    assert len(header) == 128
    return header + table + data


def icc_profile(space: str) -> bytes:
    """The ICC v2.4 profile embedded for the RGB colour space ``space`` (:func:`matrix_trc_icc`)."""
    return matrix_trc_icc(space, DESCRIPTIONS.get(space))


# ---------------------------------------------------------------- TIFF metadata
MAX_STRIP_BYTES = 8_000_000               # strips of at most 8 MB (a 24 MP master in one 147 MB strip is refused by
                                          # readers that load a strip whole; FADGI and libtiff advise small strips)


@dataclass
class TiffMetadata:
    """What every delivered TIFF carries in its tags: resolution (ppi), Make/Model, DateTime, Software,
    ImageDescription, DocumentName (the original), Copyright, an XMP packet and an EXIF IFD (the capture). Only
    baseline TIFF tags and the registered XMP (700), ICC (34675) and ExifIFD (34665) ones (SLUB's checkit_tiff
    baseline whitelist)."""

    software: str
    description: str = ""
    make: str = ""
    model: str = ""
    ppi: float | None = None
    datetime: str = ""                         # "YYYY:MM:DD HH:MM:SS" (TIFF); default: now
    xmp: bytes = b""
    document_name: str = ""
    copyright: str = ""
    exif: CaptureExif | None = None

    def tags(self) -> list[tuple[int, str, int, str | bytes | int, bool]]:
        """tifffile ``extratags``: DocumentName (269), Make (271), Model (272), Copyright (33432), XMP (700) and the
        EXIF IFD's placeholder (app.processing.exif)."""
        from dualrgb.app.processing.exif import PLACEHOLDER

        out: list[tuple[int, str, int, str | bytes | int, bool]] = []
        for code, text in ((269, self.document_name), (271, self.make), (272, self.model)):
            if text:
                out.append((code, "s", 0, text, True))
        if self.copyright:
            out.append((33432, "s", 0, self.copyright, True))
        if self.xmp:
            out.append((700, "B", len(self.xmp), self.xmp, True))
        if self.exif is not None:
            out.append((PLACEHOLDER, "I", 1, 0, True))
        return out


def tiff_datetime(when: datetime | None = None) -> str:
    return (when or datetime.now()).strftime("%Y:%m:%d %H:%M:%S")


_XML_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]*")
# XML 1.0 Char: tab, LF, CR, U+0020-U+D7FF, U+E000-U+FFFD, U+10000-U+10FFFF (core.metadata refuses these
# and more before anything is captured; this is the last guard, so no packet is ever ill-formed)
_NOT_XML_CHAR = re.compile("[^\t\n\r\u0020-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _xml_text(name: str, value: object) -> str:
    text = str(value)
    bad = _NOT_XML_CHAR.search(text)
    if bad:
        raise ValueError(f"XMP {name}: U+{ord(bad.group()):04X} at character {bad.start() + 1} is not allowed in XML")
    return escape(text)


def _xml_name(name: str) -> str:
    if not _XML_NAME.fullmatch(name):
        raise ValueError(f"XMP property {name!r}: not an XML name")
    return name


@dataclass
class DublinCore:
    """The XMP's Dublin Core and provenance beyond identifier / title / description: creators, rights statement,
    the capture's date, the file's MIME type, and the processing history (xmpMM:History events: action, when,
    softwareAgent, parameters); the IPTC Core credit line and source (``photoshop:Credit``, ``photoshop:Source``)."""

    creator: Sequence[str] = ()
    rights: str = ""
    date: datetime | None = None
    format: str = ""
    history: Sequence[Mapping[str, str]] = ()
    credit: str = ""
    source: str = ""

    def properties(self) -> list[str]:
        props = []
        if self.creator:
            items = "".join(f"<rdf:li>{_xml_text('dc:creator', c)}</rdf:li>" for c in self.creator)
            props.append(f"<dc:creator><rdf:Seq>{items}</rdf:Seq></dc:creator>")
        if self.rights:
            props.append(f'<dc:rights><rdf:Alt><rdf:li xml:lang="x-default">{_xml_text("dc:rights", self.rights)}'
                         '</rdf:li></rdf:Alt></dc:rights>')
        if self.date is not None:
            props.append(f"<dc:date><rdf:Seq><rdf:li>{self.date.isoformat(timespec='seconds')}</rdf:li></rdf:Seq>"
                         "</dc:date>")
        if self.format:
            props.append(f"<dc:format>{_xml_text('dc:format', self.format)}</dc:format>")
        if self.history:
            events = "".join('<rdf:li rdf:parseType="Resource">' + "".join(
                f"<stEvt:{_xml_name(k)}>{_xml_text(k, v)}</stEvt:{k}>" for k, v in ev.items()) + "</rdf:li>"
                for ev in self.history)
            props.append(f"<xmpMM:History><rdf:Seq>{events}</rdf:Seq></xmpMM:History>")
        for key, value in (("Credit", self.credit), ("Source", self.source)):
            if value:
                props.append(f"<photoshop:{key}>{_xml_text(f'photoshop:{key}', value)}</photoshop:{key}>")
        return props


def xmp_packet(fields: Mapping[str, object], *, identifier: str = "", title: str = "", tool: str = "",
               created: datetime | None = None, columns: Mapping[str, str] | None = None,
               description: str = "", dc: DublinCore | None = None) -> bytes:
    """An XMP packet (UTF-8): dc:identifier, dc:title, dc:description, xmp:CreatorTool, xmp:CreateDate, the Dublin
    Core and history of ``dc`` (:class:`DublinCore`) and ``dualrgb:<Key>`` fields.

    ``columns`` (property -> the exact column name it came from) adds a ``dualrgb:ExtraColumns`` bag of
    {``dualrgb:Property``, ``dualrgb:Column``} so the names of a queue CSV's extra columns survive exactly.
    Text that XML 1.0 cannot carry raises ValueError naming the property (the workflow refuses it earlier).
    """
    created = created or output_time()
    props = [f"<xmp:CreateDate>{created.isoformat(timespec='seconds')}</xmp:CreateDate>"]
    if tool:
        props.append(f"<xmp:CreatorTool>{_xml_text('CreatorTool', tool)}</xmp:CreatorTool>")
    if identifier:
        props.append(f"<dc:identifier>{_xml_text('dc:identifier', identifier)}</dc:identifier>")
    if title:
        props.append(f'<dc:title><rdf:Alt><rdf:li xml:lang="x-default">{_xml_text("dc:title", title)}</rdf:li>'
                     '</rdf:Alt></dc:title>')
    if description:
        props.append(f'<dc:description><rdf:Alt><rdf:li xml:lang="x-default">'
                     f'{_xml_text("dc:description", description)}</rdf:li></rdf:Alt></dc:description>')
    props += (dc or DublinCore()).properties()
    for key, value in fields.items():
        if value is not None and value != "":
            props.append(f"<dualrgb:{_xml_name(key)}>{_xml_text(key, value)}</dualrgb:{key}>")
    if columns:
        items = "".join(f'<rdf:li rdf:parseType="Resource"><dualrgb:Property>{_xml_text("Property", prop)}'
                        f'</dualrgb:Property><dualrgb:Column>{_xml_text("Column", col)}</dualrgb:Column></rdf:li>'
                        for prop, col in columns.items())
        props.append(f"<dualrgb:ExtraColumns><rdf:Bag>{items}</rdf:Bag></dualrgb:ExtraColumns>")
    return _xmp_wrap(props)


def _xmp_wrap(props: list[str]) -> bytes:
    body = "\n    ".join(props)
    text = ('<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>\n'
            '<x:xmpmeta xmlns:x="adobe:ns:meta/">\n'
            ' <rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">\n'
            '  <rdf:Description rdf:about="" xmlns:dc="http://purl.org/dc/elements/1.1/"\n'
            '    xmlns:xmp="http://ns.adobe.com/xap/1.0/"\n'
            '    xmlns:xmpMM="http://ns.adobe.com/xap/1.0/mm/"\n'
            '    xmlns:photoshop="http://ns.adobe.com/photoshop/1.0/"\n'
            '    xmlns:stEvt="http://ns.adobe.com/xap/1.0/sType/ResourceEvent#"\n'
            f'    xmlns:dualrgb="{XMP_NAMESPACE}">\n    {body}\n  </rdf:Description>\n </rdf:RDF>\n'
            '</x:xmpmeta>\n<?xpacket end="w"?>')
    return text.encode("utf-8")


def rows_per_strip(shape: tuple[int, ...], itemsize: int) -> int:
    """Rows per strip so that a strip holds at most :data:`MAX_STRIP_BYTES`."""
    row = int(np.prod(shape[1:], dtype=np.int64)) * itemsize
    return max(1, min(int(shape[0]), MAX_STRIP_BYTES // max(row, 1)))


def tiff_kwargs(meta: TiffMetadata, *, photometric: str = "minisblack", icc: bytes | None = None,
                rowsperstrip: int | None = None) -> dict:
    """``tifffile.imwrite`` arguments (all but the data) of an uncompressed TIFF with contiguous samples carrying
    ``meta``, in strips of ``rowsperstrip`` rows: the one place the deliverables' TIFF layout is decided."""
    kwargs: dict = dict(photometric=photometric, planarconfig="contig", iccprofile=icc,
                        description=meta.description or None, software=meta.software,
                        datetime=meta.datetime or tiff_datetime(), extratags=meta.tags(), metadata=None,
                        rowsperstrip=rowsperstrip)
    if meta.ppi:
        kwargs.update(resolution=(float(meta.ppi), float(meta.ppi)), resolutionunit=RESOLUTION_UNIT_INCH)
    return kwargs


def open_tiff(path: Path, shape: tuple[int, ...], meta: TiffMetadata, *, dtype=np.uint16,
              photometric: str = "minisblack", icc: bytes | None = None, band_rows: int = 64, executor=None,
              direct: bool = True, digest: str | None = None, slots: int = 2):
    """A TIFF of ``shape`` to fill band by band (app.processing.tiff_stream.TiffStream, ``slots`` band buffers),
    written atomically (``digest``: also the file's checksum, e.g. "sha256", computed as it is written)."""
    from dualrgb.app.processing.tiff_stream import TiffStream

    strip = rows_per_strip(shape, np.dtype(dtype).itemsize)
    return TiffStream(path, shape, dtype, tiff_kwargs(meta, photometric=photometric, icc=icc, rowsperstrip=strip),
                      band_rows=band_rows, executor=executor, direct=direct, digest=digest,
                      exif=meta.exif.ifd if meta.exif is not None else None, slots=slots)


def write_tiff(path: Path, image: np.ndarray, meta: TiffMetadata, *, photometric: str = "minisblack",
               icc: bytes | None = None, band_rows: int = 256) -> Path:
    """One uncompressed TIFF (contiguous samples) with ``meta`` in its tags, written atomically (temp file,
    fsync, rename) through the streamed writer of the deliverables: byte for byte what ``tifffile.imwrite`` of
    the array writes."""
    image = np.asarray(image)
    with open_tiff(path, image.shape, meta, dtype=image.dtype.newbyteorder("="), photometric=photometric, icc=icc,
                   band_rows=band_rows) as out:
        for r0 in range(0, image.shape[0], out.band_rows):
            rows = min(out.band_rows, image.shape[0] - r0)
            out.band(rows)[...] = image[r0: r0 + rows]
            out.commit()
    return Path(path)


# ---------------------------------------------------------------- CSVs
def _write_csv(path: Path, rows: Sequence[Sequence[object]]) -> Path:
    with atomic_output(Path(path), "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return Path(path)


def write_patch_csv(path: Path, names: Sequence[str], values: np.ndarray, channels: Sequence[str],
                    xyz_ref: np.ndarray, predictions: Mapping[str, np.ndarray], errors: Mapping[str, np.ndarray],
                    *, target: str = "") -> Path:
    """One row per patch: camera values, reference XYZ, predicted XYZ and dE00 per method."""
    head = ["target", "patch"] + list(channels) + ["X_ref", "Y_ref", "Z_ref"]
    for m in predictions:
        head += [f"X_{m}", f"Y_{m}", f"Z_{m}", f"dE00_{m}"]
    rows = [head]
    for i, name in enumerate(names):
        row = [target, name] + [f"{v:.6g}" for v in values[i]] + [f"{v:.6g}" for v in xyz_ref[i]]
        for m in predictions:
            row += [f"{v:.6g}" for v in predictions[m][i]] + [f"{errors[m][i]:.4f}"]
        rows.append(row)
    return _write_csv(path, rows)


def write_matrices_csv(path: Path, matrices: Mapping[str, CharacterisationMatrix]) -> Path:
    """Rows ``method, term, X, Y, Z``: XYZ = sum over the terms of term value * row (a linear model's terms are
    its channels; a root-polynomial's are named like 'sqrt(R1*G2)', simulation.colour_models.term_names)."""
    from dualrgb.simulation.colour_models import term_names

    rows: list[list[object]] = [["method", "channel", "X", "Y", "Z"]]
    for name, m in matrices.items():
        chans = m.channels or [f"ch{i + 1}" for i in range(m.n_channels)]
        terms = term_names(list(chans), m.degree) if m.degree > 1 else chans
        rows += [[name, t, *(f"{v:.10g}" for v in row)] for t, row in zip(terms, m.matrix, strict=True)]
    return _write_csv(path, rows)
