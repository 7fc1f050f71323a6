"""``dualrgb study stand``: does fitting the model to the stand pay, in a world that is not the nominal model?

On the virtual lab in a world (default ``mismatched-d700``: another measured camera, LED peaks +-3 nm, 0.5 % flare):

1. calibrate with the mode's nominal preset (the calibration fits the stand model from the nominal camera,
   app/workflow/stand_calibration.py) and measure the camera with the monochromator sweep in the same world
   (app/workflow/csrf.py);
2. stand models: nominal; fitted from the nominal camera (LED outputs and peaks, gains, flare) without and with its
   curves' shift and width; fitted from the measured camera (app/workflow/stand_reoptimise.py refits from the
   profile's observations); and the world itself (its true camera, LEDs and flare);
3. each model's R^2 against the captured patch DNs (training target: fitted; test target: checked) and its
   predicted mean CIEDE2000 of the test target for the preset's lights beside the captured one;
4. lights re-optimised on each fitted model and on the world (the world's optimum), with the same optimiser and
   objective as ``dualrgb simulate``, each captured in the world with every seed (a calibration per light set and
   seed: least-squares matrix, as the objective), against the nominal preset.

Writes ``stand.json``, ``study_stand.png`` and ``SUMMARY.md``.
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.workflow.profile import CalibrationProfile
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report, scaled
from dualrgb.simulation.stand_fit import StandObservations, expected_de00, fit_stand, predict, r2_per_channel
from dualrgb.simulation.stand_model import StandModel, StandParameters

log = logging.getLogger(__name__)

FORMAT = "dualrgb-study-stand/1"
FITS = ("fitted, nominal camera", "fitted, nominal camera, LEDs only", "fitted, measured camera")


@dataclass(frozen=True)
class StandStudyConfig:
    world: str = "mismatched-d700"
    mode: str = "reflective"
    frame_size: tuple[int, int] = (600, 400)
    seeds: tuple[int, ...] = (0, 1, 2)
    preset: str | None = None                 # the nominal preset (default: the mode's, app.workflow.defaults)
    csrf_step_nm: float = 10.0
    csrf_frame_size: tuple[int, int] = (240, 160)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass
class StandStudy:
    config: StandStudyConfig
    models: dict[str, dict[str, Any]] = field(default_factory=dict)      # R^2, predicted vs captured
    lights: dict[str, dict[str, Any]] = field(default_factory=dict)      # captured per light set
    files: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "config": self.config.to_dict(), "models": self.models, "lights": self.lights,
                "files": self.files}


def world_model(world: Any) -> StandModel:
    """The stand model that is the world itself (drivers.virtual.world.World): its camera, LEDs and flare."""
    return StandModel(camera_csv=str(world.camera_path),
                      params=StandParameters(led_output_scale=tuple(world.led_output_scale),
                                             led_peak_shift_nm=tuple(world.led_peak_shift_nm),
                                             led_width_scale=tuple(world.led_width_scale), flare=float(world.flare)),
                      sources={"world": world.identity})


# ---- the virtual lab's part ---------------------------------------------------------------------------------
def calibrate_in_world(cfg: StandStudyConfig, preset: Any, seed: int, folder: Path) -> CalibrationProfile:
    """A calibration (``hdr off``) in the study's world with ``preset``'s lights, in session ``folder``."""
    from dualrgb.app.session.capture_session import CaptureSession
    from dualrgb.app.workflow.copystand import CopyStand, StandSettings
    from dualrgb.drivers.virtual.lab import VirtualLab
    from dualrgb.drivers.virtual.world import load_world

    definition = {"workflow": "study stand", "preset": preset.name, "seed": seed, "mode": cfg.mode,
                  "frame_size": list(cfg.frame_size), "world": load_world(cfg.world).identity}
    with VirtualLab(mode=cfg.mode, frame_size=cfg.frame_size, seed=seed, world=cfg.world) as lab:
        session = CaptureSession.resume(folder, definition, {"mode": cfg.mode})
        try:
            stand = CopyStand(*lab.devices(), session, stand=lab.place, lab=lab,
                              settings=StandSettings(settle_s=0.0, optimise_matrix=False))
            return stand.calibrate(preset, hdr_auto=False)
        finally:
            session.close()


def measure_camera(cfg: StandStudyConfig, folder: Path) -> Path:
    """The camera CSV the monochromator sweep measures in the study's world (thesis 4.2)."""
    from dualrgb.app.sequences.csrf import CsrfSettings
    from dualrgb.app.session.capture_session import CaptureSession
    from dualrgb.app.workflow.csrf import measure_csrf
    from dualrgb.drivers.virtual.monochromator_bench import MonochromatorBench
    from dualrgb.simulation.radiance_reference import read_radiance_reference

    settings = CsrfSettings(380.0, 780.0, cfg.csrf_step_nm)
    with MonochromatorBench(frame_size=cfg.csrf_frame_size, world=cfg.world) as bench:
        session = CaptureSession.resume(folder / "csrf-session", {**settings.definition(), "world": cfg.world},
                                        {"measurement": "csrf"})
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
    return m.path


