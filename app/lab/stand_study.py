"""``dualrgb study stand``: does the stand model predict what is captured, in worlds that are not the nominal model?

In each virtual-lab world asked for (default ``mismatched-d700``; ``all``: every packaged world), README's
measurement workflow, step by step:

1. measure the LEDs (``dualrgb measure leds``, levels only: spectra, minimum stable level, each LED's level ->
   output curve) and the camera (``dualrgb measure csrf``: the monochromator sweep) in the world;
2. calibrate with the mode's nominal preset, once per seed; each calibration's stand fit from the measured camera
   and LEDs (what ``calibrate --camera-csv --stand-dir`` stores: :func:`workflow_figures` refits each
   calibration's stored observations from that start, the same function on the same data) predicts the captured
   test dE00;
3. re-optimise on that model (seed 0's; ``simulate --stand``, the lights in use kept unless better are found);
4. calibrate with the re-optimised lights, once per seed, and compare again (captured against each calibration's
   own prediction and against the model that chose them).

In the worlds named in ``compare`` (by default the one world when only one is studied) also the other stand
models, each with its R^2 and predicted test dE00 for the preset's lights, and lights re-optimised on each and
captured: nominal; fitted from the nominal camera (LED outputs and peaks, gains, flare) with and without its
curves' shift and width; and the world itself (its true camera, LEDs, level response and flare).

Writes ``stand.json`` (``dualrgb-study-stand/2``), ``study_stand.png`` (the workflow in every world),
``study_stand_models.png`` (the first world compared) and ``SUMMARY.md``
(app/workflow/stand_study_report.py).
"""
from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.workflow.profile import CalibrationProfile
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report, scaled
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.presets import Preset
from dualrgb.simulation.sphere import LevelCurve, LevelCurves
from dualrgb.simulation.stand_fit import StandObservations, expected_de00, fit_stand, predict, r2_per_channel
from dualrgb.simulation.stand_model import StandModel, StandParameters

log = logging.getLogger(__name__)

FORMAT = "dualrgb-study-stand/2"
FITS = ("fitted, nominal camera", "fitted, nominal camera, LEDs only")
WORKFLOW = "fitted, measured camera and LEDs"          # the measurement workflow's model (module docstring)
PRESET, REOPTIMISED = "nominal preset", f"re-optimised: {WORKFLOW}"


@dataclass(frozen=True)
class StandStudyConfig:
    worlds: tuple[str, ...] = ("mismatched-d700",)
    mode: str = "reflective"
    frame_size: tuple[int, int] = (600, 400)
    seeds: tuple[int, ...] = (0, 1, 2)
    preset: str | None = None                 # the nominal preset (default: the mode's, app.workflow.defaults)
    csrf_step_nm: float = 10.0
    csrf_frame_size: tuple[int, int] = (240, 160)
    compare: tuple[str, ...] = ("mismatched-d700",)   # worlds where every model is compared (module docstring)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass
class WorldStudy:
    """One world's figures: the workflow's predictions against its captures, the models, the light sets."""

    world: str
    identity: str
    workflow: dict[str, Any] = field(default_factory=dict)
    models: dict[str, dict[str, Any]] = field(default_factory=dict)     # R^2, predicted vs captured
    lights: dict[str, dict[str, Any]] = field(default_factory=dict)     # captured per light set
    files: dict[str, str] = field(default_factory=dict)
    elapsed_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass
class StandStudy:
    config: StandStudyConfig
    worlds: dict[str, WorldStudy] = field(default_factory=dict)
    elapsed_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "config": self.config.to_dict(), "elapsed_s": self.elapsed_s,
                "worlds": {k: v.to_dict() for k, v in self.worlds.items()}}


def world_model(world: Any) -> StandModel:
    """The stand model that is the world itself (drivers.virtual.world.World): its camera, LEDs, their level
    response (:func:`world_level_curves`) and flare."""
    return StandModel(camera_csv=str(world.camera_path),
                      params=StandParameters(led_output_scale=tuple(world.led_output_scale),
                                             led_peak_shift_nm=tuple(world.led_peak_shift_nm),
                                             led_width_scale=tuple(world.led_width_scale), flare=float(world.flare)),
                      sources={"world": world.identity}, level_curves=world_level_curves(world))


def world_level_curves(world: Any) -> LevelCurves:
    """The world's low-level response as a level curve per LED (none for an ideal driver): 0.025 % steps up to the
    knee, proportional above it."""
    response = world.led_low_level
    if response.identity:
        return ()
    knee = max(response.knee, response.dead_band)
    levels = np.unique(np.concatenate([np.arange(1, int(np.ceil(knee / 2.5e-4))) * 2.5e-4, [knee, 1.0]]))
    curve = LevelCurve(tuple(float(v) for v in levels), tuple(float(v) for v in response.output(levels)))
    return (curve,) * len(world.led_output_scale)


