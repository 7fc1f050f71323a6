"""The archival files made from an original's channels (what an original is and how its fields are checked:
core.metadata; where its files go and how a re-delivery keeps the previous set: app.workflow.delivery.delivery_folder;
which files, their layout and their size: app.workflow.delivery.deliverables).

An original is delivered at the sensor's full resolution (the default: each light's exposures merged,
flat-fielded and demosaiced, app.processing.masters) or at half resolution (one pixel per 2x2 Bayer cell, no
interpolation: app.processing.pipeline.ChannelStack); either way the channels come one row band at a time and
every file is written while the next band is encoded (:func:`write_images`). The sidecar ``<id>.json`` holds the
format tag and software versions (dualrgb, numpy, numba, colour-science, rawpy, LibRaw: dualrgb.simulation.versions),
the original, the calibration, the resolution and demosaic, exposures, light dose, QA, the spectral estimate and
the map that makes the cube from the channel files (app.processing.cube_map), the files, and their fixity (size and
SHA-256 of every deliverable, computed as it is written: ``dualrgb verify`` checks them, app.workflow.delivery.fixity).
Its
JSON Schema is resources/schemas/dualrgb-delivery-1.schema.json.

Every TIFF carries resolution (ppi), Make/Model, DateTime, Software with the dualrgb version, an
ImageDescription, a DocumentName, Copyright, an EXIF IFD, an ICC profile and XMP (app.workflow.delivery.master_metadata
says what each holds; app.processing.outputs writes them). Text policy: the XMP packet (UTF-8) and the sidecar
(UTF-8 JSON) carry every field exactly as normalised (the XMP's ``dc:description`` the exact text of the
ImageDescription); TIFF's ASCII tags (ImageDescription, Make, Model, DocumentName, Copyright) carry
core.metadata.ascii_text of it.
"""
from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, nullcontext
from dataclasses import asdict, dataclass, field
from datetime import datetime
from functools import partial
from pathlib import Path

import numpy as np

from dualrgb.app.json_output import dumps
from dualrgb.app.processing.band_pipeline import encode_master, open_all, ring_slots
from dualrgb.app.processing.cube_map import spectral_map
from dualrgb.app.processing.demosaic import DEMOSAIC
from dualrgb.app.processing.encode import LINEAR_ONE, XYZ_ONE, DeliveryEncoder
from dualrgb.app.processing.envi import DTYPE, IGNORE_VALUE, INTERLEAVE, SCALE_FACTOR, EnviHeader
from dualrgb.app.processing.masters import FULL, MasterStack
from dualrgb.app.processing.outputs import open_tiff
from dualrgb.app.processing.pipeline import ChannelSource
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT
from dualrgb.app.processing.spectral_cube import SpectralEncoder
from dualrgb.app.processing.tiff_stream import RawStream, TiffStream
from dualrgb.app.workflow.calibration.profile import CalibrationProfile, CameraIdentity
from dualrgb.app.workflow.delivery.deliverables import (
    CUBE_FILE,
    Deliverable,
    SpectralPlan,
    check_spectral_request,
    deliverable_files,
)
from dualrgb.app.workflow.delivery.delivery_folder import SIDECAR_FORMAT, read_sidecar, staged, stem_of
from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings
from dualrgb.app.workflow.delivery.fixity import FIXITY_ALGORITHM, file_fixity, fixity_section
from dualrgb.app.workflow.delivery.master_metadata import MasterContext, exact_description, image_description
from dualrgb.common.clock import output_time
from dualrgb.common.progress import CancelToken, check
from dualrgb.core.metadata import MODES, Original, ascii_text
from dualrgb.core.session.capture_session import atomic_write
from dualrgb.simulation.versions import dualrgb_version, output_header

log = logging.getLogger(__name__)

BAND_ROWS = 64          # rows encoded and written at a time: 24 MP full resolution, 23 MB over the five TIFFs


