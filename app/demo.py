"""The whole workflow, headless, on the virtual lab (``dualrgb demo``; Qt-free so the GUI can run it too).

It holds no processing of its own: captures run through app.workflow.copystand.CopyStand and the sequences,
processing through app.workflow.session_processing.process_session, exactly as the GUI and the CLI do.

presets from the optimiser on the expected captured error of this capture (exhaustive = dual-RGB, the default
successive-halving PSO = dual-RGB-PSO, realisable NNLS D65 mix = 3-channel baseline)
-> the sphere emulator on a real pty + the virtual camera -> auto-exposure on the open gate -> (HDR plan on
the ND-covered target) -> dark series at every exposure -> open-gate flats -> train and test captures ->
master darks, eq 7.1 flat field / eq 8.9 HDR merge -> per-light superpixel images stacked to N channels ->
patch means (PatchGrid on the target's corners) -> characterisation (least squares and dE00-optimised) and the
spectral estimate (app.processing.spectral: its test RMSE, GFC and dE00 under other lights beside the colour
figures) -> report.json, and per condition a folder with its report.json, PNG figures and CSVs. The mode's
virtual original (the painting, or the film) is captured too, under the default lights (dual-RGB-PSO), and its
stack, mapped by that condition's matrix and spectral estimator, is compared per pixel with the original's truth:
report.json's ``original`` holds dE00 and spectral RMSE (mean, p90, per material, over edges and flat regions;
app.lab.truth) at half resolution (2x2 cells), ``original_full`` the same at the sensor's full
resolution (the frames demosaiced: app.processing.masters), from the same frames.
"""
from __future__ import annotations

import dataclasses
import logging
import time
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.lab.targets import scene_grid, virtual_target_spec
from dualrgb.app.processing.characterise import LEAST_SQUARES
from dualrgb.app.processing.quality import quality_summary
from dualrgb.app.sequences.calibration import DarkSeries, FlatSeries
from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.app.sequences.hdr import HdrPlan
from dualrgb.app.session.capture_session import CaptureSession, atomic_write
from dualrgb.app.session.log import SessionLog
from dualrgb.app.session.manifest import camera_definition, image_area_definition, light_definition
from dualrgb.app.workflow.copystand import CopyStand, StandSettings
from dualrgb.app.workflow.defaults import DEFAULT_MODE, VIRTUAL_FRAME_SIZE, VIRTUAL_ORIGINALS, workflow_defaults
from dualrgb.app.workflow.folders import open_session
from dualrgb.app.workflow.metering import HdrMetering
from dualrgb.app.workflow.session_processing import process_session
from dualrgb.app.workflow.targets import nd_transmittance, reference_white
from dualrgb.app.workflow.vocabulary import NamedLight, Subject, lights_of
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report, scaled
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.drivers.virtual.lab import VirtualLab
from dualrgb.drivers.virtual.world import load_world
from dualrgb.simulation.camera_model import channel_responses
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.objective import ErrorStats
from dualrgb.simulation.presets import Preset, save_preset
from dualrgb.simulation.runner import run as run_simulation
from dualrgb.simulation.versions import output_header

log = logging.getLogger(__name__)

REPORT_FORMAT = "dualrgb-demo-report/1"

CONDITIONS = ("three_channel", "dual_rgb", "dual_rgb_pso")
ORIGINAL_CONDITION = "dual_rgb_pso"       # the default lights: the virtual original is captured under them


def _darks() -> int:
    return workflow_defaults().dark_frames


def _flats() -> int:
    return workflow_defaults().flat_frames


