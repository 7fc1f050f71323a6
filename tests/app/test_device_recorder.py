"""Every device action comes from the run engine (issue 36), watched on the virtual lab: its sphere and camera are
wrapped in recorders that note, for every call, the module that made it. Over a calibration's plans (auto-exposure,
darks, flats, the targets), an original's capture and delivery (CopyStand.capture, as `dualrgb capture` and the
window's Originals run it) and the light held by hand (the manual light, the framing light, Light OFF: plans as the
window runs them), every call that acts - light, levels, exposure, download - is made by the engine's modules,
and every run starts and ends with the light switched off and read back."""
from __future__ import annotations

import sys
from typing import Any

from workflow_profiles import make_profile

from dualrgb.app.workflow.stand.copystand import CopyStand, StandSettings
from dualrgb.app.workflow.stand.light_plans import Dark, FramingLight, HeldLight, framing_light
from dualrgb.core.engine import RunEngine, StandDevices
from dualrgb.core.metadata import Original
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import NamedLight
from dualrgb.drivers.virtual.lab import VirtualLab
from dualrgb.simulation.lightsource import LightSource

ENGINE = {f"dualrgb.core.{m}" for m in ("engine", "device_actions", "shooter", "shutter_shooter")}
ACTS = {"apply", "set_levels", "on", "off", "ensure_off", "shutdown", "all_off", "keepalive", "exposure_done",
        "expose", "fetch", "capture", "preview"}
LIGHTS = [NamedLight("P light 1", LightSource((1, 6, 7), (0.0, 0.42, 1.0), "P light 1"))]


class Recorder:
    """``target`` with every method call noted in ``calls`` as (what, method, the caller's module)."""

    def __init__(self, target: Any, what: str, calls: list):
        object.__setattr__(self, "_target", target)
        object.__setattr__(self, "_what", what)
        object.__setattr__(self, "_calls", calls)

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._target, name)
        if not callable(value) or name.startswith("_"):
            return value

        def call(*args: Any, **kwargs: Any) -> Any:
            self._calls.append((self._what, name, sys._getframe(1).f_globals.get("__name__", "?")))
            return value(*args, **kwargs)
        return call


def test_every_device_action_comes_from_the_run_engine(tmp_path):
    calls: list[tuple[str, str, str]] = []
    with VirtualLab(frame_size=(96, 64)) as lab:
        sphere, camera = Recorder(lab.sphere, "sphere", calls), Recorder(lab.camera, "camera", calls)
        session = CaptureSession.create(tmp_path / "s", {"test": "device recorder"})

        def place(what: str, nd: bool = False):
            return lab.place("original:painting" if what.startswith("original:") else what, nd)
        stand = CopyStand(camera, sphere, session, stand=place,
                          settings=StandSettings(settle_s=0.0, dark_frames=1, flat_frames=1, force=True))

        def calibration_plans() -> None:                 # CopyStand.calibrate's plans (its processing aside)
            base = stand.auto_expose(LIGHTS)
            for seq, lo, hi in stand.calibration_sequences(LIGHTS, stand.exposure_plan(base, False, "reflective"),
                                                           base):
                stand.run_sequence(seq, lo, hi)
        stand.engine.run(calibration_plans)
        runs = [len(calls)]
        stand.capture(Original("ACC-1"), make_profile(tmp_path / "cal", shape=(64, 96)))
        runs.append(len(calls))
        for plan in (HeldLight(LIGHTS[0].light, 0.3, tick_s=0.02),
                     FramingLight(framing_light(LIGHTS[0].light, 0.02), 0.4, max_s=0.6, margin_s=0.1), Dark()):
            RunEngine(plan.name, StandDevices(sphere=sphere, session=session)).run_plan(plan)
            runs.append(len(calls))
        session.close()
    acting = [c for c in calls if c[1] in ACTS]
    outside = sorted({c for c in acting if c[2] not in ENGINE})
    assert outside == [], outside
    made = {(what, method) for what, method, _ in acting}
    assert {("sphere", "apply"), ("sphere", "on"), ("sphere", "off"), ("sphere", "ensure_off"),
            ("camera", "expose"), ("camera", "fetch")} <= made
    starts = [0, *runs[:-1]]
    for a, b in zip(starts, runs, strict=True):         # each run: dark at its start and at its end, read back
        light = [c[1] for c in calls[a:b] if c[0] == "sphere" and c[1] in ACTS]
        assert light[0] == "ensure_off" and light[-1] == "ensure_off", light
