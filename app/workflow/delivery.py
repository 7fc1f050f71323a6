"""The archival files made from an original's channels (what an original is and how its fields are checked:
app.workflow.metadata; where its files go and how a re-delivery keeps the previous set: app.workflow.delivery_folder;
which files, their layout and their size: app.workflow.deliverables).

An original is delivered at the sensor's full resolution (the default: each light's exposures merged,
flat-fielded and demosaiced, app.processing.masters) or at half resolution (one pixel per 2x2 Bayer cell, no
interpolation: app.processing.pipeline.ChannelStack); either way the channels come one row band at a time and
every file is written while the next band is encoded (:func:`write_images`). The sidecar ``<id>.json`` holds the
format tag and software versions (dualrgb, numpy, numba, colour-science, rawpy, LibRaw: dualrgb.simulation.versions),
the original, the calibration, the resolution and demosaic, exposures, light dose, QA, the spectral estimate and
the map that makes the cube from the channel files (app.processing.cube_map), the files, and their fixity (size and
SHA-256 of every deliverable, computed as it is written: ``dualrgb verify`` checks them, app.workflow.fixity). Its
JSON Schema is resources/schemas/dualrgb-delivery-1.schema.json.

Every TIFF carries resolution (ppi), Make/Model, DateTime, Software with the dualrgb version, an
ImageDescription, a PageName and XMP (identifier, title, description, operator, notes, extra fields, calibration
id, light dose); see app.processing.outputs. Text policy: the XMP packet (UTF-8) and the sidecar (UTF-8 JSON) carry
every field exactly as normalised (the XMP's ``dc:description`` the exact text of the ImageDescription); TIFF's
ASCII tags (ImageDescription, Make, Model, PageName) carry app.workflow.metadata.ascii_text of it.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, nullcontext
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from dualrgb.app.json_output import dumps
from dualrgb.app.processing.cube_map import spectral_map
from dualrgb.app.processing.demosaic import DEMOSAIC, HALO
from dualrgb.app.processing.encode import LINEAR_ONE, DeliveryEncoder
from dualrgb.app.processing.envi import DTYPE, IGNORE_VALUE, INTERLEAVE, SCALE_FACTOR, EnviHeader
from dualrgb.app.processing.masters import FULL, MasterStack
from dualrgb.app.processing.outputs import (
    TiffMetadata,
    icc_profile,
    open_tiff,
    tiff_datetime,
    xmp_packet,
    xyz_icc,
)
from dualrgb.app.processing.pipeline import ChannelSource
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT
from dualrgb.app.processing.spectral_cube import SpectralEncoder
from dualrgb.app.processing.tiff_stream import RawStream, TiffStream
from dualrgb.app.session.capture_session import atomic_write
from dualrgb.app.workflow.deliverables import CUBE_FILE, Deliverable, SpectralPlan, deliverable_files
from dualrgb.app.workflow.delivery_folder import SIDECAR_FORMAT, read_sidecar, staged
from dualrgb.app.workflow.fixity import FIXITY_ALGORITHM, file_fixity, fixity_section
from dualrgb.app.workflow.metadata import MODES, Original, ascii_text, xmp_property
from dualrgb.app.workflow.profile import CalibrationProfile, CameraIdentity
from dualrgb.common.progress import CancelToken, check
from dualrgb.simulation.versions import dualrgb_version, output_header

log = logging.getLogger(__name__)

BAND_ROWS = 64          # rows encoded and written at a time: 24 MP full resolution, 23 MB over the five TIFFs


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
    overrides: list[str] = field(default_factory=list)   # rules the user overrode (--force), said first

    def text(self) -> str:
        def de(v: float | None) -> str:
            return "n/a" if v is None else f"{v:.2f}"
        spectral = "" if self.spectral_rmse is None else f", spectral RMSE test {self.spectral_rmse:.3f}"
        forced = "".join(f"OVERRIDE: {o}; " for o in self.overrides)
        return (f"{self.identifier}: {forced}clipped {self.clipped_pct:.2f} %, under-exposed "
                f"{self.underexposed_pct:.2f} %, light dose {self.dose.lux_h:.3g} lux.h ({self.dose.lux_s:.3g} "
                f"lux.s), calibration dE00 train "
                f"{de(self.train_mean)} / test {de(self.test_mean)}{spectral}" + (", HDR" if self.hdr else "")
                + "".join(f"; {w}" for w in self.warnings))

    def to_dict(self) -> dict:
        return {"text": self.text(), "clipped_pct": round(self.clipped_pct, 4),
                "underexposed_pct": round(self.underexposed_pct, 4), "invalid_pct": round(self.invalid_pct, 4),
                "light_dose": self.dose.to_dict(), "calibration_train_de00_mean": self.train_mean,
                "calibration_test_de00_mean": self.test_mean, "calibration_test_spectral_rmse": self.spectral_rmse,
                "hdr": self.hdr, "warnings": self.warnings, "overrides": self.overrides}


@dataclass
class Delivery:
    original: Original
    files: dict[str, Path]
    sidecar: Path
    qa: QaLine


def _qa(stack: ChannelSource, invalid: float, profile: CalibrationProfile, original: Original,
        dose: LightDoseRecord, hdr: bool, warnings: list[str]) -> QaLine:
    best = profile.statistics.get("methods", {}).get(profile.statistics.get("best", ""), {})
    clipped = max(stack.clipped_fraction.values(), default=0.0)
    under = stack.underexposed_fraction
    rmse = ((profile.spectral.get("test") or {}).get("rmse") or {}).get("mean") if profile.estimator else None
    return QaLine(original.identifier, 100 * clipped, 100 * under, 100 * invalid, dose,
                  (best.get("train") or {}).get("mean"), profile.test_mean, hdr, list(warnings), rmse)


def tiff_meta(original: Original, calibration_id: str, camera: CameraIdentity, dose: LightDoseRecord,
              ppi: float | None, what: str, now: datetime, page_name: str = "") -> TiffMetadata:
    """The tags and XMP of one of ``original``'s TIFFs holding ``what`` (app.processing.outputs.TiffMetadata)."""
    software = f"dualrgb {dualrgb_version()}"
    extra = {xmp_property(name): value for name, value in original.extra.items()}
    xmp = xmp_packet({"Operator": original.operator, "CalibrationID": calibration_id, "Mode": original.mode,
                      "LightDoseLuxHours": f"{dose.lux_h:.6g}", "LightDoseLuxSeconds": f"{dose.lux_s:.6g}",
                      "Content": what, "Notes": original.notes, **extra},
                     identifier=original.identifier, title=original.title, tool=software, created=now,
                     columns={xmp_property(name): name for name in original.extra},
                     description=exact_description(original, what))
    make, _, model = (camera.model or "").partition(" ")
    return TiffMetadata(software, image_description(original, what), ascii_text(make or camera.model),
                        ascii_text(model or camera.model), ppi, tiff_datetime(now.astimezone()), xmp,
                        ascii_text(page_name).strip())


