"""The archival files made from an original's stack (what an original is and how its fields are checked:
app.workflow.metadata; where its files go and how a re-delivery keeps the previous set: app.workflow.delivery_folder).

Per original, named from its identifier (``<id>`` below: app.workflow.metadata.file_stem, portable and distinct for
distinct identifiers), in ``<out>/<id>/`` (:func:`deliverable_files` lists them, the one place that does):

* ``<id>_prophoto_16bit.tif`` and ``<id>_srgb_16bit.tif``: display-encoded RGB with the ICC profile embedded;
* ``<id>_XYZ_16bit.tif``: linear CIE XYZ, 32768 = the reference white's Y (2x headroom);
* ``<id>_<N>ch_16bit.tif``: the flat-fielded N-channel stack, 32768 = the white (open gate);
* ``<id>_spectral.img`` + ``<id>_spectral.hdr``: the estimated spectral cube (the calibration's spectral
  estimator per pixel; ENVI, band-interleaved by line, 16-bit, factor x 10000, the wavelengths in the header:
  app.processing.envi), when the calibration has an estimator;
* ``<id>_under_<light>_prophoto_16bit.tif``: the cube rendered under the chosen light (``--render-illuminant``:
  D65 by default, D50, A, FL11, LED), ProPhoto RGB, ICC embedded (app.processing.render);
* ``<id>.json``: the sidecar (format tag and software versions - dualrgb, numpy, numba, colour-science, rawpy,
  LibRaw - from dualrgb.simulation.versions, the original, the calibration, exposures, light dose, QA, the spectral
  deliverables' wavelengths, scale, method and calibration, the files; on the virtual lab the figures against the
  virtual original's truth: app.workflow.virtual_truth).

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
from contextlib import ExitStack, nullcontext
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from dualrgb.app.processing.encode import LINEAR_ONE, DeliveryEncoder
from dualrgb.app.processing.envi import DTYPE, IGNORE_VALUE, INTERLEAVE, SCALE_FACTOR, EnviHeader
from dualrgb.app.processing.outputs import TiffMetadata, icc_profile, open_tiff, tiff_datetime, xmp_packet
from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT, Rendering, rendering
from dualrgb.app.processing.spectral_cube import SpectralEncoder
from dualrgb.app.processing.tiff_stream import RawStream
from dualrgb.app.session.capture_session import atomic_write
from dualrgb.app.workflow.delivery_folder import SIDECAR_FORMAT, read_sidecar, staged
from dualrgb.app.workflow.metadata import MODES, Original, ascii_text, xmp_property
from dualrgb.app.workflow.profile import CalibrationProfile, CameraIdentity
from dualrgb.app.workflow.virtual_truth import OriginalTruth, assess, qa_text
from dualrgb.simulation.spectral_estimation import SpectralEstimator
from dualrgb.simulation.versions import dualrgb_version, output_header

log = logging.getLogger(__name__)

BAND_ROWS = 64          # rows encoded and written at a time: 24 MP dual-RGB, 6 MB over the four TIFFs + 15 MB of cube


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
    spectral_rmse: float | None = None      # the calibration's spectral RMSE on its test target (None: no spectra)
    truth: dict | None = None               # virtual lab: the figures against the original's truth

    def text(self) -> str:
        def de(v: float | None) -> str:
            return "n/a" if v is None else f"{v:.2f}"
        spectral = "" if self.spectral_rmse is None else f", spectral RMSE test {self.spectral_rmse:.3f}"
        return (f"{self.identifier}: clipped {self.clipped_pct:.2f} %, under-exposed {self.underexposed_pct:.2f} %, "
                f"light dose {self.dose.lux_h:.3g} lux.h ({self.dose.lux_s:.3g} lux.s), calibration dE00 train "
                f"{de(self.train_mean)} / test {de(self.test_mean)}{spectral}" + (", HDR" if self.hdr else "")
                + (f"; {qa_text(self.truth)}" if self.truth else "") + "".join(f"; {w}" for w in self.warnings))

    def to_dict(self) -> dict:
        return {"text": self.text(), "clipped_pct": round(self.clipped_pct, 4),
                "underexposed_pct": round(self.underexposed_pct, 4), "invalid_pct": round(self.invalid_pct, 4),
                "light_dose": self.dose.to_dict(), "calibration_train_de00_mean": self.train_mean,
                "calibration_test_de00_mean": self.test_mean, "calibration_test_spectral_rmse": self.spectral_rmse,
                "hdr": self.hdr, "warnings": self.warnings, **({"virtual_truth": self.truth} if self.truth else {})}


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
    rmse = ((profile.spectral.get("test") or {}).get("rmse") or {}).get("mean") if profile.estimator else None
    return QaLine(original.identifier, 100 * clipped, 100 * under, 100 * invalid, dose,
                  (best.get("train") or {}).get("mean"), profile.test_mean, hdr, list(warnings), rmse)


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
    (app.workflow.metadata.ascii_text) without surrounding spaces (a spacing accent such as '¯' transliterates to
    one, and TIFF readers, tifffile among them, strip it); the exact text is in the XMP packet."""
    return ascii_text(original.identifier + (f" - {original.title}" if original.title else "") + f"; {what}").strip()


