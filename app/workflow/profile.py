"""The calibration profile: made once at the copy stand, reused all day, checked every time it is reused.

A profile is two files written atomically next to each other: ``<id>.json`` (format tag, dualrgb version,
camera and sphere identity, the lights with their exact levels, the exposure plan, the chosen matrix with its
train/test statistics, the white point, creation time, the sha256 of every source frame and of the arrays file)
and ``<id>.npz`` (the master darks per exposure time and the HDR flat-field whites per light, float32 mosaics).

The spectral estimate (issue 21) is an optional ``spectral`` section of the same format, ``dualrgb-calibration/1``
(an addition older readers ignore): the fitted estimator (simulation.spectral_estimation.SpectralEstimator, a
linear map + clip from the profile's channels to the spectra), how it was chosen (cross-validation on the
training target) and its figures on both targets (spectral RMSE, GFC, CIEDE2000 under D65, A, D50, FL11 and a
warm-white LED). A profile without it (made before, or without the targets' spectra) loads and says spectra are
unavailable (:meth:`CalibrationProfile.spectral_estimator`). The estimator maps the same channels as the matrix
(checked on load) from the same lights (checked on every reuse, :func:`check_reuse`).

The stand model fitted to the calibration's captures (app/workflow/stand_calibration.py) is another optional
section, ``stand_model``: the fitted model (measurements it started from, parameters with uncertainties), R^2 of
the nominal and the fitted model against the captured patch means, the captured test CIEDE2000 beside what each
model predicts; the observations it was fitted to are ``stand_*`` arrays in the .npz (a refit from other
measurements needs only the profile). A profile without it loads and says the stand model was not fitted.

Reuse (:func:`check_reuse`): a different camera serial, camera model, ISO, aperture, world (what a simulated
camera reports it renders: a calibration made in one world is refused in another), light levels, or a sphere
temperature more than ``ReuseLimits.temperature_drift_c`` away from the calibration's is a refusal (one line
naming each mismatch; ``force`` turns it into a warning). The age is always reported; past
``ReuseLimits.max_age_h`` (default 8 h) it warns. The temperature limit: LED output and peak wavelength follow
junction temperature (thesis 4.3.2: drift appears as the sphere warms); 5 C keeps it within the range the
thesis saw no drift in.
"""
from __future__ import annotations

import hashlib
import logging
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.calibration import DarkFrame, FlatField, MasterDark
from dualrgb.app.session.capture_session import atomic_write
from dualrgb.app.workflow import profile_check
from dualrgb.app.workflow.profile_arrays import ProfileArrays
from dualrgb.app.workflow.profile_check import FORMAT, ProfileError
from dualrgb.app.workflow.profile_colour import colour_lines
from dualrgb.app.workflow.stand_calibration import describe_stand, observation_arrays, observations_from_arrays
from dualrgb.app.workflow.vocabulary import NamedLight
from dualrgb.common.atomic_files import atomic_output
from dualrgb.common.formatting import format_exposure, format_temperature
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.matrix_fit import CharacterisationMatrix
from dualrgb.simulation.spectral_estimation import SpectralEstimator
from dualrgb.simulation.stand_fit import StandObservations
from dualrgb.simulation.versions import dualrgb_version, software_versions

if TYPE_CHECKING:
    from dualrgb.app.protocols import Sphere
    from dualrgb.drivers.camera.base import Camera

log = logging.getLogger(__name__)

LEVEL_TOLERANCE = 1e-4          # the sphere quantises levels to 16-bit PWM


