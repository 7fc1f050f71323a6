"""The virtual lab as devices: its instruments served each on its own address, in a process of their own
(`dualrgb lab serve`), so the program that drives the stand opens them exactly as it opens a physical stand's.

* ``sphere``: the sphere emulator (drivers/virtual/sphere_emulator.py) on ``socket://127.0.0.1:PORT``: the LED
  sphere's protocol (docs/led-sphere-protocol.md), its watchdog and on-time limit its own;
* ``camera``: the virtual camera (drivers/virtual/camera.py) behind a camera bridge (drivers.camera.bridge) on
  ``tcp://127.0.0.1:PORT``; it renders what this process's sphere emulator emits at the moment of each exposure and
  what lies on the stand;
* ``stand``: the sample changer (drivers/virtual/changer_emulator.py) on ``socket://``: it puts targets, the open
  gate, the lens cap and the originals' stand-ins on the virtual stand;
* ``monochromator``: the Cornerstone 130 emulator (drivers/virtual/monochromator_emulator.py) on ``socket://``;
* ``spectroradiometer``: the virtual spectroradiometer pointed at this sphere (drivers/virtual/
  spectroradiometer_server.py: ``MEAS?`` reads what the sphere emits now) on ``socket://``.

``read_chart(role, layout, leave_out, file)``: how the sample changer's ``CHART`` request reads a chart's reference
file into the target the lab renders (`dualrgb lab serve` gives app.workflow.charts' reader).

``light_record``: a file where every lit period of the sphere is written as JSON lines: ``{"event": "on", "t_on",
"levels"}`` when it begins and ``{"event": "off", "t_on", "t_off", "levels", "ended_by"}`` when it ends (times on
the emulator's clock, ``time.monotonic``; ``ended_by``: a request, 'on-time limit', 'watchdog', 'power off'), so
what happens to the light can be watched from outside without a word to the sphere (a request would restart its
watchdog), e.g. after its client was killed (:func:`lit_now`, :func:`lit_periods`). :meth:`LabServer.dark` says
whether the sphere emits nothing now.

    server = LabServer(LabSettings(mode="reflective", frame_size=(600, 400)))
    for name, address in server.start().items(): print(name, address)
    ...; server.stop()
"""
from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dualrgb.drivers.camera.bridge import CameraBridge
from dualrgb.drivers.virtual.changer_emulator import ChangerEmulator
from dualrgb.drivers.virtual.lab import VirtualLab
from dualrgb.drivers.virtual.monochromator_emulator import MonochromatorEmulator
from dualrgb.drivers.virtual.spectroradiometer import VirtualSpectroradiometer
from dualrgb.drivers.virtual.spectroradiometer_server import SpectroradiometerServer
from dualrgb.drivers.virtual.sphere_emulator import LightInterval
from dualrgb.simulation.datasets import Target

log = logging.getLogger(__name__)

INSTRUMENTS = ("sphere", "camera", "stand", "monochromator", "spectroradiometer")
DEFAULT_STAND_INS = {"reflective": "painting", "transmissive": "film"}
RECORD_POLL_S = 0.02


@dataclass
class LabSettings:
    """What the lab is: its mode (the packaged targets it holds), frame size, noise seed, world, the sphere's
    watchdog, the shutter's bumps, the stand's own charts (``'train'`` / ``'test'`` -> a rendered Target) and the
    stand-in shown for an original (default: the mode's virtual original)."""

    mode: str = "reflective"
    frame_size: tuple[int, int] = (600, 400)
    seed: int = 0
    world: Any = None
    watchdog_s: float = 30.0
    bumps: bool = False
    charts: dict[str, Target] = field(default_factory=dict)
    stand_in: str = ""