def exact_description(original: Original, what: str) -> str:
    """``<identifier> - <title>; <what>`` exactly (the XMP's dc:description)."""
    return original.identifier + (f" - {original.title}" if original.title else "") + f"; {what}"


def image_description(original: Original, what: str) -> str:
    """TIFF ImageDescription (7-bit ASCII): :func:`exact_description` transliterated
    (app.workflow.metadata.ascii_text) without surrounding spaces (a spacing accent such as '¯' transliterates to
    one, and TIFF readers, tifffile among them, strip it); the exact text is in the XMP packet."""
    return ascii_text(exact_description(original, what)).strip()


def delivered_ppi(profile: CalibrationProfile, resolution: str) -> float | None:
    """The deliverables' sampling from the calibration (None: unknown): the profile's ppi is the sensor's (full
    resolution; profiles made before full-resolution masters stated the half-resolution grid's, ``raw.ppi_grid``
    absent), half resolution has half of it."""
    if not profile.ppi:
        return None
    sensor = float(profile.ppi) * (1.0 if profile.raw.get("ppi_grid") == "sensor" else 2.0)
    return sensor if resolution == FULL else sensor / 2.0


@dataclass
class Written:
    """What :func:`write_images` wrote: the files by key, each file's size and SHA-256, the invalid fraction."""

    files: dict[str, Path]
    fixity: dict[str, dict]
    invalid: float