@dataclass
class CameraIdentity:
    model: str = ""
    serial: str = ""
    lens: str = ""
    iso: int | None = None
    aperture: float | None = None
    world: str = ""                  # the world a simulated camera reports it renders ('' for a real camera)

    @classmethod
    def of(cls, camera: Camera) -> CameraIdentity:
        """What the camera reports about itself (gphoto2: serialnumber / lensname config; others: their summary)."""
        summary = camera.config_summary()
        settings = camera.settings()
        get = getattr(camera, "get_config_value", None)

        def config(*names: str) -> str:
            for name in names:
                if summary.get(name):
                    return str(summary[name])
                if get is not None:
                    try:
                        value = get(name)
                    except Exception as exc:  # noqa: BLE001 - not every body reports every field
                        log.debug("camera config %s: %s", name, exc)
                        continue
                    if value:
                        return str(value)
            return ""
        return cls(str(summary.get("camera") or getattr(camera, "name", "")), config("serial", "serialnumber"),
                   config("lens", "lensname"), settings.iso, settings.aperture, str(summary.get("world") or ""))


@dataclass
class SphereIdentity:
    model: str = ""
    firmware: str = ""
    serial: str = ""
    temperature_c: float | None = None

    @classmethod
    def of(cls, sphere: Sphere) -> SphereIdentity:
        info = sphere.identify()
        return cls(str(info.get("model", "")), str(info.get("firmware", "")), str(info.get("serial", "")),
                   float(sphere.temperature_c()))


@dataclass(frozen=True)
class ReuseLimits:
    temperature_drift_c: float = 5.0
    max_age_h: float = 8.0


@dataclass
class ReuseCheck:
    refusals: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    age_h: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.refusals

    def message(self) -> str:
        return "; ".join(self.refusals)