@dataclass
class LightDoseRecord:
    """The light an original received while it was captured (metering included).

    ``recorded`` False: no lit period was recorded (frames another program shot, issue 37); the figures are then
    unknown, written as null and never as a zero dose."""

    lux_s: float = 0.0
    on_s: float = 0.0
    recorded: bool = True

    @classmethod
    def unknown(cls) -> LightDoseRecord:
        return cls(recorded=False)

    @property
    def lux_h(self) -> float:
        return self.lux_s / 3600.0

    def text(self) -> str:
        """The QA line's words for it."""
        if not self.recorded:
            return "light dose not recorded"
        return f"light dose {self.lux_h:.3g} lux.h ({self.lux_s:.3g} lux.s)"

    def to_dict(self) -> dict:
        if not self.recorded:
            return {"lux_s": None, "lux_h": None, "on_s": None}
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
    per_pixel: dict | None = None           # the calibration's per-pixel test dE00 {mean, p90} (None: not measured)
    noise_gain: float | str | None = None   # the delivered model's noise gain (Y) at the white

    def text(self) -> str:
        def de(v: float | None) -> str:
            return "n/a" if v is None else f"{v:.2f}"
        spectral = "" if self.spectral_rmse is None else f", spectral RMSE test {self.spectral_rmse:.3f}"
        forced = "".join(f"OVERRIDE: {o}; " for o in self.overrides)
        pixel = "" if not self.per_pixel else (f", per pixel test {de(self.per_pixel.get('mean'))} / p90 "
                                               f"{de(self.per_pixel.get('p90'))} (noise gain {self.noise_gain})")
        return (f"{self.identifier}: {forced}clipped {self.clipped_pct:.2f} %, under-exposed "
                f"{self.underexposed_pct:.2f} %, {self.dose.text()}, calibration dE00 train "
                f"{de(self.train_mean)} / test {de(self.test_mean)}{pixel}{spectral}" + (", HDR" if self.hdr else "")
                + "".join(f"; {w}" for w in self.warnings))

    def to_dict(self) -> dict:
        return {"text": self.text(), "clipped_pct": round(self.clipped_pct, 4),
                "underexposed_pct": round(self.underexposed_pct, 4), "invalid_pct": round(self.invalid_pct, 4),
                "light_dose": self.dose.to_dict(), "calibration_train_de00_mean": self.train_mean,
                "calibration_test_de00_mean": self.test_mean, "calibration_test_spectral_rmse": self.spectral_rmse,
                "calibration_test_per_pixel_de00": self.per_pixel, "calibration_noise_gain_y": self.noise_gain,
                "hdr": self.hdr, "warnings": self.warnings, "overrides": self.overrides}


@dataclass
class Delivery:
    original: Original
    files: dict[str, Path]
    sidecar: Path
    qa: QaLine
    calibration: str = ""                   # the id of the calibration it was delivered with


def _qa(stack: ChannelSource, invalid: float, profile: CalibrationProfile, original: Original,
        dose: LightDoseRecord, hdr: bool, warnings: list[str]) -> QaLine:
    best = profile.statistics.get("methods", {}).get(profile.statistics.get("best", ""), {})
    clipped = max(stack.clipped_fraction.values(), default=0.0)
    under = stack.underexposed_fraction
    rmse = ((profile.spectral.get("test") or {}).get("rmse") or {}).get("mean") if profile.estimator else None
    stats = profile.statistics
    return QaLine(original.identifier, 100 * clipped, 100 * under, 100 * invalid, dose,
                  (best.get("train") or {}).get("mean"), profile.test_mean, hdr, list(warnings), rmse,
                  per_pixel=(stats.get("per_pixel_de00") or {}).get("test"),
                  noise_gain=(stats.get("noise_gain") or {}).get("Y"))


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


def open_deliverable(im: Deliverable, height: int, width: int, ctx: MasterContext, band_rows: int,
                     pool: ThreadPoolExecutor | None, direct: bool, slots: int = 2) -> TiffStream:
    """The streamed file of deliverable ``im`` (its SHA-256 computed as it is written; tags, XMP, EXIF and ICC from
    ``ctx``; ``slots``: band buffers, more than 2 for app.processing.band_pipeline)."""
    if im.kind == "cube":                                     # the cube's data: band-interleaved by line
        return RawStream(im.path, (height, im.samples, width), DTYPE, band_rows=band_rows, executor=pool,
                         direct=direct, digest=FIXITY_ALGORITHM)
    return open_tiff(im.path, (height, width, im.samples), ctx.meta(im), photometric=im.photometric,
                     icc=ctx.icc(im), band_rows=band_rows, executor=pool, direct=direct, digest=FIXITY_ALGORITHM,
                     slots=slots)


