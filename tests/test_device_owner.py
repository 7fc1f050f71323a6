"""One owner of every device action (issue 36): the run engine (core.engine and its hands,
core.device_actions, .shooter, .shutter_shooter) alone switches the light, sets the LED levels, exposes,
downloads, moves the monochromator and reads the spectroradiometer; plans yield messages
(core.messages). Two checks:

* an AST walk of every module in app/ and core/: a call that acts on a device (the sphere's light and levels, the
camera's
  exposure, the monochromator's shutter and wavelength, the spectroradiometer's reading) appears only in the
  engine's modules, or in the few places listed below with the reason they stay outside it;
* a recording run (tests/app/test_device_recorder.py): every action on the virtual lab's devices during a
  calibration, an original's capture and the light held by hand comes from the engine's modules.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ("core/engine.py", "core/device_actions.py", "core/shooter.py",
          "core/shutter_shooter.py")
OUTSIDE = {       # what still acts on a device outside the engine, and why
    "app/workflow/stand/stand_devices.py": "opening and closing a device: identified, every LED 0 and the light off, "
                                           "read back (open_sphere, close_sphere), the camera's ISO and aperture",
    "app/commands/sphere.py": "`dualrgb sphere`, the sphere's own device tool (set, apply, on with its cap, off): "
                              "its effect must outlast the command, so it is no run",
    "app/gui/panels/camera.py": "the Camera panel: settings, an unlit test shot and live view (the camera only)",
    "app/interrupts.py": "the signal handler's safety net (issue 38): on SIGINT / SIGTERM / SIGHUP every open sphere "
                         "is switched off and read back at once, whatever run is in progress, before the engine's "
                         "own clean-up; it only ever switches off",
}
# method -> the words one of which the receiver's text must hold for the call to act on a device
ACTIONS = {
    **dict.fromkeys(("on", "off", "ensure_off", "shutdown", "set_levels", "set_level", "all_off", "apply",
                     "exposure_done", "keepalive"), ("sphere",)),
    **dict.fromkeys(("open_shutter", "close_shutter", "ensure_closed", "goto", "prepare"), ("mono", "instrument")),
    **dict.fromkeys(("expose", "fetch", "capture", "preview"), ("cam",)),
    "measure": ("radiometer", "instrument", "spectro"),
}
NOT_DEVICES = ("self.w.camera",)      # the window's Camera panel (its capture is the panel's test shot button)


def device_calls(path: Path) -> list[str]:
    """``line: receiver.method`` for every call in ``path`` that acts on a device (ACTIONS)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ACTIONS:
            receiver = ast.unparse(node.func.value).lower()
            if receiver not in NOT_DEVICES and any(word in receiver for word in ACTIONS[node.func.attr]):
                out.append(f"{node.lineno}: {ast.unparse(node.func)}")
    return out


def violations(root: Path = ROOT) -> list[str]:
    bad = []
    for path in sorted([*(root / "app").rglob("*.py"), *(root / "core").rglob("*.py")]):
        rel = path.relative_to(root).as_posix()
        if rel in ENGINE or rel in OUTSIDE:
            continue
        bad += [f"{rel}:{call}" for call in device_calls(path)]
    return bad


def test_only_the_engine_acts_on_a_device():
    assert violations() == []


def test_the_engine_and_the_listed_places_do_act():
    """The rule sees what it guards: each listed module still holds a device call (else it leaves the list)."""
    for rel in (*ENGINE[1:], *OUTSIDE):
        assert device_calls(ROOT / rel), f"{rel} acts on no device: take it off the list"


@pytest.mark.parametrize("source", [
    "def _steps(self):\n    self.shooter.sphere.on(max_on_s=2)\n",
    "def plan(cam):\n    return cam.expose(1 / 60)\n",
    "def wave(self):\n    self.monochromator.goto(500)\n",
    "def show(lab):\n    lab.sphere.apply(light)\n",
])
def test_the_rule_catches_a_plan_acting_itself(tmp_path, source):
    target = tmp_path / "app" / "sequences" / "x.py"
    target.parent.mkdir(parents=True)
    target.write_text(source)
    found = violations(tmp_path)
    assert len(found) == 1 and found[0].startswith("app/sequences/x.py:")


def test_plans_hold_no_device():
    """The plans (app/sequences, the metering and light plans) import none of the engine's hands."""
    hands = tuple(f"dualrgb.core.{m}" for m in ("shooter", "shutter_shooter", "device_actions"))
    plans = [*sorted((ROOT / "app" / "sequences").glob("*.py")), ROOT / "app/workflow/stand/metering.py",
             ROOT / "app/workflow/stand/light_plans.py", ROOT / "app/workflow/stand/plans.py"]
    for path in plans:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module:
                assert not node.module.startswith(hands), f"{path.name} imports {node.module}"