@dataclass
class CalibrationProfile:
    """Everything a capture needs from the calibration (arrays in ``darks`` / ``whites``, loaded from the .npz)."""

    id: str
    created_at: str
    mode: str
    camera: CameraIdentity
    sphere: SphereIdentity
    preset: str
    lights: list[NamedLight]
    exposures: dict[str, list[float]]           # light -> every calibrated exposure (base first)
    base_exposures: dict[str, float]            # light -> open-gate exposure (80 % of the linear limit)
    matrix: CharacterisationMatrix
    statistics: dict                            # the characterisation: best, methods' train/test stats
    white_xyz: list[float]
    raw: dict                                   # white_level, black_level, cfa, linear_limit, shape
    sources: dict[str, str]                     # frame file -> sha256
    ppi: float | None = None
    targets: dict = field(default_factory=dict)
    version: str = field(default_factory=dualrgb_version)
    darks: MasterDark | None = None
    whites: dict[str, FlatField] = field(default_factory=dict)
    path: Path | None = None
    spectral: dict = field(default_factory=dict)     # the spectral section without the estimator (figures, choice)
    estimator: SpectralEstimator | None = None       # the spectral estimate; None: spectra unavailable
    stand: dict = field(default_factory=dict)        # the stand model section (app.workflow.stand_calibration)
    stand_observations: StandObservations | None = None   # what it was fitted to (from the .npz)
    charts: dict = field(default_factory=dict)       # per target: its chart's file, sha256, patches, range (charts)
    unavailable: dict = field(default_factory=dict)  # what this calibration cannot give, and why (e.g. lights unknown)

    # ---- derived ----
    @property
    def test_mean(self) -> float | None:
        best = self.statistics.get("methods", {}).get(self.statistics.get("best", ""), {})
        return (best.get("test") or {}).get("mean")

    def age_h(self, now: datetime | None = None) -> float:
        created = datetime.fromisoformat(self.created_at)
        return ((now or datetime.now(UTC)) - created).total_seconds() / 3600.0

    def spectral_estimator(self, channels: Sequence[str] | None = None) -> SpectralEstimator:
        """The spectral estimator, for values of ``channels`` (default: the matrix's); ProfileError (one line) when
        the profile has none (spectra unavailable) or maps other channels."""
        if self.estimator is None:
            raise ProfileError(f"calibration {self.id}: spectra unavailable (no spectral estimator in this profile, "
                               f"made by dualrgb {self.version or '?'}); calibrate again to estimate spectra")
        want = list(channels) if channels is not None else list(self.matrix.channels)
        if list(self.estimator.channels) != want:
            raise ProfileError(f"calibration {self.id}: the spectral estimator maps channels "
                               f"{', '.join(self.estimator.channels)}, not {', '.join(want)}")
        return self.estimator

    def light(self, name: str) -> NamedLight:
        for nl in self.lights:
            if nl.name == name:
                return nl
        raise KeyError(f"calibration {self.id} has no light {name!r}")

    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": self.version, "software": software_versions(), "id": self.id,
                "created_at": self.created_at,
                "mode": self.mode, "camera": asdict(self.camera), "sphere": asdict(self.sphere),
                "preset": self.preset, "lights": [{"name": nl.name, **nl.light.to_dict()} for nl in self.lights],
                "exposures": self.exposures, "base_exposures": self.base_exposures,
                "matrix": self.matrix.to_dict(), "statistics": self.statistics, "white_xyz": self.white_xyz,
                "raw": self.raw, "ppi": self.ppi, "targets": self.targets, "sources": self.sources,
                **({"spectral": {"estimator": self.estimator.to_dict(), **self.spectral}} if self.estimator else {}),
                **({"stand_model": self.stand} if self.stand else {}),
                **({"charts": self.charts} if self.charts else {}),
                **({"unavailable": self.unavailable} if self.unavailable else {})}

    # ---- files ----
    def save(self, folder: Path) -> Path:
        """``<folder>/<id>.npz`` then ``<folder>/<id>.json`` (atomic each; the JSON names the npz's sha256)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {}
        dark_index, white_index = [], []
        darks = [(t, self.darks.frame(t)) for t in self.darks.exposures] if self.darks is not None else []
        for i, (t, f) in enumerate(darks):
            arrays[f"dark_{i}"] = f.mean
            dark_index.append({"array": f"dark_{i}", "exposure_s": t, "n_frames": f.n_frames,
                               "noise_dn": None if np.isnan(f.noise_dn) else f.noise_dn})
        for i, (name, ff) in enumerate(self.whites.items()):
            arrays[f"white_{i}"] = ff.white
            white_index.append({"array": f"white_{i}", "light": name, "threshold": ff.threshold})
        if self.stand_observations is not None:
            arrays.update(observation_arrays(self.stand_observations))
        npz = folder / f"{self.id}.npz"
        doc = {**self.to_dict(), "arrays": {"file": npz.name, "sha256": "0" * 64,     # the npz's, once written
                                            "darks": dark_index, "whites": white_index}}
        profile_check.check_document(doc, f"calibration {self.id} (not saved)", digest=False)   # before any write
        with atomic_output(npz, "wb") as fh:         # streamed: a 150 MP calibration's 3.6 GB never copied whole
            np.savez(fh, **arrays)  # type: ignore[arg-type]  # numpy's stub fears a key 'allow_pickle': keys are ours
        size = npz.stat().st_size
        doc["arrays"]["sha256"] = _sha256(npz)
        path = folder / f"{self.id}.json"
        atomic_write(path, (strict_dumps(profile_check.seal(doc), indent=2) + "\n").encode())
        self.path = path
        log.info("calibration %s saved: %s (+ %s, %.0f MB)", self.id, path, npz.name, size / 1e6)
        return path


def load_profile(path: Path, *, arrays: bool = True) -> CalibrationProfile:
    """Read a profile, checked like a frame (app.workflow.profile_check: size, finite numbers, schema, value ranges,
    digest) and, with ``arrays``, its .npz (size, sha256 the JSON names, every array present)."""
    path = Path(path)
    doc = profile_check.read_document(path)
    profile_check.check_document(doc, path)
    try:
        prof = _from_dict(doc)
    except (KeyError, TypeError, ValueError) as exc:
        raise ProfileError(f"{path}: damaged calibration ({type(exc).__name__}: {exc})") from None
    prof.path = path
    if arrays:
        _load_arrays(prof, path.parent, doc)
    return prof


def _from_dict(doc: dict) -> CalibrationProfile:
    lights = [NamedLight(d["name"], LightSource.from_dict(d)) for d in doc["lights"]]
    return CalibrationProfile(
        id=doc["id"], created_at=doc["created_at"], mode=doc["mode"], camera=CameraIdentity(**doc["camera"]),
        sphere=SphereIdentity(**doc["sphere"]), preset=doc["preset"], lights=lights,
        exposures={k: [float(t) for t in v] for k, v in doc["exposures"].items()},
        base_exposures={k: float(v) for k, v in doc["base_exposures"].items()},
        matrix=CharacterisationMatrix.from_dict(doc["matrix"]), statistics=doc["statistics"],
        white_xyz=[float(v) for v in doc["white_xyz"]], raw=doc["raw"], sources=doc["sources"], ppi=doc.get("ppi"),
        targets=doc.get("targets", {}), version=doc.get("version", ""), stand=dict(doc.get("stand_model") or {}),
        charts=dict(doc.get("charts") or {}), unavailable=dict(doc.get("unavailable") or {}), **_spectral_of(doc))


def _spectral_of(doc: dict) -> dict:
    """The optional spectral section: {"estimator", "spectral"} for the profile (empty when absent)."""
    section = doc.get("spectral")
    if not section:
        return {}
    estimator = SpectralEstimator.from_dict(section.get("estimator"), "spectral estimator")
    channels = list(doc["matrix"].get("channels", []))
    if channels and list(estimator.channels) != channels:
        raise ValueError(f"the spectral estimator maps {', '.join(estimator.channels)} but the matrix "
                         f"{', '.join(channels)}")
    return {"estimator": estimator, "spectral": {k: v for k, v in section.items() if k != "estimator"}}


def _load_arrays(prof: CalibrationProfile, folder: Path, doc: dict) -> None:
    index = doc["arrays"]
    npz = folder / index["file"]
    try:
        size, cap = npz.stat().st_size, profile_check.npz_cap(doc)
        if size > cap:
            raise ProfileError(f"{npz}: {size / 2 ** 20:.0f} MiB, more than the {cap / 2 ** 20:.0f} MiB its arrays "
                               f"need ({prof.id}.json); not read")
        digest = _sha256(npz)
    except OSError as exc:
        raise ProfileError(f"{npz}: the calibration's arrays are missing ({exc.strerror or exc})") from None
    if digest != index["sha256"]:
        raise ProfileError(f"{npz}: damaged (sha256 differs from the one {prof.id}.json names)")
    try:
        arrays = ProfileArrays(npz)          # loaded, or mapped when large (app.workflow.profile_arrays)
    except (OSError, ValueError, KeyError) as exc:
        raise ProfileError(f"{npz}: not a calibration's arrays ({_short(exc)})") from None
    profile_check.check_npz(doc, npz, arrays.files)
    try:
        _read_arrays(prof, arrays, index, tuple(doc["raw"]["shape"]))
    except ValueError as exc:                 # an object array (never written by dualrgb), a bad shape
        raise ProfileError(f"{npz}: not a calibration's arrays ({_short(exc)})") from None
    if prof.stand:
        prof.stand_observations = observations_from_arrays(arrays, float(prof.stand.get("dn_scale", 1.0)),
                                                           default_grid(prof.mode))


def _read_arrays(prof: CalibrationProfile, arrays: ProfileArrays, index: dict, shape: tuple[int, ...]) -> None:
    def read(name: str) -> np.ndarray:
        a = arrays[name]
        if a.shape != shape or a.dtype.kind != "f":
            raise ValueError(f"{name} is {a.dtype} {a.shape}, expected floats of the raw frame's shape {shape}")
        return a

    prof.darks = MasterDark()
    for d in index["darks"]:
        noise = d.get("noise_dn")
        prof.darks.put(DarkFrame(float(d["exposure_s"]), read(d["array"]), int(d["n_frames"]),
                                 noise_dn=float("nan") if noise is None else float(noise)))
    prof.whites = {}
    for w in index["whites"]:
        ff = FlatField.__new__(FlatField)          # the threshold was decided when it was made: keep it
        ff.white, ff.threshold, ff.n_invalid = read(w["array"]), float(w["threshold"]), 0
        prof.whites[w["light"]] = ff


def _short(exc: BaseException) -> str:
    """numpy's message without its advice to load the file unsafely (allow_pickle), which is never right here."""
    text = str(exc)
    if "allow_pickle" in text:
        return "it holds Python objects, which a calibration never does"
    return text