@dataclass
class Deliverable:
    """One deliverable file: its path, samples per pixel (the cube: wavelengths), TIFF photometric, RGB space
    (display-encoded, its ICC profile embedded; None: linear), what it holds, and what makes it (``stack``: the
    colour encodings of app.processing.encode; ``spectra``: the spectral encoder of app.processing.spectral_cube;
    ``header``: the cube's ENVI header, written last)."""

    path: Path
    samples: int
    photometric: str
    space: str | None
    what: str
    source: str = "stack"


@dataclass
class SpectralPlan:
    """The spectral deliverables of a delivery: the calibration's estimator and the rendering's light."""

    estimator: SpectralEstimator
    rendering: Rendering

    @classmethod
    def of(cls, profile: CalibrationProfile, illuminant: str = DEFAULT_RENDER_ILLUMINANT) -> SpectralPlan | None:
        """The plan for ``profile`` (None: it has no spectral estimator) rendering under ``illuminant``."""
        if profile.estimator is None:
            return None
        est = profile.spectral_estimator()
        return cls(est, rendering(illuminant, est.wavelengths))


def deliverable_files(folder: Path, stem: str, channels: list[str],
                      spectral: SpectralPlan | None = None) -> dict[str, Deliverable]:
    """Every file of an original named ``stem`` with the stack's ``channels`` (and the spectral ones of
    ``spectral``) but the sidecar, by key (the sidecar's)."""
    n = len(channels)
    files = {
        "prophoto": Deliverable(folder / f"{stem}_prophoto_16bit.tif", 3, "rgb", "ProPhoto RGB",
                           "ProPhoto RGB (ROMM), 16-bit, ICC embedded"),
        "srgb": Deliverable(folder / f"{stem}_srgb_16bit.tif", 3, "rgb", "sRGB", "sRGB, 16-bit, ICC embedded"),
        "xyz": Deliverable(folder / f"{stem}_XYZ_16bit.tif", 3, "minisblack", None,
                      f"CIE XYZ (D65, 2 deg), linear, {LINEAR_ONE:g} = reference white Y"),
        "channels": Deliverable(folder / f"{stem}_{n}ch_16bit.tif", n, "minisblack", None,
                           f"{n} camera channels {' '.join(channels)}, flat-fielded, linear, {LINEAR_ONE:g} = white"),
    }
    if spectral is not None:
        est, r = spectral.estimator, spectral.rendering
        files["spectral"] = Deliverable(folder / f"{stem}_spectral.img", est.n_wavelengths, "", None,
                                        f"{est.quantity} x {SCALE_FACTOR:g} at {est.n_wavelengths} wavelengths, ENVI "
                                        f"{INTERLEAVE}, 16-bit", "spectra")
        files["spectral_header"] = Deliverable(folder / f"{stem}_spectral.hdr", 0, "", None,
                                               "ENVI header of the spectral cube", "header")
        files["render"] = Deliverable(folder / f"{stem}_under_{r.illuminant}_prophoto_16bit.tif", 3, "rgb", r.space,
                                      f"rendered under {r.light} from the estimated spectra, {r.space}, 16-bit, "
                                      "ICC embedded", "spectra")
    return files