# ---- the models -----------------------------------------------------------------------------------------------
def _captured_de(profiles: list[CalibrationProfile]) -> dict[str, Any]:
    """Mean captured CIEDE2000 (least squares) of calibrations of one light set: mean over seeds, and each."""
    per = [(p.statistics["methods"]["least-squares"]["train"]["mean"],
            p.statistics["methods"]["least-squares"]["test"]["mean"]) for p in profiles]
    a = np.array(per)
    return {"train": float(a[:, 0].mean()), "test": float(a[:, 1].mean()),
            "train_each": [float(v) for v in a[:, 0]], "test_each": [float(v) for v in a[:, 1]]}


def model_figures(models: dict[str, StandModel], obs: StandObservations, levels: np.ndarray, mode: str,
                  capture: Any, captured: dict[str, Any]) -> dict[str, dict[str, Any]]:
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


def stand_models(profile: CalibrationProfile, csrf: Path, world: Any) -> dict[str, StandModel]:
    """The study's stand models (module docstring, step 2)."""
    from dualrgb.app.workflow.stand_reoptimise import Measurements, assemble

    obs = profile.stand_observations
    if obs is None:
        raise ValueError(f"calibration {profile.id}: no stand observations")
    return {"nominal": StandModel(), FITS[0]: assemble(profile)[0],
            FITS[1]: fit_stand(obs, StandModel(), camera_shape=False).model,
            FITS[2]: assemble(profile, Measurements.of(camera_csv=csrf))[0], "world": world_model(world)}


# ---- the study ------------------------------------------------------------------------------------------------
def _preset_of(lights: np.ndarray, name: str, mode: str) -> Any:
    from dualrgb.simulation.lightsource import LightSource
    from dualrgb.simulation.presets import Preset

    sources = tuple(LightSource(tuple(int(k) + 1 for k in np.flatnonzero(w)), tuple(float(w[k]) for k in
                                                                                 np.flatnonzero(w)), f"source {i}")
                    for i, w in enumerate(lights, start=1))
    return Preset(name, sources, method="study stand", mode=mode)


def reoptimised_lights(models: dict[str, StandModel], mode: str, capture: Any, incumbent: Any = None,
                       progress: ProgressCallback | None = None) -> dict[str, np.ndarray]:
    """The lights (L, n_leds) re-optimised on each model (app.workflow.stand_reoptimise.reoptimise: the default
    optimiser and objective, the calibration's lights ``incumbent`` kept where nothing better is found, as
    ``simulate --stand`` does), keyed 're-optimised: <model>'."""
    from dualrgb.app.workflow.stand_reoptimise import reoptimise

    out = {}
    for i, (name, model) in enumerate(models.items()):
        report(progress, i / len(models), f"optimising on the {name} model")
        result = reoptimise(model, mode, top=1, capture=capture, incumbents=[incumbent] if incumbent else ())
        out[f"re-optimised: {name}"] = np.stack([s.weights() for s in result.preset().sources])
    return out


