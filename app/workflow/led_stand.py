"""The sphere measured (thesis 4.3): LED spectra, level linearity and warm-up drift from spectroradiometer
readings, written as a *stand folder* the simulation can use instead of the nominal model.

:func:`analyse` takes :class:`app.workflow.led_readings.LedReadings` (from the virtual lab's sequence or from a
real instrument's files) and, per LED, finds (simulation/led_fit.py):

(a) its spectrum at full level (level-1 readings averaged; else the first warm-up reading): peak, FWHM, radiance;
(b) its level -> output curve (output integrated over the LED's band, relative to full level), the fitted
    low-level response (dead band, exponent, knee) and the minimum stable level;
(c) its warm-up series: peak shift against seconds on (against the first reading), the fitted drift model, and
    the output relative to the first reading (LED 10's fade in the thesis).

:func:`write_stand` writes into the stand folder:

* ``leds.csv``: the LED spectra at full level (spectral CSV, one column per LED in the readings' units, negative
  noise clipped to 0); ``simulate --leds-csv`` or ``--stand-dir`` takes it;
* ``levels.csv``: level, then each LED's relative output (empty where not measured);
* ``stand.json`` (``dualrgb-stand-measurement/1``): everything above per LED, and ``min_stable_level``: the
  largest of the LEDs' (the sphere holds one minimum for all, simulation.sphere.SphereProperties); each LED's
  measured ``levels.level`` / ``levels.relative_output`` is its level -> output curve, which the sphere's one
  level model (simulation.sphere.LevelCurve) predicts with wherever the stand folder is given;
* ``levels.png``, ``warmup.png``: the curves (thesis Fig 4.10 for the drift).

:func:`load_stand` reads a stand folder back for ``simulate --stand-dir``.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.app.workflow.led_readings import LedReadings
from dualrgb.simulation.choices import N_SPHERE_LEDS
from dualrgb.simulation.led_fit import STABLE_TOLERANCE, band_output, fit_drift, fit_low_level, led_band, led_shape
from dualrgb.simulation.sphere import LevelCurves, SphereProperties, curves_from_dict

if TYPE_CHECKING:
    pass

log = logging.getLogger(__name__)
MAX_STAND_BYTES = 4 << 20         # stand.json: a few kB; checked before reading

STAND_FORMAT = "dualrgb-stand-measurement/1"
STAND_JSON, LEDS_CSV, LEVELS_CSV = "stand.json", "leds.csv", "levels.csv"


@dataclass
class LedResult:
    """What was measured of one LED (each part None when its readings were not taken)."""

    led: int
    spectrum: np.ndarray | None = None
    shape: dict[str, float | None] | None = None   # fwhm_nm None for a broadband reading
    levels: dict[str, Any] | None = None
    warmup: dict[str, Any] | None = None


@dataclass
class StandMeasurement:
    wavelengths: np.ndarray
    units: str
    leds: dict[int, LedResult] = field(default_factory=dict)
    sources: list[str] = field(default_factory=list)
    tolerance: float = STABLE_TOLERANCE

    @property
    def min_stable_level(self) -> float | None:
        found = [r.levels["fit"]["min_stable_level"] for r in self.leds.values() if r.levels and r.levels.get("fit")]
        return max(found) if found else None

    def to_dict(self) -> dict[str, Any]:
        return {"units": self.units, "tolerance": self.tolerance, "min_stable_level": self.min_stable_level,
                "leds": {str(k): {"shape": r.shape, "levels": r.levels, "warmup": r.warmup}
                         for k, r in sorted(self.leds.items())},
                "sources": self.sources}


def _full_spectrum(readings: LedReadings, led: int) -> np.ndarray | None:
    full = [s for lv, s in readings.levels.get(led, []) if lv == 1.0]
    if full:
        return np.mean(full, axis=0)
    warm = readings.warmup.get(led)
    return warm[0][1] if warm else None


def _levels(readings: LedReadings, led: int, full: np.ndarray, tolerance: float) -> dict[str, Any] | None:
    series = readings.levels.get(led, [])
    if len(series) < 2:
        return None
    band = led_band(full)
    ref = band_output(readings.wavelengths, full, band)
    lv = np.array([p[0] for p in series])
    out = np.array([band_output(readings.wavelengths, s, band) for _, s in series]) / ref
    result: dict[str, Any] = {"level": lv.tolist(), "relative_output": out.tolist(), "fit": None}
    try:
        result["fit"] = fit_low_level(lv, out, tolerance).to_dict()
    except ValueError as exc:
        log.warning("LED %d: %s", led, exc)
    return result


def _warmup(readings: LedReadings, led: int) -> dict[str, Any] | None:
    series = readings.warmup.get(led, [])
    if len(series) < 2:
        return None
    t = np.array([p[0] for p in series])
    shapes = [led_shape(readings.wavelengths, s) for _, s in series]
    peaks = np.array([sh.peak_nm for sh in shapes])
    integral = np.array([sh.integral for sh in shapes])
    shift = peaks - peaks[0]
    result: dict[str, Any] = {"t_s": t.tolist(), "peak_nm": peaks.tolist(), "peak_shift_nm": shift.tolist(),
                              "relative_output": (integral / integral[0]).tolist(), "fit": None}
    try:
        fit = fit_drift(t, shift)
        result["fit"] = {**fit.to_dict(), "shift_at_end_nm": float(fit.shift(t.max()))}
    except ValueError as exc:
        log.warning("LED %d: %s", led, exc)
    return result


def analyse(readings: LedReadings, tolerance: float = STABLE_TOLERANCE) -> StandMeasurement:
    """Per LED: shape at full level, level curve and fit, warm-up drift and fit (module docstring)."""
    result = StandMeasurement(readings.wavelengths, readings.units, sources=list(readings.sources),
                              tolerance=tolerance)
    for led in readings.leds:
        r = LedResult(led, _full_spectrum(readings, led))
        if r.spectrum is not None:
            r.shape = led_shape(readings.wavelengths, r.spectrum).to_dict()
            r.levels = _levels(readings, led, r.spectrum, tolerance)
        r.warmup = _warmup(readings, led)
        result.leds[led] = r
    return result


def write_stand(result: StandMeasurement, out_dir: str | Path, extra: dict[str, Any] | None = None) -> list[Path]:
    """The stand folder's files (module docstring); returns their paths."""
    from dualrgb.app.json_output import write_json
    from dualrgb.simulation.spectral_io import write_spectral_csv

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    with_spectra = {k: r.spectrum for k, r in sorted(result.leds.items()) if r.spectrum is not None}
    if with_spectra:
        values = np.clip(np.stack(list(with_spectra.values()), axis=1), 0.0, None)
        write_spectral_csv(out / LEDS_CSV, result.wavelengths, values, [f"LED{k}" for k in with_spectra], {
            "title": "LED spectra at full level, measured", "units": result.units or "as the readings",
            "source": "spectroradiometer readings: " + ", ".join(Path(s).name for s in result.sources),
            "made_by": "dualrgb measure (app/workflow/led_stand.py): level-1 readings averaged, negatives "
                       "(instrument noise) set to 0"})
        files.append(out / LEDS_CSV)
    files += _write_levels_csv(result, out)
    files.append(Path(str(write_json(out / STAND_JSON, STAND_FORMAT, {**result.to_dict(), **(extra or {})}))))
    files += _figures(result, out)
    return files


