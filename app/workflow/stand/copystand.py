"""The copy-stand day, Qt-free: calibrate once, then capture and deliver originals with that calibration.

    stand = CopyStand(camera, sphere, session, stand=changer.place, progress=print_progress)
    profile = stand.calibrate(preset, hdr_auto=True)                  # darks, flats, targets, matrix, profile
    report = stand.capture(Original("ACC-123", title="Portrait"), profile)   # metering, HDR if needed, deliver
    print(report.qa.text())

The GUI, the CLI and the demo drive the stand through this object. Every device action runs through the one run
engine (core.engine.RunEngine, ``stand.engine``: its plans yield messages, the engine alone applies them;
each public call is one run, from dark to dark, read back) and reports through plain callbacks: ``progress(fraction,
message)`` and ``on_event(ProgressEvent)`` (every frame saved / kept, every prompt); ``cancel`` (a
common.progress.CancelToken) or ``control`` (the run's RunControl: cancel and pause) stops between frames with
the LEDs off and between the processing's work units, raising common.progress.Cancelled. Hooks for a person:
``prompt(message)`` returns when they have done what it asks (place the target, cap the lens; never called when
a ``stand`` callback places things: an automated sample changer's, drivers.sample_changer) and
``reshoot(original, n_frames)`` answers whether an original already in the session is shot again (True: new frames
under the next take) or kept (False).
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.masters import FULL, check_resolution
from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef, sub_progress
from dualrgb.app.processing.quality import grading_summary
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT, check_illuminant
from dualrgb.app.sequences.base import ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.sequences.calibration import DarkSeries, FlatSeries, snap_down
from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.app.workflow.calibration.charts import definition as chart_definition
from dualrgb.app.workflow.calibration.profile import (
    CalibrationProfile,
    CameraIdentity,
    ProfileError,
    ReuseCheck,
    ReuseLimits,
    SphereIdentity,
    check_reuse,
    new_profile_id,
)
from dualrgb.app.workflow.calibration.session_processing import SessionResult, process_session
from dualrgb.app.workflow.calibration.targets import NdFilter, TargetSpec, reference_white, target_spec
from dualrgb.app.workflow.delivery.deliverables import check_spectral_request
from dualrgb.app.workflow.delivery.delivery import Delivery, LightDoseRecord, Original, deliver
from dualrgb.app.workflow.delivery.delivery_folder import prepare
from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings
from dualrgb.app.workflow.stand.defaults import study_defaults, workflow_defaults
from dualrgb.app.workflow.stand.metering import AutoExposure, HdrMetering
from dualrgb.app.workflow.stand.mode_rule import check_mode
from dualrgb.app.workflow.stand.plans import StandPlanner
from dualrgb.app.workflow.stand.preflight import (
    capture_frames,
    check_capture_space,
    check_conditioning,
    check_exposures,
    check_frame_shape,
    check_lights,
    deliverable_bytes,
)
from dualrgb.app.workflow.stand.run_phases import AUTO_EXPOSURE, DARKS, FLATS, PROCESSING, TARGET_FRAMES
from dualrgb.common.progress import CancelToken, ProgressCallback, report
from dualrgb.core.device_actions import Place, StandDevices
from dualrgb.core.engine import RunControl, RunEngine, facts_of
from dualrgb.core.light_safety import SafetySettings, StandFacts
from dualrgb.core.metadata import check_original
from dualrgb.core.session.paths import record
from dualrgb.core.vocabulary import (
    EventKind,
    NamedLight,
    Role,
    Subject,
    lights_of,
    role_of,
    split_take,
    subject_of,
)

if TYPE_CHECKING:
    from dualrgb.app.processing.masters import MasterFrames
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.app.processing.pipeline import ChannelSource, StackBuilder
    from dualrgb.core.protocols import Session, Sphere
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.simulation.charts import Chart
    from dualrgb.simulation.presets import Preset
    from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

Prompt = Callable[[str], None]
ReshootQuestion = Callable[[Original, int], bool]
EventCallback = Callable[[ProgressEvent], None]


def _dark_frames() -> int:
    return workflow_defaults().dark_frames


def _flat_frames() -> int:
    return workflow_defaults().flat_frames


@dataclass
class StandSettings:
    settle_s: float = SafetySettings().settle_s
    latency_s: float | None = None         # the camera's latency allowance; None: what the camera reports
    max_on_s: float = SafetySettings().max_on_s   # light on per capture at most (thesis 4.3.2: 10 s)
    dark_frames: int = field(default_factory=_dark_frames)     # app.workflow.stand.defaults (thesis 8.2.1: 10)
    flat_frames: int = field(default_factory=_flat_frames)
    hdr_exposures: int | None = None       # most exposures per light; None: resources/parsimony.json
    optimise_matrix: bool | None = None    # also the dE00-optimised matrix; None: resources/parsimony.json
    limits: ReuseLimits = field(default_factory=ReuseLimits)
    force: bool = False                       # reuse a mismatching calibration with a warning
    mode_overrides: frozenset[str] = frozenset()   # originals shot in another mode than the calibration's, asked
    ppi: float | None = None               # sampling set by the user (else from the target's size): calibrate: the
                                           # sensor's (full resolution); capture: the deliverables' as delivered
    target_width_mm: float | None = None   # test target's width (corner patches' outer corners) -> ppi
    meter_tiles: int = 12                     # metering regions across the frame (HDR decision for originals)
    original_frames: int = 1                  # frames averaged per exposure of an original (noise / sqrt(n))
    render_illuminant: str = DEFAULT_RENDER_ILLUMINANT   # the light the spectral rendering is seen under
    resolution: str = FULL                    # originals' deliverables: the sensor's pixels (full) or 2x2 cells
    stand_start: StandModel | None = None     # the stand model the fit starts from (simulation.stand_model; None:
                                              # nominal): measured camera / LEDs (calibrate --camera-csv, --stand-dir)
    charts: dict[str, Chart] = field(default_factory=dict)   # 'train' / 'test' -> the stand's own chart
                                              # (simulation.charts.Chart); absent: the mode's packaged target
    delivery: DeliverySettings | None = None  # what a delivery holds (app.workflow.delivery.delivery_settings; None:
                                              # the file's)
    nd_filter: NdFilter = field(default_factory=NdFilter)   # the stand's ND filter over a target (thesis 8.3)


@dataclass
class CaptureReport:
    original: Original
    new: int
    kept: int
    exposures: dict[str, list[float]]
    delivery: Delivery
    check: ReuseCheck
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> str:
        return f"{self.original.identifier}: {self.new} new, {self.kept} kept; {self.delivery.qa.text()}"


@dataclass
class ShotOriginal:
    """An original whose frames are all in the session and taken into its channels (``builder``), not yet
    delivered: what :meth:`CopyStand.shoot` hands to :meth:`CopyStand.deliver_shot`. ``capture_s``: the seconds
    from its checks to its last frame."""

    original: Original
    profile: CalibrationProfile
    take: int
    exposures: dict[str, list[float]]
    warnings: list[str]
    checked: ReuseCheck
    override: str
    builder: MasterFrames | StackBuilder
    dose: LightDoseRecord
    new: int
    kept: int
    steps: list[str]
    out_dir: Path
    capture_s: float
    camera: CameraIdentity                 # read in the run's thread: the delivery touches no device


class CopyStand:
    """Devices + session + the rules of the copy-stand day (see the module docstring)."""

    def __init__(self, camera: Camera, sphere: Sphere, session: Session, *, stand: Place | None = None,
                 settings: StandSettings | None = None,
                 progress: ProgressCallback | None = None, cancel: CancelToken | None = None,
                 prompt: Prompt | None = None, reshoot: ReshootQuestion | None = None,
                 on_event: EventCallback | None = None, control: RunControl | None = None):
        self.camera, self.sphere, self.session = camera, sphere, session
        self.settings = settings or StandSettings()
        self.engine = RunEngine("copy stand", StandDevices(camera, sphere, session, stand),
                                safety=safety_of(self.settings), control=control or RunControl(cancel),
                                progress=progress, prompt=prompt, on_event=on_event)
        self.progress, self.cancel, self.prompt = progress, self.engine.token, prompt
        self.reshoot, self.on_event = reshoot, on_event
        self.planned_condition: float | None = None     # the light set's, checked before the light (calibrate)

    @property
    def facts(self) -> StandFacts:
        """What plans know of this stand (the camera's shutter speeds, the light-on rule): the engine's."""
        return self.engine.facts

    def planner(self) -> StandPlanner:
        """The single steps (darks, flats, a target, auto-exposure, HDR metering) on this stand, to run through
        :meth:`run_sequence` or a front end's core.engine.Run."""
        return StandPlanner(self.facts)

    # ------------------------------------------------------------------ running sequences
    def run_sequence(self, seq: BaseSequence, lo: float = 0.0, hi: float = 1.0) -> list[ProgressEvent]:
        """Run a plan through the run engine (core.engine): prompts go to ``prompt``, progress to
        ``progress``, cancel stops it (LEDs off, read back) and raises Cancelled."""
        self.engine.progress, self.engine.on_event = self.progress, self.on_event
        return self.engine.run_plan(seq, lo, hi)

    def _check_cancel(self) -> None:
        self.engine.check()

    # ------------------------------------------------------------------ calibration
    def exposure_plan(self, base: dict[str, float], hdr_auto: bool, mode: str) -> dict[str, list[float]]:
        """Per light: the open-gate exposure, and with ``hdr_auto`` longer ones (HDR, thesis 8) up to the most the
        parsimony study found worth it in ``mode``, each within the overlap the HDR planner keeps and the light-on
        limit."""
        from dualrgb.app.sequences.hdr import LINEAR_LIMIT_DN

        n = self.hdr_exposures(mode) if hdr_auto else 1
        limit = self.facts.max_exposure_s
        usable = [s for s in self.facts.shutter_speeds() if s <= limit]
        step = 0.8 * LINEAR_LIMIT_DN / 100.0                 # app.sequences.hdr.plan_hdr's overlap factor
        plan = {}
        for name, t in base.items():
            ts = [t]
            while len(ts) < n:
                nxt = snap_down(usable, ts[-1] * step)
                if nxt <= ts[-1]:
                    break
                ts.append(nxt)
            plan[name] = ts
        return plan

    def hdr_exposures(self, mode: str) -> int:
        return int(self.settings.hdr_exposures or study_defaults(mode)["hdr_exposures"])

    def auto_expose(self, lights: Sequence[NamedLight]) -> dict[str, float]:
        """Per light, the open-gate exposure (app.workflow.stand.metering.AutoExposure: cancellable between lights)."""
        seq = AutoExposure(self.facts, lights)
        self.run_sequence(seq, *AUTO_EXPOSURE)
        return dict(seq.exposures)

    def calibration_sequences(self, lights: Sequence[NamedLight], plan: dict[str, list[float]],
                              base: dict[str, float]) -> list[tuple[BaseSequence, float, float]]:
        """The frames of a calibration, in order, with the share of the progress each fills: darks at every
        planned exposure (thesis 8.2.1), flats per light at its planned exposures (8.2.2), the training and test
        targets at the base exposures."""
        facts, s = self.facts, self.settings
        out: list[tuple[BaseSequence, float, float]] = [
            (DarkSeries(facts, sorted({t for ts in plan.values() for t in ts}), s.dark_frames), *DARKS),
            (FlatSeries(facts, lights, plan, s.flat_frames), *FLATS)]
        for name, band in TARGET_FRAMES.items():
            out.append((SubjectCapture(facts, lights, {n: [t] for n, t in base.items()}, Subject.target(name)),
                        *band))
        return out

    def calibrate(self, preset: Preset, *, hdr_auto: bool | None = None,
                  grids: Mapping[str, PatchGrid | None] | None = None, report_dir: Path | None = None
                  ) -> CalibrationProfile:
        """Auto-exposure, darks and flats at every planned exposure, training and test targets, characterisation:
        the calibration profile, saved in ``<session>/calibration/``. ``hdr_auto`` None: the day's default
        (app.workflow.stand.defaults)."""
        check_lights(lights_of(preset), f"preset {preset.name}")      # before anything is lit
        self.planned_condition, _ = check_conditioning(lights_of(preset), preset.mode, f"preset {preset.name}",
                                                       self.settings.stand_start)

        def calibration() -> CalibrationProfile:
            base = self.auto_expose(lights_of(preset))
            return self.calibrate_at(preset, base, hdr_auto=hdr_auto, grids=grids, report_dir=report_dir)
        return self.engine.run(calibration)

    def calibrate_at(self, preset: Preset, base: dict[str, float], *, hdr_auto: bool | None = None,
                     grids: Mapping[str, PatchGrid | None] | None = None, report_dir: Path | None = None
                     ) -> CalibrationProfile:
        """:meth:`calibrate` from known open-gate exposures ``base`` (light name -> seconds). Once the exposures
        are planned, an event says so (``data``: 'plan', the frames; 'base'; 'exposures', per light)."""
        return self.engine.run(lambda: self._calibrate_at(preset, base, hdr_auto, grids, report_dir))

    def _calibrate_at(self, preset: Preset, base: dict[str, float], hdr_auto: bool | None,
                      grids: Mapping[str, PatchGrid | None] | None, report_dir: Path | None) -> CalibrationProfile:
        lights = lights_of(preset)
        defaults = workflow_defaults(preset.mode)
        plan = self.exposure_plan(base, defaults.hdr_auto if hdr_auto is None else hdr_auto, preset.mode)
        specs = self.target_specs(preset.mode, grids)          # a chart that cannot be used: before any frame
        self.session.extend_definition(**chart_definition(self.settings.charts or {}))   # other charts: refused
        sequences = self.calibration_sequences(lights, plan, base)
        if self.on_event is not None:
            self.on_event(ProgressEvent(0, 0, "auto-exposure done: darks, flats and the targets next",
                                        data={"plan": [f for seq, _lo, _hi in sequences for f in seq.plan()],
                                              "base": dict(base), "exposures": plan}))
        for seq, lo, hi in sequences:
            self.run_sequence(seq, lo, hi)
        optimise = self.settings.optimise_matrix
        if optimise is None:
            optimise = defaults.optimise_matrix
        out = Path(report_dir or self.session.path / "calibration" / "report")
        result = process_session(self.session, out, specs["train"], specs["test"], lights=[nl.name for nl in lights],
                                 exposures={n: [t] for n, t in base.items()}, optimise=optimise,
                                 white_xyz=reference_white(preset.mode), title=f"calibration, {preset.name}",
                                 progress=sub_progress(self.progress, *PROCESSING), cancel=self.cancel,
                                 mode=preset.mode, stand_start=self.settings.stand_start)
        profile = self._profile(preset, lights, plan, base, result, specs["test"])
        profile.charts = {k: spec.chart.record() for k, spec in specs.items() if spec.chart is not None}
        self._check_cancel()             # a cancel during the processing never makes (or replaces) a calibration
        profile.save(self.session.path / "calibration")
        report(self.progress, 1.0, f"calibration {profile.id} saved")
        return profile

    def target_specs(self, mode: str, grids: Mapping[str, PatchGrid | None] | None = None) -> dict[str, TargetSpec]:
        """The training and test targets' specs: the stand's own charts (``settings.charts``) or the mode's
        packaged targets, with the grids placed by hand (``grids``)."""
        charts = self.settings.charts or {}
        return {name: target_spec(mode, Subject.target(name), (grids or {}).get(name), chart=charts.get(name),
                                  nd=self.settings.nd_filter) for name in ("train", "test")}

    def _profile(self, preset: Preset, lights: list[NamedLight], plan: dict[str, list[float]], base: dict[str, float],
                 result: SessionResult, test: TargetSpec) -> CalibrationProfile:
        proc = result.processor
        entries = [e for e in self.session.entries() if role_of(e) in (Role.DARK, Role.FLAT, Role.TARGET)]
        sources = {e.file: e.sha256 for e in entries}
        temps = [e.sphere_temperature_c for e in entries if e.sphere_temperature_c is not None]
        sphere = SphereIdentity.of(self.sphere)
        if temps:
            sphere.temperature_c = float(np.mean(temps))
        created = datetime.now(UTC)
        c = result.characterisation
        first = next(iter(proc._whites.values()))
        return CalibrationProfile(
            id=new_profile_id(created, sources), created_at=created.isoformat(timespec="seconds"), mode=preset.mode,
            camera=CameraIdentity.of(self.camera), sphere=sphere, preset=preset.name, lights=lights, exposures=plan,
            base_exposures=base, matrix=c.matrix, statistics={**c.to_dict(), "report": str(result.files["report"]),
                                                              "quality": grading_summary(result.report["quality"]),
                                                              **self._planned()},
            white_xyz=[float(v) for v in c.white], sources=sources,
            ppi=self._ppi(result.grids.get("test") or test.grid),
            raw={"white_level": proc.white_level, "black_level": proc.black_level, "cfa": proc.cfa,
                 "linear_limit": proc.linear_limit, "shape": list(first.white.shape), "ppi_grid": "sensor"},
            targets={"train": result.report.get("train"), "test": result.report.get("test")},
            darks=proc.darks, whites=dict(proc._whites), **_spectral_fields(result), **_stand_fields(result))

    def _planned(self) -> dict:
        """The light set's condition number the plan checked from the camera model (check_conditioning), beside
        the one the calibration measured from the captures (statistics.condition_number)."""
        cond = self.planned_condition
        if cond is None or cond != cond:               # not checked (calibrate_at alone) or one light
            return {}
        return {"condition_number_planned": round(cond, 2) if np.isfinite(cond) else "inf"}

    def _ppi(self, grid: PatchGrid | None) -> float | None:
        """The sampling: as set, else from the test target's width and its grid (found in the image or placed)."""
        if self.settings.ppi:
            return float(self.settings.ppi)
        width_mm = self.settings.target_width_mm
        if not width_mm or grid is None:
            return None
        tl, tr = np.asarray(grid.corners[0]), np.asarray(grid.corners[1])
        # the target's corners are on the 2x2-cell grid of the charts' superpixels: the sensor has twice the pixels
        return round(2.0 * float(np.hypot(*(tr - tl))) / (width_mm / 25.4), 2)

    # ------------------------------------------------------------------ originals
    def check(self, profile: CalibrationProfile, lights: Sequence[NamedLight] | None = None) -> ReuseCheck:
        """Compare the stand with the calibration; a mismatch raises ProfileError (one line) unless ``force``."""
        result = check_reuse(profile, CameraIdentity.of(self.camera), SphereIdentity.of(self.sphere),
                             lights if lights is not None else profile.lights, self.settings.limits)
        if not result.ok:
            if not self.settings.force:
                raise ProfileError(f"calibration {profile.id} refused: {result.message()} (--force to use it anyway)")
            result.warnings.insert(0, f"calibration used despite: {result.message()}")
        for w in result.warnings:
            log.warning("%s", w)
        return result

    def _take(self, original: Original, reshoot: bool | None) -> int:
        """The take to record: 1 for a new original, the next one when it is shot again, else its last."""
        takes = original_takes(self.session, original)
        if not takes:
            return 1
        again = reshoot if reshoot is not None else (self.reshoot(original, len(takes)) if self.reshoot else False)
        return max(takes) + 1 if again else max(takes)

    def meter(self, original: Original, profile: CalibrationProfile, take: int
              ) -> tuple[dict[str, list[float]], list[str]]:
        """Metering frame per light -> the calibrated exposures the original needs (HDR only when it must)."""
        h, w = profile.raw["shape"]
        n = self.settings.meter_tiles
        rows, cols = np.linspace(0, h, n + 1).astype(int), np.linspace(0, w, n + 1).astype(int)
        tiles = [(rows[i], rows[i + 1], cols[j], cols[j + 1]) for i in range(n) for j in range(n)]
        seq = HdrMetering(self.facts, profile.lights, profile.base_exposures, original.subject, tiles, take=take,
                          max_frames=self.hdr_exposures(profile.mode))
        self.run_sequence(seq, 0.0, 0.1)
        plans = seq.plans
        exposures, warnings = {}, []
        for nl in profile.lights:
            wanted = len(plans[nl.name].exposures)
            have = profile.exposures[nl.name]
            exposures[nl.name] = have[:wanted]
            if wanted > len(have):
                warnings.append(f"{nl.name}: the scene needs {wanted} exposures, the calibration covers "
                                f"{len(have)} (recalibrate with --hdr auto)")
        return exposures, warnings

    def deliverables(self, out_dir: Path | None = None) -> Path:
        return Path(out_dir or self.session.path / "deliverables")

    def preflight(self, original: Original, out_dir: Path | None = None,
                  profile: CalibrationProfile | None = None) -> str:
        """What must hold before the light goes on for ``original``: its metadata validate (core.metadata),
        its mode is the calibration's ``profile``'s unless ``settings.force`` (app.workflow.stand.mode_rule; returns the
        override said in the sidecar and QA line, '' when none), its deliverables folder is creatable and not
        another original's (app.workflow.delivery.delivery_folder), and the spectral rendering's light is known."""
        check_original(original)
        forced = self.settings.force or original.identifier in self.settings.mode_overrides
        override = check_mode(original, profile, force=forced) if profile is not None else ""
        check_illuminant(self.settings.render_illuminant)
        check_spectral_request(profile, self.settings.delivery is not None and self.settings.delivery.spectral is True)
        check_resolution(self.settings.resolution)
        prepare(self.deliverables(out_dir), original)
        return override

    def check_before_light(self, profile: CalibrationProfile, out_dir: Path | None = None, originals: int = 1) -> None:
        """What the calibration and the stand decide before the light goes on (app.workflow.stand.preflight): every
        exposure within the light-on cap with this settle time and camera, and free space for the frames and the
        deliverables of ``originals`` originals."""
        check_lights(profile.lights, f"calibration {profile.id}")
        check_frame_shape(self.camera, profile)
        check_exposures(self.facts.safety, profile)
        frame_bytes = getattr(self.camera, "frame_bytes", None)
        per_frame = int(frame_bytes()) if callable(frame_bytes) else 0
        frames = capture_frames(profile, self.settings.original_frames, self.hdr_exposures(profile.mode))
        bands = profile.estimator.n_wavelengths if profile.estimator is not None else 0
        check_capture_space(self.session.path, self.deliverables(out_dir), originals * frames * per_frame,
                            originals * deliverable_bytes(profile, bands),
                            f"{originals} original{'s' if originals > 1 else ''}")

    def capture(self, original: Original, profile: CalibrationProfile, *, reshoot: bool | None = None,
                out_dir: Path | None = None, frames: int | None = None) -> CaptureReport:
        """Check the original (:meth:`preflight`) and the calibration, meter, capture (HDR when metering asks),
        deliver (one run); frames already in the session are kept unless re-shot (``reshoot`` or the ``reshoot``
        hook); ``frames`` per exposure (else ``settings.original_frames``)."""
        return self.engine.run(lambda: self._capture(original, profile, reshoot, out_dir, frames))

    def _capture(self, original: Original, profile: CalibrationProfile, reshoot: bool | None,
                 out_dir: Path | None, frames: int | None) -> CaptureReport:
        shot = self.shoot(original, profile, reshoot, out_dir, frames)
        report(self.progress, 0.8, f"{original.identifier}: merging its frames, writing its deliverables")
        return self.finish(shot, self.deliver_shot(shot))

    def shoot(self, original: Original, profile: CalibrationProfile, reshoot: bool | None = None,
              out_dir: Path | None = None, frames: int | None = None) -> ShotOriginal:
        """The device half of :meth:`capture` (inside a run): checks, metering and the frames, each taken into
        the original's channels as it lands; :meth:`deliver_shot` (no device: any thread) and :meth:`finish`
        (the session's record, the run's thread) do the rest."""
        t0 = time.monotonic()
        override = self.preflight(original, out_dir, profile)
        self.check_before_light(profile, out_dir)
        checked = self.check(profile)
        take = self._take(original, reshoot)
        exposures, warnings = self.meter(original, profile, take)
        builder = begin_channels(profile_processor(profile), [nl.name for nl in profile.lights],
                                 self.settings.resolution)
        seq = SubjectCapture(self.facts, profile.lights, exposures, original.subject, take,
                             meta={"title": original.title, "operator": original.operator, "mode": original.mode},
                             frames=frames or self.settings.original_frames)

        def landed(ev: ProgressEvent) -> None:            # each frame taken in as soon as it is on disk
            if ev.kind in (EventKind.FRAME, EventKind.KEPT):
                e = next(x for x in self.session.entries() if x.seq == ev.data["entry"])
                builder.add(ev.data["light"], ExposureRef(self.session.file_path(e), e.exposure(), e.file),
                            cancel=self.cancel)
        outer, self.on_event = self.on_event, _chain(self.on_event, landed)
        try:
            self.run_sequence(seq, 0.1, 0.8)
        except BaseException:
            builder.close()
            raise
        finally:
            self.on_event = outer
        return ShotOriginal(original, profile, take, exposures, warnings, checked, override, builder,
                            original_dose(self.session, original.subject), seq.new, seq.kept, seq.steps(),
                            self.deliverables(out_dir), time.monotonic() - t0, CameraIdentity.of(self.camera))

    def deliver_shot(self, shot: ShotOriginal) -> Delivery:
        """The deliverables of a shot original (no device, no session write: a delivery worker may run it while
        the run shoots the next original); its frames are released on every path."""
        try:
            source = shot.builder.result()
        finally:
            shot.builder.close()
        with closing(source):
            return deliver(source, shot.profile, shot.original, shot.out_dir,
                           camera=shot.camera, dose=shot.dose, ppi=self.settings.ppi,
                           exposures=shot.exposures, warnings=shot.checked.warnings + shot.warnings,
                           extra={"session": str(self.session.path), "take": shot.take, "frames": shot.steps},
                           render_illuminant=self.settings.render_illuminant,
                           overrides=[shot.override] if shot.override else [], cancel=self.cancel,
                           settings=self.settings.delivery)

    def finish(self, shot: ShotOriginal, delivery: Delivery) -> CaptureReport:
        """A delivered original recorded in the session (the run's thread) and reported."""
        self._remember(shot.original, shot.dose, delivery, shot.take, shot.profile)
        report(self.progress, 1.0, f"{shot.original.identifier}: {shot.new} new, {shot.kept} kept; delivered")
        return CaptureReport(shot.original, shot.new, shot.kept, shot.exposures, delivery, shot.checked,
                             shot.warnings)

    def _remember(self, original: Original, total: LightDoseRecord, delivery: Delivery, take: int,
                  profile: CalibrationProfile) -> None:
        """The original's metadata and total dose in session.json (``dualrgb process`` re-delivers from it)."""
        originals = dict(self.session.settings.get("originals", {}))
        here = Path(self.session.path)
        originals[original.identifier] = {**original.to_dict(), "take": take, "light_dose": total.to_dict(),
                                          "sidecar": record(here, delivery.sidecar),
                                          "calibration": record(here, profile.path or "")}
        self.session.update_settings(originals=originals)


def safety_of(settings: StandSettings) -> SafetySettings:
    """The light-on rule (light-on cap, settle time, the camera's latency allowance) of a stand."""
    return SafetySettings(settle_s=settings.settle_s, latency_s=settings.latency_s, max_on_s=settings.max_on_s)


def plans_only(camera: Camera | None, settings: StandSettings) -> StandPlanner:
    """The single steps' plans on ``camera`` alone (nothing is touched: no sphere, no session)."""
    return StandPlanner(facts_of(camera, safety_of(settings)))


def _spectral_fields(result: SessionResult) -> dict:
    """The profile's spectral estimator and section from the processing (none without the targets' spectra)."""
    if result.spectral is None:
        return {}
    section = result.spectral.to_dict()
    return {"estimator": result.spectral.estimator, "spectral": {k: v for k, v in section.items() if k != "estimator"}}


def _stand_fields(result: SessionResult) -> dict:
    """The profile's stand model section and its observations (none when the fit was not made)."""
    if result.stand is None:
        return {}
    return {"stand": result.stand.summary(), "stand_observations": result.stand.observations}


def original_takes(session: Session, original: Original) -> list[int]:
    """The take of every frame of ``original`` already in ``session`` (empty: never shot). A front end asks
    "already in the session: re-shoot / keep" when it is not empty."""
    subject = original.subject
    return [split_take(e.step_id or "")[1] for e in session.entries(include_superseded=True)
            if role_of(e) is Role.ORIGINAL and subject_of(e) == subject]


def original_dose(session: Session, subject: Subject) -> LightDoseRecord:
    """Every lit period of an original (metering, every take) from the dose lines; unknown if imported (none kept)."""
    from dualrgb.core.session.light_dose import LightDose, light_from_record

    if session.settings.get("imported"):
        return LightDoseRecord.unknown()
    total = LightDose()
    marker = f"/{subject.key}/"
    for d in session.doses():
        if d.step_id and marker in d.step_id:
            total.add(light_from_record(d.light), d.on_s)
    return LightDoseRecord(total.lux_s, total.on_s)


def _chain(*callbacks: EventCallback | None) -> EventCallback:
    def call(ev: ProgressEvent) -> None:
        for cb in callbacks:
            if cb is not None:
                cb(ev)
    return call


def profile_processor(profile: CalibrationProfile) -> CaptureProcessor:
    """A processor with the calibration's master darks and whites (nothing recomputed)."""
    raw = profile.raw
    proc = CaptureProcessor(darks=profile.darks, white_level=raw.get("white_level"), black_level=raw.get("black_level"),
                            linear_limit=raw.get("linear_limit"), cfa=raw.get("cfa"), mode=profile.mode)
    for name, ff in profile.whites.items():
        proc.put_white(name, ff)
    return proc


def begin_channels(proc: CaptureProcessor, lights: list[str], resolution: str) -> MasterFrames | StackBuilder:
    """What takes an original's frames in as they land: a full-resolution MasterFrames (held, merged and
    demosaiced band by band at delivery) or a half-resolution StackBuilder (merged as they land)."""
    return proc.begin_master(lights) if check_resolution(resolution) == FULL else proc.begin_stack(lights)


def channels_of(proc: CaptureProcessor, light_frames: dict[str, list[ExposureRef]], resolution: str,
                cancel: CancelToken | None = None) -> ChannelSource:
    """The channels of an original from its frames on disk (a ChannelSource to close after delivery)."""
    builder = begin_channels(proc, list(light_frames), resolution)
    try:
        for light, refs in light_frames.items():
            for ref in refs:
                builder.add(light, ref, cancel=cancel)
        return builder.result()
    finally:
        builder.close()
