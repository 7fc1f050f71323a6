"""What each delivered TIFF says about itself: tags, XMP, EXIF and ICC profile (app.processing.outputs writes them).

* TIFF tags (baseline and registered only, as SLUB's checkit_tiff baseline whitelist allows): ImageDescription
  (what the file holds, 7-bit ASCII), DocumentName (the original), Make / Model, Software, DateTime (when the file
  was made), Copyright (the rights, as the XMP's), resolution;
* EXIF IFD (app.processing.exif): exposure time, f-number, ISO, capture time with its UTC offset, focal length,
  body serial, lens, colour space;
* XMP: Dublin Core identifier, title, description (the exact Unicode), creator and rights (the original's
  collection preset's, else the delivery settings'), IPTC credit line and source (the preset's), date (the
  capture), format (MIME type); ``xmpMM:History`` (captured by the camera, converted by dualrgb with the
  calibration); ``dualrgb:`` fields (operator, calibration id, lights, exposures, light dose, the
  queue's extra columns by their exact names);
* ICC: the space's matrix/TRC profile, the XYZ one, or the camera-RGB one (app.workflow.delivery.camera_profiles).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from datetime import datetime

from dualrgb.app.processing.exif import COLOUR_SPACE_SRGB, COLOUR_SPACE_UNCALIBRATED, CaptureExif, focal_length_mm
from dualrgb.app.processing.outputs import DublinCore, TiffMetadata, icc_profile, tiff_datetime, xmp_packet, xyz_icc
from dualrgb.app.workflow.calibration.profile import CameraIdentity
from dualrgb.app.workflow.delivery.deliverables import Deliverable
from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings
from dualrgb.core.metadata import Original, ascii_text, xmp_property
from dualrgb.simulation.versions import dualrgb_version

log = logging.getLogger(__name__)

MIME = {".tif": "image/tiff", ".jp2": "image/jp2"}


def _figure(lux_s: float | None, per: float) -> str:
    """A dose figure for the XMP, empty (the field left out) where the dose was not recorded: never a zero dose."""
    return "" if lux_s is None else f"{lux_s / per:.6g}"


def exact_description(original: Original, what: str) -> str:
    """``<identifier> - <title>; <what>`` exactly (the XMP's dc:description)."""
    return original.identifier + (f" - {original.title}" if original.title else "") + f"; {what}"


def image_description(original: Original, what: str) -> str:
    """TIFF ImageDescription (7-bit ASCII): :func:`exact_description` transliterated
    (core.metadata.ascii_text) without surrounding spaces (a spacing accent such as '¯' transliterates to
    one, and TIFF readers, tifffile among them, strip it); the exact text is in the XMP packet."""
    return ascii_text(exact_description(original, what)).strip()


@dataclass
class MasterContext:
    """What one original's files say about it and its capture (one per delivery)."""

    original: Original
    calibration_id: str
    camera: CameraIdentity
    dose_lux_s: float | None                      # None: not recorded (another program shot the frames)
    ppi: float | None
    now: datetime                                 # when the files are made (aware)
    captured: datetime                            # when the original was captured (aware)
    exposures: dict[str, list[float]] = field(default_factory=dict)    # light name -> seconds
    lights: list[str] = field(default_factory=list)
    settings: DeliverySettings = field(default_factory=DeliverySettings)
    processing: str = ""                          # the conversion's parameters (calibration, matrix, demosaic)
    white_xyz: list[float] = field(default_factory=list)
    profile: object = None                        # the calibration (camera-RGB profiles); None: not available

    def exposure(self, im: Deliverable) -> float | None:
        """The file's exposure time: its light's shortest (base) exposure; the first light's for the others."""
        name = im.light_name if im.kind == "channels" else (self.lights[0] if self.lights else "")
        times = self.exposures.get(name) or next(iter(self.exposures.values()), [])
        return min(times) if times else None

    @property
    def rights(self) -> str:
        """The rights statement: the original's collection preset's, else the delivery settings' (XMP dc:rights,
        TIFF Copyright)."""
        return self.original.credits.rights or self.settings.rights

    def exif(self, im: Deliverable) -> CaptureExif:
        cam = self.camera
        return CaptureExif(self.captured, self.exposure(im), cam.aperture, cam.iso, focal_length_mm(cam.lens),
                           ascii_text(cam.serial), ascii_text(cam.lens),
                           COLOUR_SPACE_SRGB if im.space == "sRGB" else COLOUR_SPACE_UNCALIBRATED)

    def history(self) -> list[dict[str, str]]:
        lights = "; ".join(f"{n}: {', '.join(f'{t:g} s' for t in self.exposures.get(n, []))}" for n in self.lights)
        return [{"action": "created", "when": self.captured.isoformat(timespec="seconds"),
                 "softwareAgent": self.camera.model or "camera", "parameters": f"raw frames; {lights}"},
                {"action": "converted", "when": self.now.isoformat(timespec="seconds"),
                 "softwareAgent": f"dualrgb {dualrgb_version()}", "parameters": self.processing}]

    def xmp(self, im: Deliverable) -> bytes:
        o = self.original
        extra = {xmp_property(name): value for name, value in o.extra.items()}
        credits = o.credits
        dc = DublinCore(credits.creator or self.settings.creator, self.rights, self.captured,
                        MIME.get(im.path.suffix.lower(), "image/tiff"), self.history(), credits.credit,
                        credits.source)
        fields = {"Operator": o.operator, "CalibrationID": self.calibration_id, "Mode": o.mode,
                  "Lights": "; ".join(self.lights), "LightDoseLuxHours": _figure(self.dose_lux_s, 3600.0),
                  "LightDoseLuxSeconds": _figure(self.dose_lux_s, 1.0), "Content": im.what, "Notes": o.notes, **extra}
        software = f"dualrgb {dualrgb_version()}"
        return xmp_packet(fields, identifier=o.identifier, title=o.title, tool=software, created=self.now,
                          columns={xmp_property(name): name for name in o.extra},
                          description=exact_description(o, im.what), dc=dc)

    def meta(self, im: Deliverable) -> TiffMetadata:
        """The tags, XMP and EXIF of deliverable ``im``."""
        make, _, model = (self.camera.model or "").partition(" ")
        o = self.original
        return TiffMetadata(f"dualrgb {dualrgb_version()}", image_description(o, im.what),
                            ascii_text(make or self.camera.model), ascii_text(model or self.camera.model), self.ppi,
                            tiff_datetime(self.now.astimezone()), self.xmp(im),
                            ascii_text(o.identifier + (f" - {o.title}" if o.title else "")).strip(),
                            ascii_text(self.rights).strip(), self.exif(im))

    def icc(self, im: Deliverable) -> bytes | None:
        """The ICC profile ``im`` embeds (None: it has none)."""
        if im.icc == "XYZ":
            return xyz_icc(self.white_xyz)
        if im.icc == "camera":
            if self.profile is None:
                raise ValueError(f"{im.path.name}: the camera-RGB profile needs the calibration")
            from dualrgb.app.workflow.delivery.camera_profiles import camera_rgb_icc

            return camera_rgb_icc(self.profile, im.light, im.light_name or f"light {im.light + 1}")
        return icc_profile(im.icc) if im.icc else None