def _icc(im: Deliverable, white_xyz: list[float]) -> bytes | None:
    if im.icc == "XYZ":
        return xyz_icc(white_xyz, LINEAR_ONE)
    return icc_profile(im.icc) if im.icc else None


def open_deliverable(im: Deliverable, height: int, width: int, meta: Callable[[str, str], TiffMetadata],
                     band_rows: int, pool: ThreadPoolExecutor | None, direct: bool, white_xyz: list[float]
                     ) -> TiffStream:
    """The streamed file of deliverable ``im`` (its SHA-256 computed as it is written)."""
    if im.kind == "cube":                                     # the cube's data: band-interleaved by line
        return RawStream(im.path, (height, im.samples, width), DTYPE, band_rows=band_rows, executor=pool,
                         direct=direct, digest=FIXITY_ALGORITHM)
    return open_tiff(im.path, (height, width, im.samples), meta(im.what, im.page_name), photometric=im.photometric,
                     icc=_icc(im, white_xyz), band_rows=band_rows, executor=pool, direct=direct,
                     digest=FIXITY_ALGORITHM)


def write_images(source: ChannelSource, profile: CalibrationProfile, images: dict[str, Deliverable],
                 meta: Callable[[str, str], TiffMetadata], *, spectral: SpectralPlan | None = None,
                 band_rows: int = BAND_ROWS, direct: bool = True, cancel: CancelToken | None = None) -> Written:
    """Encode the channels band by band straight into the open files (app.processing.tiff_stream): while one band
    is encoded (both cores, nogil), the writer threads put the previous one on disk and add it to the file's
    SHA-256; nothing image-sized is held but what ``source`` holds. The spectral cube (when it is a file) and the
    rendering come from the same bands (``spectral``; the cube's header is written by :func:`deliver`); ``cancel``
    is checked before every band (common.progress.Cancelled: nothing is delivered). A matrix or
    white point that is not finite, or images that come out blank, are refused (:class:`DeliveryQaError`)."""
    H, W = source.shape
    N = len(source.channels)
    if not (np.isfinite(profile.matrix.matrix).all() and np.isfinite(profile.white_xyz).all()):
        raise DeliveryQaError(f"QA refused the delivery: no pixel is a finite number (calibration {profile.id} has "
                              "a matrix or white point that is not finite); nothing was delivered, the raw frames "
                              "are kept in the session")
    streamed = {k: im for k, im in images.items() if im.kind != "cube_header"}
    rgb_keys = [k for k, im in streamed.items() if im.kind == "rgb"]
    ch_keys = sorted((k for k, im in streamed.items() if im.kind == "channels"), key=lambda k: streamed[k].light)
    est = spectral.estimator if spectral is not None and "spectral" in streamed else None
    spec = (SpectralEncoder((H, W, N), est.matrix, est.bounds, spectral.rendering, offset=est.offset)
            if spectral is not None and est is not None else nullcontext())
    with DeliveryEncoder((H, W, N), profile.matrix.matrix, profile.white_xyz,
                         [images[k].space or "" for k in rgb_keys]) as enc, spec as cube_enc, \
            ThreadPoolExecutor(len(streamed), thread_name_prefix="deliver") as pool, ExitStack() as opened:
        out = {k: opened.enter_context(open_deliverable(im, H, W, meta, band_rows, pool, direct, profile.white_xyz))
               for k, im in streamed.items()}
        rgb, chans = [out[k] for k in rgb_keys], [out[k] for k in ch_keys]
        for r0 in range(0, H, band_rows):
            check(cancel)
            rows = min(band_rows, H - r0)
            bands = (out["xyz"].band(rows), [o.band(rows) for o in rgb], [o.band(rows) for o in chans])
            if isinstance(source, MasterStack) and cube_enc is None:     # demosaiced as it is encoded: one pass
                enc.encode_mosaic(r0, *bands, mosaic=source.mosaic_band(r0, rows), p0=HALO, cfa=source.cfa_index)
            else:
                band = source.band(r0, rows)
                enc.encode(r0, *bands, band=band)
                if cube_enc is not None:
                    cube_enc.encode(r0, out["spectral"].band(rows), out["render"].band(rows), band=band)
            for o in out.values():
                o.commit()
        invalid = enc.invalid_fraction
        refuse_blank(invalid, enc.lit, profile)
    return Written({k: im.path for k, im in streamed.items()},
                   {k: {"bytes": o.size, FIXITY_ALGORITHM: o.sha256} for k, o in out.items()}, invalid)