# ---- the virtual lab's part ---------------------------------------------------------------------------------
def calibrate_in_world(cfg: StandStudyConfig, world: str, preset: Preset, seed: int,
                       folder: Path) -> CalibrationProfile:
    """A calibration (``hdr off``) in ``world`` with ``preset``'s lights, in session ``folder``."""
    from dualrgb.app.lab.targets import LAB_TARGET_WIDTH_MM
    from dualrgb.app.workflow.copystand import CopyStand, StandSettings
    from dualrgb.app.workflow.folders import open_session
    from dualrgb.drivers.virtual.clock import SkippableClock
    from dualrgb.drivers.virtual.lab import VirtualLab
    from dualrgb.drivers.virtual.world import load_world

    definition = {"workflow": "study stand", "preset": preset.name, "seed": seed, "mode": cfg.mode,
                  "frame_size": list(cfg.frame_size), "world": load_world(world).identity}
    # a skippable clock: a lit exposure's time passes on the lab's clock without being waited for (drivers.virtual
    # .camera holds lit exposures; a study of a dozen calibrations has no artwork whose dose needs the wait)
    with VirtualLab(mode=cfg.mode, frame_size=cfg.frame_size, seed=seed, world=world,
                    clock=SkippableClock()) as lab:
        session = open_session(folder, definition, meta={"mode": cfg.mode})
        try:
            stand = CopyStand(*lab.devices(), session, stand=lab.place,
                              settings=StandSettings(settle_s=0.0, optimise_matrix=False,
                                                     target_width_mm=LAB_TARGET_WIDTH_MM))
            profile: CalibrationProfile = stand.calibrate(preset, hdr_auto=False)     # the charts found in frames
            return profile
        finally:
            session.close()


def measure_camera(cfg: StandStudyConfig, world: str, folder: Path) -> Path:
    """The camera CSV the monochromator sweep measures in ``world`` (thesis 4.2)."""
    from dualrgb.app.sequences.csrf import CsrfSettings
    from dualrgb.app.workflow.csrf import measure_csrf
    from dualrgb.app.workflow.folders import open_session
    from dualrgb.drivers.virtual.monochromator_bench import MonochromatorBench
    from dualrgb.simulation.radiance_reference import read_radiance_reference

    settings = CsrfSettings(380.0, 780.0, cfg.csrf_step_nm)
    with MonochromatorBench(frame_size=cfg.csrf_frame_size, world=world) as bench:
        session = open_session(folder / "csrf-session", {**settings.definition(), "world": world},
                               meta={"measurement": "csrf"})
        try:
            def radiance(wavelengths: list[float]) -> Any:
                return read_radiance_reference(bench.spectroradiometer().write_csv(
                    session.path / "radiance-virtual.csv", wavelengths))
            assert bench.camera is not None                 # made by start()
            m = measure_csrf(bench.camera, bench.monochromator, session, settings, radiance=radiance,
                             out=folder / "csrf.csv")
        finally:
            session.close()
    if m is None:
        raise RuntimeError("the camera measurement was cancelled")
    return Path(m.path)


def measure_leds(world: str, folder: Path) -> Path:
    """The stand folder ``dualrgb measure leds --warmup-leds none`` writes in ``world`` (thesis 4.3)."""
    from dualrgb.app.lab.led_bench import measure_virtual
    from dualrgb.app.sequences.led_measurement import LedMeasurementPlan

    out = folder / "stand"
    measure_virtual(out, world, LedMeasurementPlan(warmup_leds=()))
    return out


# ---- what each model predicts --------------------------------------------------------------------------------
def captured_de(profiles: list[CalibrationProfile]) -> dict[str, Any]:
    """Mean captured CIEDE2000 (least squares) of calibrations of one light set: mean over seeds, and each."""
    a = np.array([(p.statistics["methods"]["least-squares"]["train"]["mean"],
                   p.statistics["methods"]["least-squares"]["test"]["mean"]) for p in profiles])
    return {"train": float(a[:, 0].mean()), "test": float(a[:, 1].mean()),
            "train_each": [float(v) for v in a[:, 0]], "test_each": [float(v) for v in a[:, 1]]}


def lights_of(profile: CalibrationProfile) -> np.ndarray:
    """(L, n_leds) the levels a calibration set, as set."""
    return np.stack([nl.light.weights() for nl in profile.lights])


def calibration_capture(profile: CalibrationProfile) -> CaptureModel:
    """The expected-captured model of the profile's calibration (its patch sizes and frame counts)."""
    from dualrgb.app.workflow.stand_calibration import calibration_capture as capture_of

    c = profile.stand.get("capture") or {}
    return capture_of(profile.mode, np.array([c.get("train_pixels", 56)]), np.array([c.get("test_pixels", 462)]),
                      int(c.get("dark_frames", 10)), int(c.get("flat_frames", 3)))