def _sha256(path: Path, chunk: int = 1 << 22) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(chunk), b""):
            h.update(block)
    return h.hexdigest()


def check_reuse(prof: CalibrationProfile, camera: CameraIdentity, sphere: SphereIdentity | None = None,
                lights: Sequence[NamedLight] | None = None, limits: ReuseLimits = ReuseLimits(),
                now: datetime | None = None) -> ReuseCheck:
    """Compare the stand now with the calibration: refusals name each mismatch, warnings the age."""
    out = ReuseCheck(age_h=prof.age_h(now))
    c = prof.camera
    for what, have, want in (("camera model", camera.model, c.model), ("camera serial", camera.serial, c.serial),
                             ("ISO", camera.iso, c.iso), ("aperture f/", camera.aperture, c.aperture)):
        if want not in (None, "") and have != want:
            out.refusals.append(f"{what}{'' if what.endswith('/') else ' '}{have} differs from the calibration's "
                                f"{want}")
    if c.world and camera.world != c.world:
        out.refusals.append(f"virtual-lab world {camera.world or 'none (a real camera)'} differs from the "
                            f"calibration's {c.world}")
    if sphere is not None and prof.sphere.temperature_c is not None and sphere.temperature_c is not None:
        drift = sphere.temperature_c - prof.sphere.temperature_c
        if abs(drift) > limits.temperature_drift_c:
            out.refusals.append(f"sphere temperature {sphere.temperature_c:.1f} C is {drift:+.1f} C from the "
                                f"calibration's {prof.sphere.temperature_c:.1f} C "
                                f"(limit +-{limits.temperature_drift_c:g} C)")
    if sphere is not None and prof.sphere.serial and sphere.serial != prof.sphere.serial:
        out.refusals.append(f"sphere serial {sphere.serial} differs from the calibration's {prof.sphere.serial}")
    for nl in lights or ():
        _compare_light(prof, nl, out)
    if out.age_h > limits.max_age_h:
        out.warnings.append(f"calibration {prof.id} is {out.age_h:.1f} h old (over {limits.max_age_h:g} h): "
                            "recalibrate when you can")
    return out