def _open(im: Deliverable, height: int, width: int, meta: Callable[[str], TiffMetadata], band_rows: int,
          pool: ThreadPoolExecutor, direct: bool):
    if im.source == "spectra" and im.space is None:          # the cube's data: band-interleaved by line
        return RawStream(im.path, (height, im.samples, width), DTYPE, band_rows=band_rows, executor=pool,
                         direct=direct)
    return open_tiff(im.path, (height, width, im.samples), meta(im.what), photometric=im.photometric,
                     icc=icc_profile(im.space) if im.space else None, band_rows=band_rows, executor=pool, direct=direct)


def write_images(stack: ChannelStack, profile: CalibrationProfile, images: dict[str, Deliverable],
                 meta: Callable[[str], TiffMetadata], *, spectral: SpectralPlan | None = None,
                 band_rows: int = BAND_ROWS, direct: bool = True) -> tuple[dict[str, Path], float]:
    """Encode the stack band by band straight into the open files (app.processing.tiff_stream): while one band
    is encoded (both cores, nogil), the writer threads put the previous one on disk; nothing image-sized but
    the stack is held. The spectral cube and its rendering come from the same bands (``spectral``; its header
    is written by :func:`deliver`). Returns the files and the fraction of invalid (NaN) pixels."""
    H, W, _ = stack.data.shape
    streamed = {k: im for k, im in images.items() if im.source != "header"}
    spaces = {k: im.space for k, im in streamed.items() if im.space and im.source == "stack"}
    rgb_keys = list(spaces)
    spec = (SpectralEncoder(stack.data, spectral.estimator.matrix, spectral.estimator.bounds, spectral.rendering,
                            offset=spectral.estimator.offset) if spectral is not None else nullcontext())
    with DeliveryEncoder(stack.data, profile.matrix.matrix, profile.white_xyz, list(spaces.values())) as enc, \
            spec as cube_enc, \
            ThreadPoolExecutor(len(streamed), thread_name_prefix="deliver") as pool, ExitStack() as opened:
        out = {k: opened.enter_context(_open(im, H, W, meta, band_rows, pool, direct)) for k, im in streamed.items()}
        rgb = [out[k] for k in rgb_keys]
        for r0 in range(0, H, band_rows):
            rows = min(band_rows, H - r0)
            enc.encode(r0, out["xyz"].band(rows), [o.band(rows) for o in rgb], out["channels"].band(rows))
            if cube_enc is not None:
                cube_enc.encode(r0, out["spectral"].band(rows), out["render"].band(rows))
            for o in out.values():
                o.commit()
        invalid = enc.invalid_fraction
    return {k: im.path for k, im in streamed.items()}, invalid


def cube_header(spectral: SpectralPlan, original: Original, profile: CalibrationProfile,
                shape: tuple[int, int]) -> EnviHeader:
    """The ENVI header of ``original``'s cube (``shape``: lines, samples)."""
    est = spectral.estimator
    text = (f"dualrgb spectral cube of {original.identifier}" + (f" - {original.title}" if original.title else "")
            + f"; {est.quantity} estimated by {est.method} from {est.n_channels} channels; calibration {profile.id}")
    return EnviHeader(shape[0], shape[1], est.n_wavelengths, [float(w) for w in est.wavelengths], ascii_text(text),
                      extra={"dualrgb identifier": ascii_text(original.identifier), "dualrgb calibration": profile.id,
                             "dualrgb method": est.method, "dualrgb quantity": est.quantity,
                             "dualrgb software": f"dualrgb {dualrgb_version()}"})


def spectral_section(spectral: SpectralPlan, profile: CalibrationProfile, files: dict[str, Path]) -> dict:
    """The sidecar's ``spectral`` section: the cube's format, wavelengths and scale, how it was estimated (method,
    calibration, the calibration's test figures) and the rendering."""
    est = spectral.estimator
    test = profile.spectral.get("test") or {}
    return {"cube": {"data": files["spectral"].name, "header": files["spectral_header"].name, "format": "ENVI",
                     "interleave": INTERLEAVE, "data_type": "uint16", "byte_order": "little-endian",
                     "reflectance_scale_factor": SCALE_FACTOR, "data_ignore_value": IGNORE_VALUE,
                     "quantity": est.quantity, "bands": est.n_wavelengths,
                     "wavelengths_nm": [float(w) for w in est.wavelengths]},
            "estimator": {"method": est.method, "settings": est.settings, "channels": list(est.channels),
                          "calibration": profile.id,
                          "calibration_test": {"rmse_mean": (test.get("rmse") or {}).get("mean"),
                                               "rmse_p90": (test.get("rmse") or {}).get("p90"),
                                               "gfc_mean": (test.get("gfc") or {}).get("mean"),
                                               "de00_mean": {k: v.get("mean") for k, v in
                                                             (test.get("de00") or {}).items()}}},
            "rendering": {**spectral.rendering.describe(), "file": files["render"].name}}


