"""The archival files made from an original's stack (what an original is and how its fields are checked:
app.workflow.metadata; where its files go and how a re-delivery keeps the previous set: app.workflow.delivery_folder).

Per original, named from its identifier (``<id>`` below: app.workflow.metadata.file_stem, portable and distinct for
distinct identifiers), in ``<out>/<id>/`` (:func:`deliverable_files` lists them, the one place that does):

* ``<id>_prophoto_16bit.tif`` and ``<id>_srgb_16bit.tif``: display-encoded RGB with the ICC profile embedded;
* ``<id>_XYZ_16bit.tif``: linear CIE XYZ, 32768 = the reference white's Y (2x headroom);
* ``<id>_<N>ch_16bit.tif``: the flat-fielded N-channel stack, 32768 = the white (open gate);
* ``<id>.json``: the sidecar (format tag and software versions - dualrgb, numpy, numba, colour-science, rawpy,
  LibRaw - from simulation.versions, the original, the calibration, exposures, light dose, QA, the files).

Every TIFF carries resolution (ppi), Make/Model, DateTime, Software with the dualrgb version, an
ImageDescription and XMP (identifier, title, operator, notes, extra fields, calibration id, light dose); see
app.processing.outputs. Text policy: the XMP packet (UTF-8) and the sidecar (UTF-8 JSON) carry every field exactly
as normalised; TIFF's ASCII tags (ImageDescription, Make, Model) carry app.workflow.metadata.ascii_text of it.
"""
from __future__ import annotations

import json
import logging
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from app.processing.encode import LINEAR_ONE, DeliveryEncoder
from app.processing.outputs import TiffMetadata, icc_profile, open_tiff, tiff_datetime, xmp_packet
from app.processing.pipeline import ChannelStack
from app.session.capture_session import atomic_write
from app.workflow.delivery_folder import SIDECAR_FORMAT, read_sidecar, staged
from app.workflow.metadata import MODES, Original, ascii_text, xmp_property
from app.workflow.profile import CalibrationProfile, CameraIdentity
from simulation.versions import dualrgb_version, output_header

log = logging.getLogger(__name__)

BAND_ROWS = 256         # rows encoded and written at a time: 24 MP dual-RGB, 23 MB over the four files (128-512 alike)


@dataclass
class LightDoseRecord:
    """The light an original received while it was captured (metering included)."""

    lux_s: float = 0.0
    on_s: float = 0.0

    @property
    def lux_h(self) -> float:
        return self.lux_s / 3600.0

    def to_dict(self) -> dict:
        return {"lux_s": round(self.lux_s, 4), "lux_h": round(self.lux_h, 8), "on_s": round(self.on_s, 4)}


@dataclass
class QaLine:
    identifier: str
    clipped_pct: float
    underexposed_pct: float
    invalid_pct: float
    dose: LightDoseRecord
    train_mean: float | None
    test_mean: float | None
    hdr: bool = False
    warnings: list[str] = field(default_factory=list)

    def text(self) -> str:
        def de(v: float | None) -> str:
            return "n/a" if v is None else f"{v:.2f}"
        return (f"{self.identifier}: clipped {self.clipped_pct:.2f} %, under-exposed {self.underexposed_pct:.2f} %, "
                f"light dose {self.dose.lux_h:.3g} lux.h ({self.dose.lux_s:.3g} lux.s), calibration dE00 train "
                f"{de(self.train_mean)} / test {de(self.test_mean)}" + (", HDR" if self.hdr else "")
                + "".join(f"; {w}" for w in self.warnings))

    def to_dict(self) -> dict:
        return {"text": self.text(), "clipped_pct": round(self.clipped_pct, 4),
                "underexposed_pct": round(self.underexposed_pct, 4), "invalid_pct": round(self.invalid_pct, 4),
                "light_dose": self.dose.to_dict(), "calibration_train_de00_mean": self.train_mean,
                "calibration_test_de00_mean": self.test_mean, "hdr": self.hdr, "warnings": self.warnings}