def capture_lights(cfg: StandStudyConfig, lights: dict[str, np.ndarray], folder: Path, first: dict[str, Any],
                   progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                   ) -> dict[str, list[CalibrationProfile]]:
    """Each light set calibrated in the world with every seed (``first``: profiles already made, by name)."""
    out: dict[str, list[CalibrationProfile]] = {}
    jobs = [(name, seed) for name in lights for seed in cfg.seeds]
    for i, (name, seed) in enumerate(jobs):
        check(cancel)
        report(progress, i / len(jobs), f"capturing {name}, seed {seed}")
        made = first.get(name, {}).get(seed)
        slug = "".join(c if c.isalnum() else "-" for c in name).strip("-")
        out.setdefault(name, []).append(made if made is not None else calibrate_in_world(
            cfg, _preset_of(lights[name], f"study stand: {name}", cfg.mode), seed, folder / f"{slug}-seed{seed}"))
    return out


def stand_study(cfg: StandStudyConfig, folder: Path, progress: ProgressCallback | None = None,
                cancel: CancelToken | None = None) -> StandStudy:
    """Run the study (module docstring) in ``folder`` (sessions, the camera CSV); returns its figures."""
    from dualrgb.app.workflow.defaults import default_preset_name
    from dualrgb.app.workflow.stand_reoptimise import calibration_lights
    from dualrgb.drivers.virtual.world import load_world
    from dualrgb.simulation.capture_model import CaptureModel
    from dualrgb.simulation.presets import load_preset, packaged_presets

    folder = Path(folder)
    world = load_world(cfg.world)
    name = cfg.preset or default_preset_name(cfg.mode)
    preset = load_preset(next(p for p in packaged_presets() if p.stem == name) if Path(name).suffix != ".json"
                         else name)
    report(progress, 0.0, f"calibrating with {preset.name} in world {world.name}")
    profile = calibrate_in_world(cfg, preset, cfg.seeds[0], folder / f"preset-seed{cfg.seeds[0]}")
    report(progress, 0.05, "measuring the camera (monochromator sweep)")
    csrf = measure_camera(cfg, folder)
    check(cancel)
    models = stand_models(profile, csrf, world)
    levels = np.stack([nl.light.weights() for nl in profile.lights])
    capture = _calibration_capture(profile)
    lights = {"nominal preset": levels, **reoptimised_lights({k: models[k] for k in (*FITS, "world")}, cfg.mode,
                                                             CaptureModel.virtual_lab(cfg.mode),
                                                             calibration_lights(profile), scaled(progress, 0.1, 0.15))}
    captured = capture_lights(cfg, lights, folder, {"nominal preset": {cfg.seeds[0]: profile}},
                              scaled(progress, 0.15, 0.95), cancel)
    if profile.stand_observations is None:
        raise ValueError(f"{profile.path}: the calibration has no stand observations (its stand fit was not made)")
    study = StandStudy(cfg)
    study.models = model_figures(models, profile.stand_observations, levels, cfg.mode, capture,
                                 _captured_de(captured["nominal preset"]))
    study.lights = {k: {"levels": lights[k].tolist(), "captured": _captured_de(v),
                        "calibrations": [str(p.path) for p in v]} for k, v in captured.items()}
    study.files = {"csrf": str(csrf), "calibration": str(profile.path)}
    report(progress, 1.0, "stand study done")
    return study


def _calibration_capture(profile: CalibrationProfile) -> Any:
    """The expected-captured model of the profile's calibration (its patch sizes and frame counts)."""
    from dualrgb.app.workflow.stand_calibration import calibration_capture

    c = profile.stand.get("capture") or {}
    return calibration_capture(profile.mode, np.array([c.get("train_pixels", 56)]),
                               np.array([c.get("test_pixels", 462)]), int(c.get("dark_frames", 10)),
                               int(c.get("flat_frames", 3)))