def deliver(stack: ChannelStack, profile: CalibrationProfile, original: Original, out_dir: Path, *,
            camera: CameraIdentity, dose: LightDoseRecord, ppi: float | None = None,
            exposures: dict[str, list[float]] | None = None, warnings: list[str] | None = None,
            extra: dict | None = None, render_illuminant: str = DEFAULT_RENDER_ILLUMINANT,
            truth: OriginalTruth | None = None) -> Delivery:
    """Encode the stack with the calibration's matrix (and spectral estimator: the cube and its rendering under
    ``render_illuminant``) and write every deliverable of ``original``: into a fresh folder, swapped in whole when
    complete (a re-delivery keeps the previous set in ``<stem>/previous/``; a folder of another original is
    refused: app.workflow.delivery_folder). ``truth``: the virtual lab's, compared in the sidecar and QA line."""
    warnings = list(warnings or [])
    ppi = ppi or profile.ppi
    if not ppi:
        warnings.append("no resolution: set the sampling (ppi) or calibrate with the target's size")
    spectral = SpectralPlan.of(profile, render_illuminant)
    if spectral is None:
        warnings.append(f"no spectral cube: calibration {profile.id} has no spectral estimator (calibrate again)")
    now = datetime.now(UTC)
    stem = original.file_stem
    final = Path(out_dir) / stem
    with staged(Path(out_dir), original) as folder:
        images = deliverable_files(folder, stem, stack.channels, spectral)
        written, invalid = write_images(stack, profile, images,
                                        lambda what: _tiff_meta(original, profile, camera, dose, ppi, what, now),
                                        spectral=spectral)
        if spectral is not None:
            header = images["spectral_header"].path
            cube_header(spectral, original, profile, stack.data.shape[:2]).write(header)
            written["spectral_header"] = header
        qa = _qa(stack, invalid, profile, original, dose, any(len(v) > 1 for v in (exposures or {}).values()),
                 warnings)
        qa.truth = assess(truth, written, float(profile.white_xyz[1])) if truth is not None else None
        doc = _sidecar(stack, profile, original, camera, now, ppi, exposures, dose, qa, written, spectral)
        atomic_write(folder / f"{stem}.json",
                     (json.dumps({**doc, **(extra or {})}, indent=2, ensure_ascii=False, default=str) + "\n"
                      ).encode("utf-8"))
    log.info("delivered %s: %s", original.identifier, qa.text())
    return Delivery(original, {k: final / p.name for k, p in written.items()}, final / f"{stem}.json", qa)


def _sidecar(stack: ChannelStack, profile: CalibrationProfile, original: Original, camera: CameraIdentity,
             now: datetime, ppi: float | None, exposures: dict[str, list[float]] | None, dose: LightDoseRecord,
             qa: QaLine, written: dict[str, Path], spectral: SpectralPlan | None) -> dict:
    return {**output_header(SIDECAR_FORMAT), "created_at": now.isoformat(timespec="seconds"),
            "original": original.to_dict(), "file_stem": original.file_stem,
            "calibration": {"id": profile.id, "file": str(profile.path or ""), "created_at": profile.created_at,
                            "matrix": profile.matrix.method, "test_de00_mean": profile.test_mean},
            "camera": asdict(camera), "ppi": ppi, "exposures": exposures or {}, "light_dose": dose.to_dict(),
            "qa": qa.to_dict(), "encoding": {"rgb": "display-encoded, white = 65535", "linear_one": LINEAR_ONE,
                                             "channels": stack.channels},
            **({"spectral": spectral_section(spectral, profile, written)} if spectral is not None else {}),
            **({"virtual_truth": qa.truth} if qa.truth else {}),
            "files": {k: p.name for k, p in written.items()}}


__all__ = ["BAND_ROWS", "MODES", "SIDECAR_FORMAT", "Deliverable", "Delivery", "LightDoseRecord", "Original", "QaLine",
           "SpectralPlan", "deliver", "deliverable_files", "image_description", "read_sidecar", "write_images"]