@dataclass
class DemoSettings:
    out: Path
    mode: str = DEFAULT_MODE
    hdr: bool = False
    frame_size: tuple[int, int] = VIRTUAL_FRAME_SIZE
    seed: int = 0
    dark_frames: int = field(default_factory=_darks)       # app.workflow.defaults, as calibrate and the GUI
    flat_frames: int = field(default_factory=_flats)
    settle_s: float = 0.05
    optimise_matrix: bool | None = None   # also fit the dE00-optimised matrix; None: the parsimony study's choice
    conditions: tuple[str, ...] = CONDITIONS
    new_session: bool = False                # a session made with other settings: use a new one, not refuse
    world: str | None = None                 # what the virtual lab renders (drivers.virtual.world; None nominal)
    charts: dict[str, Any] = field(default_factory=dict)   # the stand's own charts (app.workflow.charts.load_charts)

    def optimise(self) -> bool:
        """Whether the dE00-optimised matrix is fitted too (``optimise_matrix``, else the mode's default)."""
        if self.optimise_matrix is None:
            return workflow_defaults(self.mode).optimise_matrix
        return self.optimise_matrix

    def definition(self) -> dict:
        """What defines this run's frames (app.session: a resume with anything else is refused)."""
        from dualrgb.app.workflow.charts import definition as chart_definition

        return {"workflow": "demo", "mode": self.mode, "frame_size": list(self.frame_size), "seed": self.seed,
                "hdr": self.hdr, "dark_frames": self.dark_frames, "flat_frames": self.flat_frames,
                "settle_s": self.settle_s, "conditions": list(self.conditions),
                "world": load_world(self.world).identity, **chart_definition(self.charts)}

    def setup(self) -> Any:
        """The packaged data of the mode with the charts' reference data as its training and test targets (what
        the optimiser chooses the lights on and the virtual lab renders)."""
        from dualrgb.simulation.datasets import default_setup

        setup = default_setup(self.mode)
        own = {role: chart.reference() for role, chart in self.charts.items()}
        return dataclasses.replace(setup, **own) if own else setup


@dataclass
class Condition:
    name: str
    lights: list[NamedLight]
    simulated: dict = field(default_factory=dict)
    exposure: dict[str, float] = field(default_factory=dict)        # base (open-gate) exposure per light
    hdr_plan: dict[str, HdrPlan] = field(default_factory=dict)