@dataclass
class Delivery:
    original: Original
    files: dict[str, Path]
    sidecar: Path
    qa: QaLine


def _qa(stack: ChannelStack, invalid: float, profile: CalibrationProfile, original: Original,
        dose: LightDoseRecord, hdr: bool, warnings: list[str]) -> QaLine:
    best = profile.statistics.get("methods", {}).get(profile.statistics.get("best", ""), {})
    clipped = max(stack.clipped_fraction.values(), default=0.0)
    under = stack.underexposed_fraction
    return QaLine(original.identifier, 100 * clipped, 100 * under, 100 * invalid, dose,
                  (best.get("train") or {}).get("mean"), profile.test_mean, hdr, list(warnings))


def _tiff_meta(original: Original, profile: CalibrationProfile, camera: CameraIdentity, dose: LightDoseRecord,
               ppi: float | None, what: str, now: datetime) -> TiffMetadata:
    software = f"dualrgb {dualrgb_version()}"
    extra = {xmp_property(name): value for name, value in original.extra.items()}
    xmp = xmp_packet({"Operator": original.operator, "CalibrationID": profile.id, "Mode": original.mode,
                      "LightDoseLuxHours": f"{dose.lux_h:.6g}", "LightDoseLuxSeconds": f"{dose.lux_s:.6g}",
                      "Content": what, "Notes": original.notes, **extra},
                     identifier=original.identifier, title=original.title, tool=software, created=now,
                     columns={xmp_property(name): name for name in original.extra})
    make, _, model = (camera.model or "").partition(" ")
    return TiffMetadata(software, image_description(original, what), ascii_text(make or camera.model),
                        ascii_text(model or camera.model), ppi, tiff_datetime(now.astimezone()), xmp)


def image_description(original: Original, what: str) -> str:
    """TIFF ImageDescription (7-bit ASCII): ``<identifier> - <title>; <what>`` transliterated
    (app.workflow.metadata.ascii_text); the exact text is in the XMP packet."""
    return ascii_text(original.identifier + (f" - {original.title}" if original.title else "") + f"; {what}")


@dataclass
class Deliverable:
    """One deliverable TIFF: its file, samples per pixel, TIFF photometric, RGB space (display-encoded, its ICC
    profile embedded; None: linear) and what it holds."""

    path: Path
    samples: int
    photometric: str
    space: str | None
    what: str


def deliverable_files(folder: Path, stem: str, channels: list[str]) -> dict[str, Deliverable]:
    """The four TIFFs of an original named ``stem`` with the stack's ``channels``, by key (the sidecar's)."""
    n = len(channels)
    return {
        "prophoto": Deliverable(folder / f"{stem}_prophoto_16bit.tif", 3, "rgb", "ProPhoto RGB",
                           "ProPhoto RGB (ROMM), 16-bit, ICC embedded"),
        "srgb": Deliverable(folder / f"{stem}_srgb_16bit.tif", 3, "rgb", "sRGB", "sRGB, 16-bit, ICC embedded"),
        "xyz": Deliverable(folder / f"{stem}_XYZ_16bit.tif", 3, "minisblack", None,
                      f"CIE XYZ (D65, 2 deg), linear, {LINEAR_ONE:g} = reference white Y"),
        "channels": Deliverable(folder / f"{stem}_{n}ch_16bit.tif", n, "minisblack", None,
                           f"{n} camera channels {' '.join(channels)}, flat-fielded, linear, {LINEAR_ONE:g} = white"),
    }