def _write_levels_csv(result: StandMeasurement, out: Path) -> list[Path]:
    from dualrgb.common.atomic_files import atomic_write

    curves = {k: r.levels for k, r in sorted(result.leds.items()) if r.levels}
    if not curves:
        return []
    all_levels = sorted({lv for c in curves.values() for lv in c["level"]})
    lines = ["# title: LED level linearity: output relative to full level", "# units: level 0..1 (PWM / 65535); "
             "output integrated over each LED's band, relative to its level-1 reading",
             "level," + ",".join(f"LED{k}" for k in curves)]
    for lv in all_levels:
        cells = []
        for c in curves.values():
            hit = [o for x, o in zip(c["level"], c["relative_output"], strict=True) if x == lv]
            cells.append(f"{hit[0]:.6g}" if hit else "")
        lines.append(f"{lv:.6g}," + ",".join(cells))
    atomic_write(out / LEVELS_CSV, "\n".join(lines) + "\n")
    return [out / LEVELS_CSV]


def _figures(result: StandMeasurement, out: Path) -> list[Path]:
    from dualrgb.app.processing.led_figures import drift_figure, levels_figure

    files = []
    if any(r.levels for r in result.leds.values()):
        files.append(levels_figure(result, out / "levels.png"))
    if any(r.warmup for r in result.leds.values()):
        files.append(drift_figure(result, out / "warmup.png"))
    return files