def _compare_light(prof: CalibrationProfile, nl: NamedLight, out: ReuseCheck) -> None:
    try:
        ref = prof.light(nl.name).light
    except KeyError:
        known = ", ".join(light.name for light in prof.lights)
        out.refusals.append(f"light {nl.name!r} is not in the calibration (it has {known})")
        return
    if not np.allclose(ref.weights(), nl.light.weights(), atol=LEVEL_TOLERANCE):
        out.refusals.append(f"{nl.name} levels {nl.light.label()} differ from the calibration's {ref.label()}")


def new_profile_id(created: datetime, sources: dict[str, str]) -> str:
    digest = hashlib.sha256("".join(sorted(sources.values())).encode()).hexdigest()[:8]
    return f"cal-{created.strftime('%Y%m%dT%H%M%SZ')}-{digest}"


def describe(prof: CalibrationProfile, check: ReuseCheck | None = None) -> list[str]:
    """Human-readable lines for ``dualrgb calibration show``."""
    lines = [f"calibration {prof.id} ({FORMAT}, dualrgb {prof.version}), made {prof.created_at} "
             f"({prof.age_h():.1f} h ago), {prof.mode}",
             f"camera: {prof.camera.model} serial {prof.camera.serial or '?'}, ISO {prof.camera.iso}, "
             f"f/{prof.camera.aperture}" + (f", lens {prof.camera.lens}" if prof.camera.lens else "")
             + (f", virtual-lab world {prof.camera.world}" if prof.camera.world else ""),
             f"sphere: {prof.sphere.model} serial {prof.sphere.serial or '?'}, "
             f"{format_temperature(prof.sphere.temperature_c)}",
             f"preset {prof.preset}:"]
    for nl in prof.lights:
        ts = ", ".join(format_exposure(t) for t in prof.exposures.get(nl.name, []))
        lines.append(f"  {nl.name}: {nl.light.label() if nl.light.leds else 'LEDs and levels unknown'}, exposures {ts}")
    lines += chart_lines(prof.charts)
    lines += colour_lines(prof.statistics, prof.matrix.method, prof.matrix.n_channels)
    lines.append(spectral_line(prof))
    lines += describe_stand(prof.stand) if "stand_model" not in prof.unavailable else []
    lines += [f"unavailable: {what}: {why}" for what, why in prof.unavailable.items()]
    lines.append(f"darks {len(prof.darks.exposures) if prof.darks else '?'} exposures, whites "
                 f"{len(prof.whites) or '?'} lights, {len(prof.sources)} source frames, "
                 f"ppi {prof.ppi if prof.ppi else 'not set'}")
    if check is not None:
        lines += [f"REFUSED: {r}" for r in check.refusals] + [f"warning: {w}" for w in check.warnings]
        lines.append("checks: " + ("ok" if check.ok else f"{len(check.refusals)} mismatch(es)"))
    return lines