def write_images(source: ChannelSource, profile: CalibrationProfile, images: dict[str, Deliverable],
                 ctx: MasterContext, *, spectral: SpectralPlan | None = None,
                 band_rows: int = BAND_ROWS, direct: bool = True, cancel: CancelToken | None = None) -> Written:
    """Encode the channels band by band straight into the open files (app.processing.tiff_stream), each file's
    SHA-256 computed from the bytes as they are written; nothing image-sized is held but what ``source`` holds. A
    full-resolution original is demosaiced as it is encoded, a band per core (app.processing.band_pipeline). The
    spectral cube (when it is a file) and the rendering come from the same bands (``spectral``; the cube's header
    is written by :func:`deliver`); ``cancel`` is checked before every band (common.progress.Cancelled: nothing is
    delivered). A matrix or white point that is not finite, or images that come out blank, are refused
    (:class:`DeliveryQaError`)."""
    H, W = source.shape
    N = len(source.channels)
    if not (np.isfinite(profile.matrix.matrix).all() and np.isfinite(profile.white_xyz).all()):
        raise DeliveryQaError(f"QA refused the delivery: no pixel is a finite number (calibration {profile.id} has "
                              "a matrix or white point that is not finite); nothing was delivered, the raw frames "
                              "are kept in the session")
    streamed = {k: im for k, im in images.items() if im.streamed}
    rgb_keys = [k for k, im in streamed.items() if im.kind == "rgb"]
    ch_keys = sorted((k for k, im in streamed.items() if im.kind == "channels"), key=lambda k: streamed[k].light)
    est = spectral.estimator if spectral is not None and "spectral" in streamed else None
    spec = (SpectralEncoder((H, W, N), est.matrix, est.bounds, spectral.rendering, offset=est.offset)
            if spectral is not None and est is not None else nullcontext())
    master = source if isinstance(source, MasterStack) and est is None else None   # the one pass, every core
    with DeliveryEncoder((H, W, N), profile.matrix.matrix, profile.white_xyz, [images[k].space or "" for k in rgb_keys],
                         degree=profile.matrix.degree) as enc, spec as cube_enc, \
            ThreadPoolExecutor(len(streamed), thread_name_prefix="deliver") as pool, ExitStack() as opened:
        slots = ring_slots(enc.threads) if master else 2
        out = open_all({k: partial(open_deliverable, im, H, W, ctx, band_rows, pool, direct, slots)
                        for k, im in streamed.items()}, pool, opened)
        rgb, chans = [out[k] for k in rgb_keys], [out[k] for k in ch_keys]
        if master is not None:
            encode_master(master, enc, out["xyz"], rgb, chans, io=pool, cancel=cancel)
        else:
            _encode_bands(source, enc, cube_enc, out, band_rows, cancel, [rgb, chans])
        invalid = enc.invalid_fraction
        refuse_blank(invalid, enc.lit, profile)
    return Written({k: im.path for k, im in streamed.items()},
                   {k: {"bytes": o.size, FIXITY_ALGORITHM: o.sha256} for k, o in out.items()}, invalid)