@dataclass(frozen=True)
class StandFiles:
    """What ``simulate --stand-dir`` and ``calibrate --stand-dir`` take from a stand folder (None or empty where
    it was not measured): the LED spectra, the minimum stable level and each LED's level -> output curve."""

    folder: Path
    leds_csv: Path | None
    min_stable_level: float | None
    level_curves: LevelCurves = ()

    def sphere(self, base: SphereProperties | None = None) -> SphereProperties:
        """The sphere's level model with this stand's measurements (simulation.sphere)."""
        return (base or SphereProperties()).measured(self.min_stable_level, self.level_curves)


def load_stand(folder: str | Path) -> StandFiles:
    """A stand folder written by :func:`write_stand` (``ValueError`` naming the file otherwise)."""
    folder = Path(folder)
    path = folder / STAND_JSON
    from dualrgb.simulation.spectral_io import read_text_file

    if not path.is_file():
        raise ValueError(f"{path}: cannot read the stand measurement (no such file); expected a folder written by "
                         "`dualrgb measure leds` or `measure import-leds`")
    try:
        doc = json.loads(read_text_file(path, "stand measurement JSON", ValueError, MAX_STAND_BYTES))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    if not isinstance(doc, dict) or doc.get("format") != STAND_FORMAT:
        raise ValueError(f"{path}: format {doc.get('format') if isinstance(doc, dict) else None!r}, "
                         f"expected {STAND_FORMAT!r}")
    level = doc.get("min_stable_level")
    if level is not None and (not isinstance(level, (int, float)) or not 0.0 <= level <= 1.0):
        raise ValueError(f"{path}: min_stable_level {level!r}: expected a level from 0 to 1")
    leds = folder / LEDS_CSV
    return StandFiles(folder, leds if leds.is_file() else None, None if level is None else float(level),
                      _level_curves(path, doc.get("leds")))


def _level_curves(path: Path, leds: Any) -> LevelCurves:
    """Each LED's measured level -> output curve from stand.json's ``leds`` (an LED without a level series:
    None, proportional); ValueError naming the file and the LED."""
    if not isinstance(leds, dict):
        return ()
    curves: dict[str, Any] = {k: v["levels"] for k, v in leds.items()
                              if isinstance(v, dict) and isinstance(v.get("levels"), dict)}
    try:
        return curves_from_dict({k: {"level": c.get("level"), "relative_output": c.get("relative_output")}
                                 for k, c in curves.items()}, N_SPHERE_LEDS)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


# ---- the way in from a real instrument's files (the virtual lab's sequence: app.lab.led_bench) ----------------
def import_readings(paths: list[str | Path], out_dir: str | Path,
                    tolerance: float = STABLE_TOLERANCE) -> tuple[StandMeasurement, list[Path]]:
    """A real instrument's reading files (app.workflow.led_readings names them) -> the stand folder ``out_dir``."""
    from dualrgb.app.workflow.led_readings import read_readings

    result = analyse(read_readings(paths), tolerance)
    return result, write_stand(result, out_dir)


def unstable_levels(lights: Any, stand: StandFiles) -> list[str]:
    """One line per LED a light sets above 0 but below the stand's measured minimum stable level."""
    if stand.min_stable_level is None:
        return []
    out = []
    for light in lights:
        for led, level in zip(light.leds, light.levels, strict=True):
            if 0.0 < level < stand.min_stable_level:
                out.append(f"light {light.name or light.label()}: LED {led} at level {level:.4g} is below the "
                           f"measured minimum stable level {stand.min_stable_level:.4g} ({stand.folder}): its output "
                           "is not proportional there; re-optimise with `dualrgb simulate --stand-dir`")
    return out