def chart_lines(charts: dict) -> list[str]:
    """One line per chart the calibration was made with (its file, patches, layout, wavelength range); none for a
    profile made before charts were recorded."""
    out = []
    for role, c in charts.items():
        lo, hi = (c.get("wavelength_range_nm") or [0, 0])[:2]
        left = f", {len(c['left_out'])} left out" if c.get("left_out") else ""
        what = f" (packaged: {c['stands_for']})" if c.get("packaged") and c.get("stands_for") else ""
        out.append(f"{'training' if role == 'train' else role} chart: {c.get('file')}{what}, {c.get('used')} of "
                   f"{c.get('patches')} patches{left}, {'x'.join(map(str, c.get('layout') or []))}, {lo:g}-{hi:g} nm"
                   + (f" ({c['extended']})" if c.get("extended") else "") + f", sha256 {str(c.get('sha256'))[:12]}")
    return out


def spectral_line(prof: CalibrationProfile) -> str:
    """One line on the spectral estimate: method and the test target's figures, or that spectra are unavailable."""
    if prof.estimator is None:
        return "spectra: unavailable (this calibration has no spectral estimator; calibrate again to estimate them)"
    f = prof.spectral.get("test") or prof.spectral.get("train") or {}
    which = "test" if prof.spectral.get("test") else "train"
    chosen = (prof.spectral.get("selection") or {}).get("chosen", prof.estimator.method)
    if not f:
        return f"spectra: {chosen}"
    de = ", ".join(f"{k} {v['mean']:.2f}" for k, v in f.get("de00", {}).items())
    measured = (f.get("wavelengths") or {}).get("measured")          # profiles made before issue 29 have none
    where = f" ({measured[0]:g}-{measured[1]:g} nm, where measured)" if measured else ""
    return (f"spectra: {chosen}; {which} RMSE{where} mean {f['rmse']['mean']:.4f} / p90 {f['rmse']['p90']:.4f}, "
            f"GFC {f['gfc']['mean']:.4f}, mean dE00 under {de}")