class LabServer:
    """The instruments of one virtual lab, served (module docstring)."""

    def __init__(self, settings: LabSettings, light_record: Path | None = None,
                 read_chart: Callable[[str, str, str, str], Target] | None = None):
        self.settings = settings
        self._read_chart = read_chart
        self.lab = VirtualLab(mode=settings.mode, frame_size=settings.frame_size, seed=settings.seed,
                              watchdog_s=settings.watchdog_s, bumps=settings.bumps, world=settings.world,
                              transport="socket")
        self.bridge: CameraBridge | None = None
        self.changer: ChangerEmulator | None = None
        self.monochromator = MonochromatorEmulator(transport="socket")
        self.spectroradiometer: SpectroradiometerServer | None = None
        self.addresses: dict[str, str] = {}
        self._record_path = Path(light_record) if light_record else None
        self._written = 0                       # lit periods whose 'off' line is written
        self._begun = 0                         # ... whose 'on' line is written
        self._stop = threading.Event()
        self._recorder: threading.Thread | None = None

    def start(self) -> dict[str, str]:
        """Start every instrument; returns name -> address (in :data:`INSTRUMENTS` order)."""
        lab = self.lab.start(connect=False)
        for role, chart in self.settings.charts.items():
            lab.use_chart(role, chart)
        camera = lab.camera
        assert camera is not None
        self.bridge = CameraBridge(camera)
        bridge = self.bridge

        def place(what: str, nd: bool) -> str:
            with bridge.lock:                    # never while the camera renders an exposure
                lab.place(what, nd)
            return lab.placed
        self.changer = ChangerEmulator(place, self.settings.stand_in or DEFAULT_STAND_INS.get(lab.mode, "painting"),
                                       transport="socket", load_chart=self._chart if self._read_chart else None)
        self.spectroradiometer = SpectroradiometerServer(
            VirtualSpectroradiometer(lab.emulator.snapshot, camera.sphere_light, seed=self.settings.seed,
                                     clock=lab.emulator.clock), transport="socket")
        self.addresses = {"sphere": lab.port, "camera": bridge.start(), "stand": self.changer.start(),
                          "monochromator": self.monochromator.start(),
                          "spectroradiometer": self.spectroradiometer.start()}
        if self._record_path is not None:
            self._record_path.parent.mkdir(parents=True, exist_ok=True)
            self._record_path.write_text("")
            self._recorder = threading.Thread(target=self._record_loop, name="light record", daemon=True)
            self._recorder.start()
        return dict(self.addresses)

    def _chart(self, role: str, layout: str, leave_out: str, file: str) -> None:
        """The changer's CHART: hold the chart of ``file`` as ``role`` ('-': the packaged target again)."""
        assert self._read_chart is not None
        target = None if file == "-" else self._read_chart(role, "" if layout == "-" else layout,
                                                          "" if leave_out == "-" else leave_out, file)
        with self.bridge.lock if self.bridge is not None else threading.Lock():
            self.lab.use_chart(role, target)

    def dark(self) -> bool:
        """Whether the sphere emits nothing now."""
        return not bool(self.lab.emulator.snapshot().levels.any())

    def light_record(self) -> list[LightInterval]:
        return self.lab.emulator.light_record()

    def stop(self) -> None:
        """Stop every instrument (the sphere powered off: its last lit period, if any, ends 'power off')."""
        self._stop.set()
        for part in (self.changer, self.bridge, self.monochromator, self.spectroradiometer):
            if part is not None:
                try:
                    part.close() if isinstance(part, CameraBridge) else part.stop()
                except Exception as exc:  # noqa: BLE001 - stopping the others matters more; logged
                    log.warning("lab: stopping %s: %s", type(part).__name__, exc)
        self.lab.stop()
        if self._recorder is not None:
            self._recorder.join(timeout=5)
        self._write_record()

    def _record_loop(self) -> None:
        while not self._stop.wait(RECORD_POLL_S):
            self._write_record()

    def _write_record(self) -> None:
        """Append an ``on`` line for every lit period begun and an ``off`` line for every one ended since the last
        call (after :meth:`stop`'s power-off every period has ended)."""
        if self._record_path is None:
            return
        record = self.light_record()
        lines = [{"event": "on", "t_on": i.t_on, "levels": list(i.levels)} for i in record[self._begun:]]
        self._begun = len(record)
        while self._written < len(record) and record[self._written].t_off is not None:
            i = record[self._written]
            lines.append({"event": "off", "t_on": i.t_on, "t_off": i.t_off, "levels": list(i.levels),
                          "ended_by": i.ended_by})
            self._written += 1
        if lines:
            with self._record_path.open("a") as f:
                f.writelines(json.dumps(line) + "\n" for line in lines)


def read_light_record(path: Path) -> list[dict[str, Any]]:
    """The lines a lab wrote to ``path`` (:class:`LabServer`'s ``light_record``): ``on`` and ``off`` events."""
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def lit_periods(path: Path) -> list[dict[str, Any]]:
    """The lit periods that have ended (``t_on``, ``t_off``, ``levels``, ``ended_by``), in order."""
    return [e for e in read_light_record(path) if e.get("event") == "off"]


def lit_now(path: Path) -> dict[str, Any] | None:
    """The lit period begun and not ended yet (its ``on`` event), None when the sphere is dark."""
    events = read_light_record(path)
    ended = {e["t_on"] for e in events if e.get("event") == "off"}
    begun = [e for e in events if e.get("event") == "on" and e["t_on"] not in ended]
    return begun[-1] if begun else None