def observations(profile: CalibrationProfile) -> StandObservations:
    if profile.stand_observations is None:
        raise ValueError(f"calibration {profile.id}: no stand observations (the stand fit was not made)")
    return profile.stand_observations


def workflow_figures(profiles: list[CalibrationProfile], start: StandModel, mode: str) -> dict[str, Any]:
    """Each calibration's stand fit from ``start`` (the measured camera and LEDs) and its predicted test and
    training dE00 beside the captured ones: per seed, the misses, and the fit's worst R^2 and warnings."""
    cap = captured_de(profiles)
    pred: dict[str, list[float]] = {"train": [], "test": []}
    r2, warnings = [], []
    for p in profiles:
        fit = fit_stand(observations(p), start)
        de = expected_de00(fit.model, mode, lights_of(p), calibration_capture(p))
        for k in pred:
            pred[k].append(de[k])
        r2.append(fit.min_r2())
        warnings.append(fit.warnings)
    miss_each = [pt / ct - 1.0 for pt, ct in zip(pred["test"], cap["test_each"], strict=True)]
    return {"captured": cap, "predicted": {"train": float(np.mean(pred["train"])), "test": float(np.mean(pred["test"])),
                                           "train_each": pred["train"], "test_each": pred["test"]},
            "miss": {"test": float(np.mean(pred["test"])) / cap["test"] - 1.0, "test_each": miss_each,
                     "test_worst": max(miss_each, key=abs)},
            "r2_train_each": r2, "warnings_each": warnings}