def demo_capture_model(settings: DemoSettings):
    """The capture this demo makes, for the expected-captured objective: its frames' patch sizes (superpixels
    the demo's patch grid averages, median over patches), its dark and flat frame counts, the virtual lab's
    sensor, exact references (the virtual lab renders the spectra the reference XYZ come from)."""
    from dataclasses import replace

    from dualrgb.drivers.virtual.scene import Scene
    from dualrgb.simulation.capture_model import CaptureModel

    setup = settings.setup()
    width, height = (int(v) // 2 * 2 for v in settings.frame_size)
    pixels = []
    for role, target in (("train", setup.train), ("test", setup.test)):
        chart = settings.charts.get(role)
        scene = Scene.with_target(chart.render_target() if chart is not None else target, width=width, height=height)
        counts = scene_grid(scene).sample(np.zeros((height // 2, width // 2, 1))).count[:scene.n_patches]
        pixels.append(max(1, int(np.median(counts))))
    cap = CaptureModel.virtual_lab(settings.mode)
    return replace(cap, camera=replace(cap.camera, pixels_per_patch=pixels[0], dark_frames=settings.dark_frames,
                                       flat_frames=settings.flat_frames), test_pixels_per_patch=pixels[1])


def make_conditions(settings: DemoSettings, progress: ProgressCallback | None = None) -> tuple[list[Condition], dict]:
    """Presets from the optimiser (#2) on the expected captured error of this demo's capture (#14), and what it
    predicts for them: expected captured errors per characterisation, with the noise-free ones beside them."""
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
    from dualrgb.simulation.runner import DEFAULT_METHOD
    from dualrgb.simulation.sphere import realisable_d65_mix
    setup = settings.setup()
    ev = ExpectedErrorEvaluator(setup, demo_capture_model(settings))
    presets = {}
    report(progress, 0.0, "optimiser: exhaustive search (expected captured error)")
    presets["dual_rgb"] = run_simulation(setup, "exhaustive", top=1, evaluator=ev,
                                         progress=scaled(progress, 0.0, 0.02)).preset(
        name=f"dual-RGB {settings.mode}")
    report(progress, 0.02, f"optimiser: {DEFAULT_METHOD} PSO (expected captured error)")
    presets["dual_rgb_pso"] = run_simulation(setup, DEFAULT_METHOD, seed=settings.seed, top=1, evaluator=ev,
                                             progress=scaled(progress, 0.02, 0.1)).preset(
        name=f"dual-RGB-PSO {settings.mode}")
    mix, duv = realisable_d65_mix(setup.leds, setup.illuminant, setup.cmfs, ev.capture.sphere)
    presets["three_channel"] = Preset("3-channel D65 mix", (mix,), method="nnls-d65", mode=settings.mode,
                                      model={"duv_to_d65": duv})
    out = []
    for name in settings.conditions:
        p = presets[name]
        W = np.stack([s.weights(ev.n_leds) for s in p.sources])
        out.append(Condition(name, lights_of(p), _predictions(ev, W, settings.optimise_matrix)))
        save_preset(p, settings.out / "presets" / f"{name}.json")
    return out, {k: v.to_dict() for k, v in presets.items()}


def _predictions(ev, W: np.ndarray, de_matrix: bool | None) -> dict:
    """What the optimiser predicts for a light set, per characterisation the processing may deliver: the
    expected captured error of the least-squares matrix (the objective) and, for the dE00-optimised matrix and the
    root-polynomials, that minus the model's noise-free gain over least squares (fitted on the noise-free simulated
    training values); the noise-free figures beside them, and the least-squares matrix per pixel (``per_pixel``:
    mean and p90 of one pixel of each patch, simulation.expected_error)."""
    from dualrgb.app.processing.characterise import (
        DE2000,
        LEAST_SQUARES,
        ROOT_POLYNOMIAL_2,
        ROOT_POLYNOMIAL_3,
        fit_de2000,
    )
    from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
    from dualrgb.simulation.matrix_fit import fit_root_polynomial

    tr, te = ev.stats(W)
    etr, ete = ev.expected_stats(W)
    px = ev.pixel_stats(W)
    out = {LEAST_SQUARES: {"train": round(etr.mean, 4), "test": round(ete.mean, 4)},
           "noise_free": {"train": round(tr.mean, 4), "test": round(te.mean, 4)},
           "per_pixel": {k: {"mean": px[k]["mean"], "p90": px[k]["p90"]} for k in ("train", "test")}}
    values = {k: ps.camera_values(W) for k, ps in (("train", ev.train), ("test", ev.test))}
    fits = {ROOT_POLYNOMIAL_2: lambda: fit_root_polynomial(values["train"], ev.train.xyz, 2),
            ROOT_POLYNOMIAL_3: lambda: fit_root_polynomial(values["train"], ev.train.xyz, 3)}
    if de_matrix is not False:
        fits[DE2000] = lambda: fit_de2000(values["train"], ev.train.xyz, ev.train.white)
    for name, fit in fits.items():
        model = fit()
        gain = {k: float(e.mean) - float(delta_e_2000(ps.lab, xyz_to_lab(model.apply(values[k]), ps.white)).mean())
                for k, e, ps in (("train", tr, ev.train), ("test", te, ev.test))}
        out[name] = {"train": round(etr.mean - gain["train"], 4), "test": round(ete.mean - gain["test"], 4)}
    return out


def _planned_condition(lights: list, mode: str) -> float | str:
    """The lights' condition number from the camera model (app.workflow.preflight), as the plan checks it."""
    from dualrgb.app.workflow.preflight import light_set_conditioning

    cond, _ = light_set_conditioning(lights, mode)
    return round(cond, 2) if np.isfinite(cond) else "inf"


class DemoRun:
    """State of one demo run; ``run()`` returns the report dict. Capture and processing go through the copy-stand
    workflow (app.workflow): the same sequences, subjects and ``process_session`` as the GUI and the CLI."""

    def __init__(self, settings: DemoSettings, progress: ProgressCallback | None = None,
                 cancel: CancelToken | None = None):
        self.s = settings
        self.progress = progress
        self.cancel = cancel
        self.t0 = time.perf_counter()

    def run(self) -> dict:
        s = self.s
        if s.dark_frames < 1 or s.flat_frames < 1 or min(s.frame_size) < 64 or s.seed < 0:   # before any shot
            raise ValueError(f"demo settings: dark frames {s.dark_frames}, flat frames {s.flat_frames}, frame size "
                             f"{s.frame_size}, seed {s.seed}: expected >= 1, >= 1, >= 64 px, >= 0")
        s.optimise_matrix = s.optimise()
        s.out.mkdir(parents=True, exist_ok=True)
        session = open_session(s.out / "session", s.definition(), meta={"mode": s.mode, "demo": True},
                               new_if_different=s.new_session,
                               hint="resume with the same options, or pass --new-session or another --out")
        try:
            with SessionLog(session.path):           # the session folder's session.log
                return self._run(session)
        finally:
            session.close()

    def _run(self, session: CaptureSession) -> dict:
        s = self.s
        conds, presets = make_conditions(s, self.progress)
        report(self.progress, 0.1, "starting the virtual lab")
        with VirtualLab(mode=s.mode, frame_size=s.frame_size, seed=s.seed, world=s.world) as lab:
            camera, sphere = lab.devices()
            session.extend_definition(camera=camera_definition(camera), **image_area_definition(camera),
                                      lights={c.name: [light_definition(nl.light, nl.name) for nl in c.lights]
                                              for c in conds})
            for role, chart in s.charts.items():                # the stand's own charts on the virtual stand
                lab.use_chart(role, chart.render_target())
            stand = CopyStand(camera, sphere, session, stand=lab.place, cancel=self.cancel,
                              settings=StandSettings(settle_s=s.settle_s, dark_frames=s.dark_frames,
                                                     flat_frames=s.flat_frames, optimise_matrix=s.optimise_matrix,
                                                     charts=dict(s.charts)),
                              progress=lambda f, m: report(self.progress, 0.1 + 0.5 * f, m))
            self.lab, self.session = lab, session
            exposures = stand.engine.run(lambda: self.capture(stand, conds))      # one run: dark to dark
            report(self.progress, 0.6, "captures done; processing")
            session.require_intact()             # a damaged frame is named, never processed
            result = self.process(conds)
        return self.write_report(session, conds, presets, exposures, result)

    def capture(self, stand: CopyStand, conds: list[Condition]) -> dict[str, list[float]]:
        """Auto-exposure, HDR plans on the ND-covered training target, darks, flats, train and test targets: every
        plan through the stand's run engine."""
        lab, s, facts = self.lab, self.s, stand.facts
        for c in conds:
            c.exposure = stand.auto_expose(c.lights)
            if s.hdr and c.name != "three_channel":
                metering = HdrMetering(facts, c.lights, c.exposure, Subject.target("train", nd=True),
                                       lab.scene_for("train", nd=True).patch_boxes())
                stand.run_sequence(metering, 0.1, 0.2)
                c.hdr_plan = metering.plans
        exposures = {nl.name: sorted({c.exposure[nl.name], *(c.hdr_plan[nl.name].exposures if c.hdr_plan else [])})
                     for c in conds for nl in c.lights}
        self.session.extend_definition(exposures=exposures)
        all_lights = [nl for c in conds for nl in c.lights]
        stand.run_sequence(DarkSeries(facts, sorted({t for ts in exposures.values() for t in ts}),
                                      frames=s.dark_frames), 0.2, 0.4)
        stand.run_sequence(FlatSeries(facts, all_lights, exposures, frames=s.flat_frames), 0.4, 0.6)
        for c in conds:
            for target in ("train", "test"):
                stand.run_sequence(SubjectCapture(facts, c.lights, {n: [t] for n, t in c.exposure.items()},
                                                  Subject.target(target)), 0.6, 0.8)
                if c.hdr_plan:
                    stand.run_sequence(SubjectCapture(facts, c.lights, {n: p.exposures for n, p in
                                                                                c.hdr_plan.items()},
                                                      Subject.target(target, nd=True)), 0.8, 1.0)
            if c.name == ORIGINAL_CONDITION:
                stand.run_sequence(SubjectCapture(facts, c.lights, {n: [t] for n, t in c.exposure.items()},
                                                  self.original_subject()), 0.8, 1.0)
        return exposures

    def original_subject(self) -> Subject:
        """The mode's virtual original (its name is its identifier: the lab places 'original:painting')."""
        return Subject.original(VIRTUAL_ORIGINALS[self.s.mode])

    def write_report(self, session: CaptureSession, conds: list[Condition], presets: dict, exposures: dict,
                     result: dict) -> dict:
        s = self.s
        verify = session.verify()
        report_data = {
            **output_header(REPORT_FORMAT),
            "mode": s.mode, "frame_size": list(s.frame_size), "hdr": s.hdr,
            "world": {"identity": load_world(s.world).identity, **load_world(s.world).to_dict()},
            "charts": {role: chart.record() for role, chart in s.charts.items()},   # {}: the packaged targets
            "conditions": [k for k in result if not k.startswith("original")],   # figures: top-level keys
            **result,
            "presets": presets,
            "exposures": exposures,
            "frames": len(session.entries()),
            "lost_frames": len(verify.missing) + len(verify.corrupted),
            "session_valid": verify.valid,
            "light_dose": session.light_dose().to_dict(),      # the manifest's: a resumed run's whole dose
            "elapsed_s": round(time.perf_counter() - self.t0, 2),
            "session": str(session.path),
        }
        atomic_write(s.out / "report.json", (strict_dumps(report_data, indent=2, default=_json) + "\n").encode())
        report(self.progress, 1.0, f"report written: {s.out / 'report.json'}")
        return report_data

    # ---- processing: app.workflow.session_processing.process_session, as the GUI and `dualrgb process` ----
    def variants(self, c: Condition) -> list[tuple[str, bool, dict[str, list[float]]]]:
        """(label, ND subject, exposures per light): the plain capture, and with HDR the bracket and its single
        base exposure (the thesis 8.3 comparison)."""
        base = {nl.name: [c.exposure[nl.name]] for nl in c.lights}
        out = [(c.name, False, base)]
        if c.hdr_plan:
            out += [("hdr_" + c.name, True, {n: p.exposures for n, p in c.hdr_plan.items()}),
                    ("single_" + c.name, True, base)]
        return out

    def process(self, conds: list[Condition]) -> dict:
        out: dict = {}
        self.results: dict = {}
        for c in conds:
            for label, nd, ts in self.variants(c):
                check(self.cancel)
                out[label] = self.process_variant(c, label, nd, ts)
        c = next(c for c in conds if c.name == ORIGINAL_CONDITION)
        out["original"] = self.assess_original(c, self.results[c.name])
        out["original_full"] = self.assess_original(c, self.results[c.name], full=True)
        return out

    def assess_original(self, c: Condition, res, full: bool = False) -> dict:
        """The virtual original's channels (captured under ``c``'s lights; ``full``: at the sensor's resolution,
        else on the 2x2 cells) through ``c``'s matrix and spectral estimator, per pixel against the original's truth
        (app.lab.truth)."""
        from dualrgb.app.lab.truth import compare, original_truth
        from dualrgb.app.workflow.copystand import channels_of
        from dualrgb.app.workflow.session_processing import select_lights, session_frames

        subject = self.original_subject()
        frames = session_frames(self.session).subject(subject)
        with closing(channels_of(res.processor, select_lights(frames, [nl.name for nl in c.lights]),
                                 "full" if full else "half", self.cancel)) as source:
            H, _ = source.shape
            data = np.concatenate([source.band(r0, min(256, H - r0)).copy() for r0 in range(0, H, 256)])
        ch = res.characterisation
        truth = original_truth(subject.name, self.lab.height, self.lab.width, self.s.mode)
        spectra = None
        if res.spectral is not None:
            spectra = res.spectral.estimator.apply(data)
            truth = truth.on_wavelengths(res.spectral.estimator.wavelengths)
        figures = compare(truth, ch.results[ch.best].matrix.apply(data), spectra)
        return {**figures, "condition": c.name, "matrix": ch.best, "frames_per_exposure": 1,
                "spectral_method": res.spectral.selection.chosen.label() if res.spectral is not None else None}

    def process_variant(self, c: Condition, label: str, nd: bool, ts: dict[str, list[float]]) -> dict:
        specs = {t: virtual_target_spec(self.lab, Subject.target(t, nd), label=f"{t} ({label})",
                                        chart=self.s.charts.get(t)) for t in ("train", "test")}
        scene = self.lab.scene_for("train", nd=nd)
        specs["train"].simulated = self._simulated_values(
            c, nd_transmittance(specs["train"].nd_mask, scene.nd_transmittance, scene.n_patches))
        res = process_session(self.session, self.s.out / label, specs["train"], specs["test"],
                              lights=[nl.name for nl in c.lights], exposures=ts, optimise=self.s.optimise(),
                              white_xyz=reference_white(self.s.mode), title=f"{label} ({self.s.mode}, virtual lab)",
                              cancel=self.cancel, mode=self.s.mode)
        self.results[label] = res
        ch = res.characterisation
        best = ch.results[ch.best]
        sim = c.simulated.get(ch.best, c.simulated[LEAST_SQUARES])      # the prediction for the delivered matrix
        entry = {"train": best.train.to_dict(), "test": best.stats("test").to_dict(),
                 "simulated": {**sim, "matrix": ch.best, "noise_free_train": c.simulated["noise_free"]["train"],
                               "noise_free_test": c.simulated["noise_free"]["test"], "per_matrix": c.simulated},
                 "matrix_method": ch.best,
                 "methods": {k: {"train": v.train.mean, "test": v.stats("test").mean} for k, v in ch.results.items()},
                 "per_pixel": {k: {"mean": v.mean, "p90": v.p90} for k, v in best.pixels.items()},
                 "models": ch.model_table(), "noise_gain": best.noise_gain(),
                 "condition_number": ch.to_dict()["condition_number"],
                 "condition_number_planned": _planned_condition(c.lights, self.s.mode),
                 "lights": [{"name": nl.name, **nl.light.to_dict(), "exposures_s": ts[nl.name]} for nl in c.lights],
                 "report": str(res.files["report"]), "figures": res.report.get("figures", []),
                 "quality": quality_summary(res.report["quality"]),
                 "spectral": res.spectral.summary() if res.spectral is not None else None}
        if nd:
            entry["nd_patches"] = {
                "train": ErrorStats.of(best.train_errors[specs["train"].nd_mask]).to_dict(),
                "test": ErrorStats.of(best.errors("test")[specs["test"].nd_mask]).to_dict()}
            entry["hdr_plan"] = {n: p.to_dict() for n, p in c.hdr_plan.items()}
        return entry

    def _simulated_values(self, c: Condition, transmittance: np.ndarray) -> np.ndarray:
        """Simulated camera values of the training patches under the condition's lights (thesis Fig 7.4)."""
        setup = self.s.setup()
        lights = np.stack([nl.light.spectrum(setup.leds) for nl in c.lights])
        spectra = setup.train.spectra * transmittance[:, None]     # the scene's ND filter, per patch
        return channel_responses(lights, spectra, setup.camera)


def _json(obj):
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, LightSource):
        return obj.to_dict()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def run_demo(settings: DemoSettings, progress: ProgressCallback | None = None,
             cancel: CancelToken | None = None) -> dict:
    return DemoRun(settings, progress, cancel).run()