class DeliveryQaError(ValueError):
    """A delivery the QA refuses: its images hold nothing (no finite pixel, or every pixel 0); nothing is
    delivered, the raw frames stay in the session."""


def refuse_blank(invalid_fraction: float, lit: bool, profile: CalibrationProfile) -> None:
    """Refuse an output with no finite pixel or with every pixel 0 (a matrix or white point that cannot be, a
    black frame): on a real stand nothing else would show it."""
    what = ("no pixel is a finite number" if invalid_fraction >= 1.0
            else "every pixel is 0" if not lit else None)
    if what is not None:
        raise DeliveryQaError(f"QA refused the delivery: {what} in the encoded images (calibration {profile.id}: "
                              "check its matrix and white point, and that the frames are lit); nothing was "
                              "delivered, the raw frames are kept in the session")


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
    """The sidecar's ``spectral`` section: the cube's format, wavelengths and scale, whether it is a file or made
    on demand, the map that makes it from the channel files (app.processing.cube_map), how it was estimated
    (method, calibration, the calibration's test figures) and the rendering."""
    est = spectral.estimator
    test = profile.spectral.get("test") or {}
    channel_files = [files[k].name for k in sorted((k for k in files if k.startswith("channels_")),
                                                   key=lambda k: int(k.split("_")[1]))]
    cube = {"delivery": spectral.cube, "format": "ENVI", "interleave": INTERLEAVE, "data_type": "uint16",
            "byte_order": "little-endian", "reflectance_scale_factor": SCALE_FACTOR,
            "data_ignore_value": IGNORE_VALUE, "quantity": est.quantity, "bands": est.n_wavelengths,
            "wavelengths_nm": [float(w) for w in est.wavelengths]}
    if spectral.cube == CUBE_FILE:
        cube.update(data=files["spectral"].name, header=files["spectral_header"].name)
    else:
        cube["command"] = f"dualrgb cube <this delivery's folder> --render {spectral.rendering.illuminant}"
    rendering = {**spectral.rendering.describe(), "delivery": spectral.cube}
    if spectral.cube == CUBE_FILE:
        rendering["file"] = files["render"].name
    return {"cube": cube, "map": spectral_map(est, channel_files),
            "estimator": {"method": est.method, "settings": est.settings, "channels": list(est.channels),
                          "calibration": profile.id,
                          "calibration_test": {"rmse_mean": (test.get("rmse") or {}).get("mean"),
                                               "rmse_p90": (test.get("rmse") or {}).get("p90"),
                                               "gfc_mean": (test.get("gfc") or {}).get("mean"),
                                               "de00_mean": {k: v.get("mean") for k, v in
                                                             (test.get("de00") or {}).items()}}},
            "rendering": rendering}