def model_figures(models: dict[str, StandModel], obs: StandObservations, levels: np.ndarray, mode: str,
                  capture: CaptureModel, captured: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per model: worst-channel R^2 on both targets, predicted mean CIEDE2000 for ``levels`` and its miss."""
    out = {}
    for name, model in models.items():
        pred = predict(model, obs)
        de = expected_de00(model, mode, levels, capture)
        out[name] = {"r2_train": min(r2_per_channel(pred.train, obs.train)),
                     "r2_test": (min(r2_per_channel(pred.test, obs.test))
                                 if pred.test is not None and obs.test is not None else None),
                     "predicted": de, "miss": {k: de[k] / captured[k] - 1.0 for k in ("train", "test")},
                     "model": model.to_dict()}
    return out


def stand_models(profile: CalibrationProfile, workflow: StandModel, world: Any,
                 compare: bool) -> dict[str, StandModel]:
    """The study's stand models fitted to seed 0's calibration (module docstring); the workflow's alone
    without ``compare``."""
    obs = observations(profile)
    fitted = fit_stand(obs, workflow).model
    if not compare:
        return {WORKFLOW: fitted}
    return {"nominal": StandModel(), FITS[0]: fit_stand(obs, StandModel()).model,
            FITS[1]: fit_stand(obs, StandModel(), camera_shape=False).model, WORKFLOW: fitted,
            "world": world_model(world)}


# ---- the study ------------------------------------------------------------------------------------------------
def preset_of(lights: np.ndarray, name: str, mode: str) -> Preset:
    from dualrgb.simulation.lightsource import LightSource

    sources = tuple(LightSource(tuple(int(k) + 1 for k in np.flatnonzero(w)), tuple(float(w[k]) for k in
                                                                                 np.flatnonzero(w)), f"source {i}")
                    for i, w in enumerate(lights, start=1))
    return Preset(name, sources, method="study stand", mode=mode)


def reoptimised_lights(models: dict[str, StandModel], mode: str, incumbent: Any = None,
                       progress: ProgressCallback | None = None) -> dict[str, np.ndarray]:
    """The lights (L, n_leds) re-optimised on each model (app.workflow.stand_reoptimise.reoptimise: the default
    optimiser and objective on the model's sphere, the calibration's lights ``incumbent`` kept where nothing
    better is found, as ``simulate --stand`` does), keyed 're-optimised: <model>'."""
    from dualrgb.app.workflow.stand_reoptimise import reoptimise

    out = {}
    for i, (name, model) in enumerate(models.items()):
        report(progress, i / len(models), f"optimising on the {name} model")
        result = reoptimise(model, mode, top=1, incumbents=[incumbent] if incumbent else ())
        out[f"re-optimised: {name}"] = np.stack([s.weights() for s in result.preset().sources])
    return out


def capture_lights(cfg: StandStudyConfig, world: str, lights: dict[str, np.ndarray], folder: Path,
                   done: dict[str, list[CalibrationProfile]], progress: ProgressCallback | None = None,
                   cancel: CancelToken | None = None) -> dict[str, list[CalibrationProfile]]:
    """Each light set calibrated in ``world`` with every seed; a set with the same levels as another (the lights in
    use kept by a re-optimisation: one in ``done``) takes that one's calibrations instead of new ones."""
    first: dict[bytes, str] = {np.round(lights[n], 12).tobytes(): n for n in done if n in lights}
    alias: dict[str, str] = {}
    for name in lights:
        alias[name] = first.setdefault(np.round(lights[name], 12).tobytes(), name)
    out = dict(done)
    jobs = [(name, seed) for name in lights if alias[name] == name and name not in done for seed in cfg.seeds]
    for i, (name, seed) in enumerate(jobs):
        check(cancel)
        report(progress, i / max(len(jobs), 1), f"{world}: capturing {name}, seed {seed}")
        slug = "".join(c if c.isalnum() else "-" for c in name).strip("-")
        out.setdefault(name, []).append(calibrate_in_world(
            cfg, world, preset_of(lights[name], f"study stand: {name}", cfg.mode), seed, folder / f"{slug}-seed{seed}"))
    return {**out, **{name: out[alias[name]] for name in lights}}


def nominal_preset(cfg: StandStudyConfig) -> Preset:
    """The study's nominal preset: ``cfg.preset`` (a packaged name or a file), else the mode's default."""
    from dualrgb.app.workflow.defaults import default_preset_name
    from dualrgb.simulation.presets import load_preset, packaged_presets

    name = cfg.preset or default_preset_name(cfg.mode)
    if Path(name).suffix == ".json":
        return load_preset(name)
    return load_preset(next(p for p in packaged_presets() if p.stem == name))


def world_study(cfg: StandStudyConfig, name: str, folder: Path, progress: ProgressCallback | None = None,
                cancel: CancelToken | None = None) -> WorldStudy:
    """The study (module docstring) in one world, its sessions and measurements in ``folder``."""
    from dualrgb.app.workflow.stand_reoptimise import Measurements, assemble, calibration_lights
    from dualrgb.drivers.virtual.world import load_world

    t0, world, preset = time.perf_counter(), load_world(name), nominal_preset(cfg)
    report(progress, 0.0, f"{world.name}: measuring the LEDs and the camera")
    stand_dir = measure_leds(name, folder)
    csrf = measure_camera(cfg, name, folder)
    start = assemble(None, Measurements.of(csrf, None, stand_dir))[0]
    levels = np.stack([s.weights() for s in preset.sources])
    done = capture_lights(cfg, name, {PRESET: levels}, folder, {}, scaled(progress, 0.05, 0.35), cancel)
    profile = done[PRESET][0]
    compare = name in cfg.compare or world.name in cfg.compare
    models = stand_models(profile, start, world, compare)
    chosen = {k: models[k] for k in ((*FITS, WORKFLOW, "world") if compare else (WORKFLOW,))}
    lights = {PRESET: lights_of(profile), **reoptimised_lights(chosen, cfg.mode, calibration_lights(profile),
                                                               scaled(progress, 0.35, 0.45))}
    captured = capture_lights(cfg, name, lights, folder, done, scaled(progress, 0.45, 1.0), cancel)
    out = WorldStudy(world.name, world.identity)
    out.models = model_figures(models, observations(profile), lights[PRESET], cfg.mode, calibration_capture(profile),
                               captured_de(captured[PRESET]))
    out.lights = {k: {"levels": lights[k].tolist(), "captured": captured_de(v),
                      "calibrations": [str(p.path) for p in v]} for k, v in captured.items()}
    reopt = workflow_figures(captured[REOPTIMISED], start, cfg.mode)
    reopt["model_predicted"] = expected_de00(models[WORKFLOW], cfg.mode, lights[REOPTIMISED],
                                             calibration_capture(profile))
    reopt["preset_kept"] = bool(np.allclose(lights[REOPTIMISED], lights[PRESET], atol=1e-12))
    out.workflow = {"preset": workflow_figures(captured[PRESET], start, cfg.mode), "re-optimised": reopt,
                    "start": start.to_dict()}
    out.files = {"csrf": str(csrf), "stand_dir": str(stand_dir), "calibration": str(profile.path)}
    out.elapsed_s = time.perf_counter() - t0
    log.info("study stand, %s: %.0f s", world.name, out.elapsed_s)
    return out


def stand_study(cfg: StandStudyConfig, folder: Path, progress: ProgressCallback | None = None,
                cancel: CancelToken | None = None) -> StandStudy:
    """Run the study (module docstring) in every world of ``cfg``, each in ``folder / <world>``."""
    t0, study = time.perf_counter(), StandStudy(cfg)
    n = len(cfg.worlds)
    for i, name in enumerate(cfg.worlds):
        check(cancel)
        world = world_study(cfg, name, Path(folder) / Path(name).stem, scaled(progress, i / n, (i + 1) / n), cancel)
        study.worlds[world.world] = world
    study.elapsed_s = time.perf_counter() - t0
    report(progress, 1.0, "stand study done")
    return study