def write_images(stack: ChannelStack, profile: CalibrationProfile, images: dict[str, Deliverable],
                 meta: Callable[[str], TiffMetadata], *, band_rows: int = BAND_ROWS,
                 direct: bool = True) -> tuple[dict[str, Path], float]:
    """Encode the stack band by band straight into the open TIFFs (app.processing.tiff_stream): while one band
    is encoded (both cores, nogil), the writer threads put the previous one on disk; nothing image-sized but
    the stack is held. Returns the files and the fraction of invalid (NaN) pixels."""
    H, W, _ = stack.data.shape
    rgb_keys = [k for k, im in images.items() if im.space]
    with DeliveryEncoder(stack.data, profile.matrix.matrix, profile.white_xyz,
                         [images[k].space for k in rgb_keys]) as enc, \
            ThreadPoolExecutor(len(images), thread_name_prefix="deliver") as pool, ExitStack() as opened:
        out = {k: opened.enter_context(open_tiff(im.path, (H, W, im.samples), meta(im.what), photometric=im.photometric,
                                                 icc=icc_profile(im.space) if im.space else None,
                                                 band_rows=band_rows, executor=pool, direct=direct))
               for k, im in images.items()}
        rgb = [out[k] for k in rgb_keys]
        for r0 in range(0, H, band_rows):
            rows = min(band_rows, H - r0)
            enc.encode(r0, out["xyz"].band(rows), [o.band(rows) for o in rgb], out["channels"].band(rows))
            for o in out.values():
                o.commit()
        invalid = enc.invalid_fraction
    return {k: im.path for k, im in images.items()}, invalid


def deliver(stack: ChannelStack, profile: CalibrationProfile, original: Original, out_dir: Path, *,
            camera: CameraIdentity, dose: LightDoseRecord, ppi: float | None = None,
            exposures: dict[str, list[float]] | None = None, warnings: list[str] | None = None,
            extra: dict | None = None) -> Delivery:
    """Encode the stack with the calibration's matrix and write every deliverable of ``original``: into a fresh
    folder, swapped in whole when complete (a re-delivery keeps the previous set in ``<stem>/previous/``; a folder
    of another original is refused: app.workflow.delivery_folder)."""
    warnings = list(warnings or [])
    ppi = ppi or profile.ppi
    if not ppi:
        warnings.append("no resolution: set the sampling (ppi) or calibrate with the target's size")
    now = datetime.now(timezone.utc)
    stem = original.file_stem
    final = Path(out_dir) / stem
    with staged(Path(out_dir), original) as folder:
        written, invalid = write_images(stack, profile, deliverable_files(folder, stem, stack.channels),
                                        lambda what: _tiff_meta(original, profile, camera, dose, ppi, what, now))
        qa = _qa(stack, invalid, profile, original, dose, any(len(v) > 1 for v in (exposures or {}).values()),
                 warnings)
        doc = {**output_header(SIDECAR_FORMAT), "created_at": now.isoformat(timespec="seconds"),
               "original": original.to_dict(), "file_stem": stem,
               "calibration": {"id": profile.id, "file": str(profile.path or ""), "created_at": profile.created_at,
                               "matrix": profile.matrix.method, "test_de00_mean": profile.test_mean},
               "camera": asdict(camera), "ppi": ppi, "exposures": exposures or {}, "light_dose": dose.to_dict(),
               "qa": qa.to_dict(), "encoding": {"rgb": "display-encoded, white = 65535",
                                                "linear_one": LINEAR_ONE, "channels": stack.channels},
               "files": {k: p.name for k, p in written.items()}, **(extra or {})}
        atomic_write(folder / f"{stem}.json",
                     (json.dumps(doc, indent=2, ensure_ascii=False, default=str) + "\n").encode("utf-8"))
    log.info("delivered %s: %s", original.identifier, qa.text())
    return Delivery(original, {k: final / p.name for k, p in written.items()}, final / f"{stem}.json", qa)


__all__ = ["BAND_ROWS", "MODES", "SIDECAR_FORMAT", "Deliverable", "Delivery", "LightDoseRecord", "Original", "QaLine",
           "deliver", "deliverable_files", "image_description", "read_sidecar", "write_images"]