# ---- outputs --------------------------------------------------------------------------------------------------
def summary_lines(study: StandStudy) -> list[str]:
    """The study's figures as Markdown tables (SUMMARY.md, README)."""
    cap = next(iter(study.lights.values()))["captured"]
    lines = [f"World `{study.config.world}`, {study.config.frame_size[0]}x{study.config.frame_size[1]} frames, seeds "
             f"{', '.join(map(str, study.config.seeds))}; captured mean dE00 with the least-squares matrix (the "
             "objective's), averaged over the seeds.", "",
             f"The nominal preset's lights: captured test dE00 {cap['test']:.3f} (train {cap['train']:.3f}).", "",
             "| Model | R² train (worst channel) | R² test | predicted test dE00 | miss |",
             "| --- | ---: | ---: | ---: | ---: |"]
    for name, m in study.models.items():
        lines.append(f"| {name} | {m['r2_train']:.5f} | {m['r2_test']:.5f} | {m['predicted']['test']:.3f} | "
                     f"{100 * m['miss']['test']:+.1f} % |")
    base = study.lights["nominal preset"]["captured"]
    world = study.lights.get("re-optimised: world", {}).get("captured")
    lines += ["", "| Lights | captured train dE00 | captured test dE00 | train vs preset | train vs world's optimum |",
              "| --- | ---: | ---: | ---: | ---: |"]
    for name, entry in study.lights.items():
        c = entry["captured"]
        vs_world = f"{100 * (c['train'] / world['train'] - 1):+.1f} %" if world else "-"
        lines.append(f"| {name} | {c['train']:.4f} | {c['test']:.4f} | {100 * (c['train'] / base['train'] - 1):+.1f} % "
                     f"| {vs_world} |")
    return lines


def study_figure(study: StandStudy) -> Any:
    """Left: each model's predicted test dE00 for the preset's lights against the captured one. Right: the
    captured train and test dE00 of each light set (bars: mean over seeds; whiskers: their range)."""
    from dualrgb.simulation.studies.common import new_figure

    fig, (a1, a2) = new_figure(12.0, 4.8, ncols=2)
    names = list(study.models)
    cap = study.lights["nominal preset"]["captured"]["test"]
    a1.bar(range(len(names)), [study.models[n]["predicted"]["test"] for n in names], color="0.6")
    a1.axhline(cap, color="black", lw=1.2, label=f"captured {cap:.3f}")
    a1.set_xticks(range(len(names)), [f"{n}\nR² {study.models[n]['r2_train']:.4f}" for n in names], fontsize=7,
                  rotation=15)
    a1.set_ylabel("test mean ΔE00 (preset's lights)")
    a1.set_title("predicted by each model vs captured")
    a1.legend(fontsize=8)
    lights = list(study.lights)
    x = np.arange(len(lights))
    for off, which, colour in ((-0.2, "train", "#1565c0"), (0.2, "test", "#ef6c00")):
        c = [study.lights[n]["captured"] for n in lights]
        mean = np.array([v[which] for v in c])
        lo = mean - np.array([min(v[f"{which}_each"]) for v in c])
        hi = np.array([max(v[f"{which}_each"]) for v in c]) - mean
        a2.bar(x + off, mean, width=0.4, color=colour, label=which, yerr=[lo, hi], capsize=3)
    a2.set_xticks(x, [n.replace("re-optimised: ", "re-opt.\n") for n in lights], fontsize=7, rotation=15)
    a2.set_ylabel("captured mean ΔE00 (least squares)")
    a2.set_title(f"lights captured in world {study.config.world}")
    a2.legend(fontsize=8)
    return fig


def write_outputs(study: StandStudy, out: Any) -> None:
    """``stand.json``, ``study_stand.png`` and ``SUMMARY.md`` into ``out`` (simulation.studies.common.StudyOutput)."""
    out.write_json("stand.json", study.to_dict())
    out.save_figure(study_figure(study), "study_stand.png")
    out.write_summary("Stand model study", summary_lines(study))