def _encode_bands(source: ChannelSource, enc: DeliveryEncoder, cube_enc: SpectralEncoder | None,
                  out: dict[str, TiffStream], band_rows: int, cancel: CancelToken | None,
                  streams: list[list[TiffStream]]) -> None:
    """The bands of ``source`` (N channels each) encoded into ``out`` in order (``streams``: the RGB ones and the
    lights' ones), the cube's and the rendering's too with ``cube_enc``: each band in pieces on both cores while
    the writer threads put the previous one on disk and hash it."""
    H = source.shape[0]
    rgb, chans = streams
    for r0 in range(0, H, band_rows):
        check(cancel)
        rows = min(band_rows, H - r0)
        bands = (out["xyz"].band(rows), [o.band(rows) for o in rgb], [o.band(rows) for o in chans])
        band = source.band(r0, rows)
        enc.encode(r0, *bands, band=band)
        if cube_enc is not None:
            cube_enc.encode(r0, out["spectral"].band(rows), out["render"].band(rows), band=band)
        for o in out.values():
            o.commit()


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
            extra: dict | None = None, render_illuminant: str | None = None,
            overrides: list[str] | None = None, cancel: CancelToken | None = None,
            settings: DeliverySettings | None = None, captured_at: datetime | None = None,
            now: datetime | None = None) -> Delivery:
    """Encode the channels of ``source`` (a full-resolution MasterStack or a half-resolution ChannelStack) with the
    calibration's matrix (and spectral estimator: the cube and its rendering under ``render_illuminant`` when the
    delivery ``settings`` ask for them; None: the settings file's, app.workflow.delivery.delivery_settings) and write
    every
    deliverable of ``original``: into a fresh folder, swapped in whole when complete (a re-delivery keeps the
    previous set in ``<stem>/previous/``; a folder of another original is refused:
    app.workflow.delivery.delivery_folder).
    ``ppi``: the delivered files' sampling (None: the calibration's, at this resolution). ``overrides``: rules the
    user overrode for it (app.workflow.stand.mode_rule), said in the sidecar and QA line. ``captured_at``: the capture's
    time (EXIF; default ``now``: the time written into every file, default common.clock's). ``cancel``: checked
    per band."""
    settings, illuminant = _request(profile, settings, render_illuminant)
    warnings = list(warnings or []) + ([] if all(nl.light.leds for nl in profile.lights) else [LIGHTS_UNKNOWN])
    ppi = ppi or delivered_ppi(profile, source.resolution)
    warnings += ppi_warnings(ppi)
    spectral = SpectralPlan.of(profile, illuminant, settings.writes_spectral(source.resolution))
    if spectral is None:
        warnings.append(f"no spectral cube: calibration {profile.id} has no spectral estimator (calibrate again)")
    ctx = MasterContext(original, profile.id, camera, dose.lux_s if dose.recorded else None, ppi,
                        (now := now or output_time()), (captured_at or now).astimezone(),
                        dict(exposures or {}), list(source.lights), settings, _processing(profile, source),
                        list(profile.white_xyz), profile)
    stem = stem_of(Path(out_dir), original)        # the ASCII form where the file system refuses Unicode
    with staged(Path(out_dir), original) as folder:
        images = deliverable_files(folder, stem, source.channels, spectral, source.lights, settings.masters,
                                   settings.access)
        try:
            written = write_images(source, profile, images, ctx, spectral=spectral, cancel=cancel)
        except DeliveryQaError as exc:
            raise DeliveryQaError(f"{original.identifier}: {exc}") from None
        files, fixity = written.files, written.fixity
        _finish_files(images, files, fixity, spectral, original, profile, source, ctx)
        qa = _qa(source, written.invalid, profile, original, dose,
                 any(len(v) > 1 for v in (exposures or {}).values()), warnings)
        qa.overrides = list(overrides or [])
        doc = _sidecar(source, profile, original, camera, now, ppi, exposures, dose, qa, files, fixity, spectral)
        doc.update(file_stem=stem, captured_at=ctx.captured.isoformat(timespec="seconds"),
                   delivery_settings=settings.describe())
        doc["qa"]["grading"] = calibration_grades(profile)
        write_sidecar(folder / f"{stem}.json", {**doc, **(extra or {})})
    log.info("delivered %s: %s", original.identifier, qa.text())
    final = Path(out_dir) / stem
    return Delivery(original, {k: final / p.name for k, p in files.items()}, final / f"{stem}.json", qa, profile.id)


LIGHTS_UNKNOWN = ("lights unknown (raw files imported without a preset): no stand-model prediction, no model-based "
                  "spectra")


def lights_section(profile: CalibrationProfile) -> dict:
    """The sidecar's word on the calibration's lights: the preset and each light's LEDs and levels, or "unknown"
    (raw files imported without a preset), and what the calibration cannot give (``unavailable``)."""
    known = all(nl.light.leds for nl in profile.lights)
    lights = ({nl.name: nl.light.label() for nl in profile.lights} if known else "unknown")
    return {"preset": profile.preset, "lights": lights,
            **({"unavailable": dict(profile.unavailable)} if profile.unavailable else {})}


def _request(profile: CalibrationProfile, settings: DeliverySettings | None, render_illuminant: str | None
             ) -> tuple[DeliverySettings, str]:
    """The delivery settings (None: the settings file's) checked against the calibration, and the rendering's
    light (the argument's, else the settings', else the default)."""
    from dualrgb.app.workflow.delivery.delivery_settings import load

    settings = settings if settings is not None else load()
    check_spectral_request(profile, settings.spectral is True)
    return settings, render_illuminant or settings.render_illuminant or DEFAULT_RENDER_ILLUMINANT


def write_sidecar(path: Path, doc: dict) -> None:
    """A delivery's sidecar, atomically (a path's undecodable byte becomes a JSON \\udcXX escape)."""
    atomic_write(path, (dumps(doc, indent=2, ensure_ascii=False, default=str) + "\n"
                        ).encode("utf-8", "backslashreplace"))