def deliver(source: ChannelSource, profile: CalibrationProfile, original: Original, out_dir: Path, *,
            camera: CameraIdentity, dose: LightDoseRecord, ppi: float | None = None,
            exposures: dict[str, list[float]] | None = None, warnings: list[str] | None = None,
            extra: dict | None = None, render_illuminant: str = DEFAULT_RENDER_ILLUMINANT,
            overrides: list[str] | None = None, cancel: CancelToken | None = None) -> Delivery:
    """Encode the channels of ``source`` (a full-resolution MasterStack or a half-resolution ChannelStack) with the
    calibration's matrix (and spectral estimator: the rendering under ``render_illuminant``, and the cube at half
    resolution) and write every deliverable of ``original``: into a fresh folder, swapped in whole when complete
    (a re-delivery keeps the previous set in ``<stem>/previous/``; a folder of another original is refused:
    app.workflow.delivery_folder). ``ppi``: the delivered files' sampling (None: the calibration's, at this
    resolution). ``overrides``: rules the user overrode for it (app.workflow.mode_rule), said in the sidecar and QA
    line. ``cancel``: checked per band."""
    warnings = list(warnings or [])
    resolution = source.resolution
    ppi = ppi or delivered_ppi(profile, resolution)
    if not ppi:
        warnings.append("no resolution: set the sampling (ppi) or calibrate with the target's size")
    spectral = SpectralPlan.of(profile, render_illuminant, resolution)
    if spectral is None:
        warnings.append(f"no spectral cube: calibration {profile.id} has no spectral estimator (calibrate again)")
    now = datetime.now(UTC)
    stem = original.file_stem
    final = Path(out_dir) / stem
    with staged(Path(out_dir), original) as folder:
        images = deliverable_files(folder, stem, source.channels, spectral, source.lights)
        try:
            written = write_images(source, profile, images, lambda what, page: tiff_meta(
                original, profile.id, camera, dose, ppi, what, now, page), spectral=spectral, cancel=cancel)
        except DeliveryQaError as exc:
            raise DeliveryQaError(f"{original.identifier}: {exc}") from None
        files, fixity = written.files, written.fixity
        if spectral is not None and spectral.cube == CUBE_FILE:
            header = images["spectral_header"].path
            cube_header(spectral, original, profile, source.shape).write(header)
            files["spectral_header"] = header
            fixity["spectral_header"] = file_fixity(header)
        qa = _qa(source, written.invalid, profile, original, dose,
                 any(len(v) > 1 for v in (exposures or {}).values()), warnings)
        qa.overrides = list(overrides or [])
        doc = _sidecar(source, profile, original, camera, now, ppi, exposures, dose, qa, files, fixity, spectral)
        atomic_write(folder / f"{stem}.json",
                     (dumps({**doc, **(extra or {})}, indent=2, ensure_ascii=False, default=str) + "\n"
                      ).encode("utf-8", "backslashreplace"))   # a path's undecodable byte: a JSON \udcXX escape
    log.info("delivered %s: %s", original.identifier, qa.text())
    return Delivery(original, {k: final / p.name for k, p in files.items()}, final / f"{stem}.json", qa)


def resolution_section(source: ChannelSource, profile: CalibrationProfile) -> dict:
    """The sidecar's ``resolution``: full or half, the delivered pixels, the sensor's, and how the channels were
    made from the mosaic."""
    H, W = source.shape
    sensor = profile.raw.get("shape") or [H, W]
    how = (DEMOSAIC if source.resolution == FULL else
           "2x2 Bayer cells (superpixels): R, mean of the two G, B of each cell, no interpolation")
    return {"mode": source.resolution, "width": W, "height": H, "sensor_width": int(sensor[1]),
            "sensor_height": int(sensor[0]), "channels_from_mosaic": how}


def _sidecar(source: ChannelSource, profile: CalibrationProfile, original: Original, camera: CameraIdentity,
             now: datetime, ppi: float | None, exposures: dict[str, list[float]] | None, dose: LightDoseRecord,
             qa: QaLine, files: dict[str, Path], fixity: dict[str, dict], spectral: SpectralPlan | None) -> dict:
    return {**output_header(SIDECAR_FORMAT), "created_at": now.isoformat(timespec="seconds"),
            "original": original.to_dict(), "file_stem": original.file_stem,
            "calibration": {"id": profile.id, "file": str(profile.path or ""), "created_at": profile.created_at,
                            "matrix": profile.matrix.method, "test_de00_mean": profile.test_mean},
            **({"overrides": qa.overrides} if qa.overrides else {}),
            "camera": asdict(camera), "ppi": ppi, "resolution": resolution_section(source, profile),
            "exposures": exposures or {}, "light_dose": dose.to_dict(),
            "qa": qa.to_dict(), "encoding": {"rgb": "display-encoded, white = 65535", "linear_one": LINEAR_ONE,
                                             "channels": source.channels},
            **({"spectral": spectral_section(spectral, profile, files)} if spectral is not None else {}),
            "files": {k: p.name for k, p in files.items()},
            "fixity": fixity_section({files[k].name: v for k, v in fixity.items()})}


__all__ = ["BAND_ROWS", "MODES", "SIDECAR_FORMAT", "Deliverable", "Delivery", "LightDoseRecord", "Original", "QaLine",
           "SpectralPlan", "Written", "deliver", "deliverable_files", "delivered_ppi", "exact_description",
           "image_description", "read_sidecar", "write_images"]