def _finish_files(images: dict[str, Deliverable], files: dict[str, Path], fixity: dict[str, dict],
                  spectral: SpectralPlan | None, original: Original, profile: CalibrationProfile,
                  source: ChannelSource, ctx: MasterContext) -> None:
    """The files made after the bands: the cube's header and the access copies (from the sRGB master)."""
    if spectral is not None and spectral.cube == CUBE_FILE:
        header = images["spectral_header"].path
        cube_header(spectral, original, profile, source.shape).write(header)
        files["spectral_header"] = header
        fixity["spectral_header"] = file_fixity(header)
    for key, im in images.items():
        if im.kind == "access":
            from dualrgb.app.workflow.delivery.access_copies import make_access_copy

            make_access_copy(im, files["srgb"], ctx)
            files[key] = im.path
            fixity[key] = file_fixity(im.path)


def calibration_grades(profile: CalibrationProfile) -> dict:
    """The sidecar's ``qa.grading``: the FADGI / ISO 19264 / Metamorfoze verdicts of the calibration the original
    was delivered with (its test target; app.processing.quality), or why there are none."""
    summary = profile.statistics.get("quality") or {}
    if not summary.get("grading"):
        return {"basis": f"calibration {profile.id} recorded no grading (made before it was)", "standards": {}}
    return {"basis": f"calibration {profile.id}, its test target (colour criteria; the rest not assessed)",
            "standards": {std: {"verdict": g["verdict"], "passed": g["passed"], "failed": g["failed"],
                                "metrics": g["metrics"]} for std, g in summary["grading"].items()}}


PPI_BASELINE = (300.0, 4000.0)      # SLUB's TIFF baseline (checkit_tiff cit_tiff6_baseline_SLUB.cfg) XResolution


def ppi_warnings(ppi: float | None) -> list[str]:
    """The QA line's words about the sampling: none known, or outside what SLUB's TIFF baseline accepts."""
    if not ppi:
        return ["no resolution: the TIFFs carry no ppi (ResolutionUnit none), which SLUB's TIFF baseline "
                "(checkit_tiff) refuses; set the sampling (ppi) or calibrate with the target's size"]
    lo, hi = PPI_BASELINE
    if not lo <= ppi <= hi:
        return [f"{ppi:.0f} ppi: the stand's sampling is outside the {lo:.0f}-{hi:.0f} ppi of SLUB's TIFF baseline "
                "(checkit_tiff reports only that rule)"]
    return []


def _processing(profile: CalibrationProfile, source: ChannelSource) -> str:
    """The conversion's parameters for the XMP history."""
    how = DEMOSAIC if source.resolution == FULL else "2x2 Bayer cells"
    return (f"calibration {profile.id} ({profile.matrix.method} matrix, test dE00 "
            f"{'n/a' if profile.test_mean is None else f'{profile.test_mean:.2f}'}); dark, flat field, HDR merge; "
            f"{source.resolution} resolution ({how})")


def colour_section(profile: CalibrationProfile) -> dict:
    """The sidecar's colour figures of the calibration beside its patch means (issue 40): the delivered model, its
    per-pixel dE00 on the charts, its noise gain and the light set's condition number (what it has of them)."""
    m, stats = profile.matrix, profile.statistics
    out: dict = {"model": {"method": m.method, "degree": m.degree, "terms": int(m.matrix.shape[0])}}
    for key in ("per_pixel_de00", "noise_gain", "condition_number"):
        if stats.get(key) is not None:
            out[key] = stats[key]
    return out


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
                            "matrix": profile.matrix.method, "test_de00_mean": profile.test_mean,
                            **lights_section(profile), **colour_section(profile)},
            **({"overrides": qa.overrides} if qa.overrides else {}),
            "camera": asdict(camera), "ppi": ppi, "resolution": resolution_section(source, profile),
            "exposures": exposures or {}, "light_dose": dose.to_dict(),
            "qa": qa.to_dict(), "encoding": {"rgb": "display-encoded, white = 65535", "linear_one": LINEAR_ONE,
                                             "channels": source.channels, "xyz": "X/Xn, Y/Yn, Z/Zn; XYZ = code / "
                                             "xyz_one * white_xyz", "xyz_one": XYZ_ONE,
                                             "white_xyz": [float(v) for v in profile.white_xyz]},
            **({"spectral": spectral_section(spectral, profile, files)} if spectral is not None else {}),
            "files": {k: p.name for k, p in files.items()},
            "fixity": fixity_section({files[k].name: v for k, v in fixity.items()})}


__all__ = ["BAND_ROWS", "MODES", "SIDECAR_FORMAT", "Deliverable", "Delivery", "LightDoseRecord", "Original", "QaLine",
           "SpectralPlan", "Written", "deliver", "deliverable_files", "delivered_ppi", "exact_description",
           "image_description", "read_sidecar", "write_images"]
