"""The devices and the capture session the window works with, behind one QObject.

Every device call is submitted to the runner's ``devices`` pool (one thread, in order); results and errors come
back on the GUI thread as signals. The light is switched only by plans of the run engine (app.workflow.engine):
a sequence's run (app.gui.sequence_view), and the light held by hand - the manual light and the framing light
(app.workflow.light_plans) - run here in the runner's ``light`` pool (``run_light``). The virtual lab is
`dualrgb lab serve` started as the window's child process (app.lab.running) on first use of a virtual device; its
sphere and camera are opened by their addresses like a physical stand's, and its sample changer places what the
runs ask for. Killing the window leaves its sphere to its own watchdog and on-time limit, as a physical sphere's
firmware.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

from PySide6.QtCore import QObject, QTimer, Signal

from dualrgb.app.gui.viewmodel import DoseFeed, light_from_levels
from dualrgb.app.gui.workers import TaskHandle, TaskRunner
from dualrgb.app.sequences.base import Sequence
from dualrgb.app.session.log import SessionLog
from dualrgb.app.workflow.defaults import DEFAULT_MODE, VIRTUAL_FRAME_SIZE
from dualrgb.app.workflow.engine import Run, RunEngine, StandDevices, owning
from dualrgb.app.workflow.light_plans import Dark, HeldLight
from dualrgb.app.workflow.stand_devices import close_camera, close_sphere, open_camera, open_sphere, stand_definition
from dualrgb.common.progress import Cancelled
from dualrgb.drivers.camera.base import Camera
from dualrgb.drivers.led_sphere import LedSphere, SphereError
from dualrgb.drivers.led_sphere.driver import DEFAULT_MAX_ON_S
from dualrgb.simulation.lightsource import LightSource

if TYPE_CHECKING:
    from dualrgb.app.lab.running import RunningLab
    from dualrgb.app.session.capture_session import CaptureSession

Device = TypeVar("Device")

log = logging.getLogger(__name__)

VIRTUAL_SPHERE = "virtual sphere (emulator)"
VIRTUAL_CAMERA = "virtual camera (virtual lab)"


def serial_ports() -> list[str]:
    """Serial ports the sphere may be on (drivers.usb_discovery; USB adapters first), the emulator entry first."""
    from dualrgb.drivers.usb_discovery import serial_ports as found
    ports = sorted(found(), key=lambda p: (not p.is_usb, p.device))
    return [VIRTUAL_SPHERE] + [p.device for p in ports]


def discover_cameras() -> tuple[list[str], list[str]]:
    """(camera choices 'model @ port' plus the virtual camera, hints such as 'claimed by gvfs: do this')."""
    from dualrgb.drivers.usb_discovery import discover
    report = discover(probe=False)
    names = [f"{c.model} @ {c.port}" for c in report.gphoto_cameras]
    return names + [VIRTUAL_CAMERA], list(report.hints)


class Lab(QObject):
    sphereChanged = Signal()
    cameraChanged = Signal()
    sphereStatus = Signal(object)          # dict: LedSphere.status() plus 'dose' (app.session.light_dose.LightDose)
    sessionChanged = Signal()
    lightApplied = Signal(object)          # LightSource now on the sphere
    virtualLabChanged = Signal()
    modeChanged = Signal(str)              # reflective / transmissive (the lights' default follows it)
    failed = Signal(str, object)           # title, exception: shown by the window as an actionable dialog
    succeeded = Signal(str)                # title of a device call that worked (its earlier error is stale)
    message = Signal(str)                  # one line for the status bar

    def __init__(self, runner: TaskRunner, parent: QObject | None = None,
                 frame_size: tuple[int, int] = VIRTUAL_FRAME_SIZE, mode: str = DEFAULT_MODE, seed: int = 0,
                 shutter_bumps: bool = False):
        super().__init__(parent)
        self.runner = runner
        self.frame_size = frame_size
        self.mode = mode
        self.seed = seed
        self.shutter_bumps = shutter_bumps         # virtual lab: the D610's exposure-time bumps (appendix A)
        self.world: str | None = None              # virtual lab: its world (a packaged name or a file; None nominal)
        self.virtual_lab: RunningLab | None = None
        self._lab_devices: tuple[Camera, LedSphere] | None = None     # the lab's, opened by their addresses
        self.lab_in_process = False               # tests: serve the lab's instruments from this process
        self.sphere: LedSphere | None = None
        self.sphere_port: str = ""
        self.camera: Camera | None = None
        self.camera_name: str = ""
        self.session: CaptureSession | None = None
        self.session_note = ""                    # why it was made ('made for the calibration'), '' by hand
        self.session_log: SessionLog | None = None   # its session.log while it is the current session
        self.last_status: dict = {}
        self.dose = DoseFeed()
        self.manual_max_on_s = DEFAULT_MAX_ON_S   # 'Light ON' lights the sphere for at most this long
        self.manual_light: LightSource | None = None   # the levels last applied ('Light ON' lights them)
        self._light_plans: list[Sequence] = []         # the light plans running or waiting (run_light)
        self._poll_pending = False
        self._status_timer = QTimer(self)
        self._status_timer.setInterval(1000)
        self._status_timer.timeout.connect(self.poll_status)
        self._status_timer.start()

    # ------------------------------------------------------------------ helpers
    def device_call(self, fn: Callable[[], Any], title: str, *, on_result: Callable[[Any], None] | None = None,
                    on_finished: Callable[[], None] | None = None,
                    on_error: Callable[[BaseException], None] | None = None) -> TaskHandle:
        """Run ``fn`` on the devices thread; errors become a dialog titled ``title``."""
        def failed(exc: BaseException) -> None:
            if on_error is not None:
                on_error(exc)
            self.failed.emit(title, exc)

        def worked(value: Any) -> None:
            self.succeeded.emit(title)
            if on_result is not None:
                on_result(value)
        return self.runner.submit(fn, pool="devices", name=title, on_result=worked, on_error=failed,
                                  on_finished=on_finished)


    def set_mode(self, mode: str) -> None:
        if mode != self.mode:
            self.mode = mode
            self.modeChanged.emit(mode)

    @property
    def is_virtual(self) -> bool:
        return self.virtual_lab is not None

    def _ensure_virtual_lab(self) -> RunningLab:      # devices thread
        if self.virtual_lab is None:
            from dualrgb.app.lab.process import LabOptions
            from dualrgb.app.lab.running import RunningLab

            options = LabOptions(mode=self.mode, frame_size=self.frame_size, seed=self.seed, world=self.world,
                                 bumps=self.shutter_bumps)
            lab = RunningLab(options, in_process=self.lab_in_process).start()
            self.virtual_lab = lab
            log.info("virtual lab started: sphere on %s, camera on %s, %dx%d frames", lab.port,
                     lab.addresses["camera"], *self.frame_size)
        return self.virtual_lab

    def _virtual_devices(self) -> tuple[Camera, LedSphere]:      # devices thread
        """The virtual lab's camera and sphere, opened by their addresses once (kept open while the lab runs)."""
        lab = self._ensure_virtual_lab()
        if self._lab_devices is None:
            sphere = open_sphere(lab.addresses["sphere"])
            try:
                camera = open_camera(lab.addresses["camera"])
            except BaseException:
                sphere.close()
                raise
            self._lab_devices = (camera, sphere)
        return self._lab_devices

    # ------------------------------------------------------------------ virtual lab
    def start_virtual_lab(self, on_done: Callable[[], None] | None = None) -> TaskHandle:
        """Start the virtual lab and connect both its devices."""
        def work() -> tuple[str, Any, Any]:
            camera, sphere = self._virtual_devices()
            return self._ensure_virtual_lab().port, sphere, camera

        def done(result: tuple[str, Any, Any]) -> None:
            port, sphere, camera = result
            self._set_sphere(sphere, VIRTUAL_SPHERE)
            self._set_camera(camera, VIRTUAL_CAMERA)
            self.virtualLabChanged.emit()
            self.message.emit(f"virtual lab ready: sphere emulator on {port}, virtual camera")
            if on_done:
                on_done()
        return self.device_call(work, "Start the virtual lab", on_result=done)

    def place(self, what: str, nd: bool = False, on_done: Callable[[], None] | None = None) -> TaskHandle:
        """Virtual lab only: put a target / the open gate / the lens cap on the copy stand."""
        def work() -> str:
            return self._ensure_virtual_lab().place(what, nd=nd)
        def placed(what_is_placed: str) -> None:
            self.message.emit(f"on the copy stand: {what_is_placed}")
            if on_done:
                on_done()
        return self.device_call(work, "Place on the copy stand", on_result=placed)

    # ------------------------------------------------------------------ sphere
    def connect_sphere(self, port: str, on_done: Callable[[bool], None] | None = None) -> TaskHandle:
        def work() -> LedSphere:
            if port == VIRTUAL_SPHERE:
                return self._virtual_devices()[1]
            return open_sphere(port)            # identified, every LED 0, light off (read back)

        return self._connect(work, "Connect the LED sphere", self._set_sphere, port, port == VIRTUAL_SPHERE, on_done)

    def _connect(self, work: Callable[[], Device], what: str, install: Callable[[Device, str], None], name: str,
                 virtual: bool, on_done: Callable[[bool], None] | None) -> TaskHandle:
        """Run ``work`` (it opens a device) as a device call; on success ``install(device, name)`` and tell
        ``on_done(True)`` (False on failure, which the device call reports)."""
        def done(device: Device) -> None:
            install(device, name)
            if virtual:
                self.virtualLabChanged.emit()
            if on_done:
                on_done(True)
        return self.device_call(work, what, on_result=done, on_error=lambda exc: on_done(False) if on_done else None)

    def _set_sphere(self, sphere: LedSphere | None, port: str) -> None:
        self.sphere = sphere
        self.sphere_port = port if sphere is not None else ""
        self.dose.reset()
        self.last_status = {}
        self.sphereChanged.emit()
        if sphere is not None:
            self.message.emit(f"LED sphere connected on {sphere.port}")
            self.poll_status()

    def disconnect_sphere(self) -> TaskHandle | None:
        sphere, port = self.sphere, self.sphere_port
        if sphere is None:
            return None
        self._set_sphere(None, "")
        self.stop_light()

        def work() -> None:
            with owning(StandDevices(sphere=sphere), "disconnect"):     # after a run on it has ended
                report = close_sphere(sphere, keep_open=port == VIRTUAL_SPHERE)   # the virtual lab keeps its port
            if not report.off:
                raise SphereError(f"disconnected; {report.message}", kind="port", light="unknown")
        return self.device_call(work, "Disconnect the LED sphere",
                                on_finished=lambda: self.message.emit("LED sphere off and disconnected"))

    def poll_status(self) -> None:
        """Ask the sphere for its status (light, levels, temperature, on-time). It restarts the watchdog but never
        keeps the light on: every lit period ends at its limit (the driver's supervisor and the firmware)."""
        sphere = self.sphere
        if sphere is None or self._poll_pending:
            return
        self._poll_pending = True

        def work() -> dict:
            return sphere.status()

        def done(status: dict) -> None:
            if sphere is not self.sphere:
                return
            status = dict(status)
            status["dose"] = self.dose.update(time.monotonic(), status["light_on"], status["levels"])
            self.last_status = status
            self.sphereStatus.emit(status)

        def failed(exc: BaseException) -> None:
            log.warning("LED sphere status: %s", exc)

        self.runner.submit(work, pool="devices", name="sphere status", on_result=done, on_error=failed,
                           on_finished=lambda: setattr(self, "_poll_pending", False))

    # ------------------------------------------------------------------ the light, by hand
    def run_light(self, plan: Sequence, title: str, *, on_finished: Callable[[str], None] | None = None,
                  on_error: Callable[[BaseException], None] | None = None) -> TaskHandle | None:
        """Run a light plan (app.workflow.light_plans) through the run engine on the sphere, in the ``light`` pool;
        ``on_finished(outcome)`` ('done', 'cancelled' or 'failed') on the GUI thread; an error is a dialog titled
        ``title``. :meth:`stop_light` cancels it (within one tick)."""
        sphere = self.sphere
        if sphere is None:
            self.failed.emit(title, SphereError("the LED sphere is not connected: connect it in Devices first",
                                                kind="port"))
            return None
        engine = RunEngine(plan.name, StandDevices(sphere=sphere, session=self.session), control=plan.control)
        self._light_plans.append(plan)
        outcome = ["failed"]

        def work() -> None:
            try:
                engine.run_plan(plan)
                outcome[0] = "done"
            except Cancelled:
                outcome[0] = "cancelled"

        def finished() -> None:
            if plan in self._light_plans:
                self._light_plans.remove(plan)
            self.poll_status()
            if on_finished is not None:
                on_finished(outcome[0])

        def failed(exc: BaseException) -> None:
            if on_error is not None:
                on_error(exc)
            self.failed.emit(title, exc)
        return self.runner.submit(work, pool="light", name=title, on_error=failed, on_finished=finished,
                                  on_cancel=plan.cancel)

    def stop_light(self) -> None:
        """End every light held by hand (the manual and the framing light): their runs end dark, read back."""
        for plan in list(self._light_plans):
            plan.cancel()

    def held_light(self) -> HeldLight | None:
        return next((p for p in self._light_plans if isinstance(p, HeldLight) and not p.cancelled), None)

    def apply_light(self, light: LightSource, switch_on: bool | None = None,
                    on_done: Callable[[], None] | None = None) -> TaskHandle | None:
        """The manual light's levels: kept for 'Light ON'; while the manual light is on, its levels change (the
        same lit period); ``switch_on`` True / False switches it on (capped) / off as well."""
        if self.sphere is None:
            self.failed.emit("Apply the light", SphereError(
                "the LED sphere is not connected: connect it in Devices first", kind="port"))
            return None
        self.manual_light = light
        held = self.held_light()
        self.lightApplied.emit(light)
        handle = None
        if switch_on is False:
            handle = self.set_light_on(False)
        elif held is not None:
            held.change(light)
        elif switch_on is True:
            handle = self.set_light_on(True)
        if on_done:
            on_done()
        return handle

    def set_light_on(self, on: bool) -> TaskHandle | None:
        """'Light ON': the levels last applied for at most ``manual_max_on_s`` (a HeldLight plan; on already: the
        same lit period, never extended). 'Light OFF': every light held by hand ends, and the run reads the light
        back off."""
        if self.sphere is None:
            self.failed.emit("Switch the light", SphereError(
                "the LED sphere is not connected: connect it in Devices first", kind="port"))
            return None
        if not on:
            self.stop_light()
            return self.run_light(Dark(), "Switch the light")
        if self.held_light() is not None:
            return None
        try:
            plan = HeldLight(self.manual_light or LightSource((), (), "none"), self.manual_max_on_s)
        except ValueError as exc:
            self.failed.emit("Switch the light", ValueError(f"{exc} (Light source: Apply)"))
            return None
        self.stop_light()                       # the framing light, if on, ends first (its run ends dark)
        return self.run_light(plan, "Switch the light")

    def plan_run(self, seq: Sequence, settings: Any) -> Run:
        """A run of one plan on the copy stand's run engine (these devices, the current session; ``settings``: an
        app.workflow.copystand.StandSettings)."""
        return Run.of(seq, lambda hooks: self.copy_stand(settings, hooks).engine)

    # ------------------------------------------------------------------ camera
    def detect_cameras(self, on_result: Callable[[tuple[list[str], list[str]]], None],
                       on_finished: Callable[[], None] | None = None) -> TaskHandle:
        return self.device_call(discover_cameras, "Detect cameras", on_result=on_result, on_finished=on_finished)

    def connect_camera(self, choice: str, on_done: Callable[[bool], None] | None = None) -> TaskHandle:
        def work() -> Camera:
            if choice == VIRTUAL_CAMERA:
                return self._virtual_devices()[0]
            return open_camera(choice)

        return self._connect(work, "Connect the camera", self._set_camera, choice, choice == VIRTUAL_CAMERA, on_done)

    def _set_camera(self, camera: Camera | None, name: str) -> None:
        self.camera = camera
        self.camera_name = name if camera is not None else ""
        self.cameraChanged.emit()
        if camera is not None:
            self.message.emit(f"camera connected: {name}")

    def disconnect_camera(self) -> TaskHandle | None:
        cam, name = self.camera, self.camera_name
        if cam is None:
            return None
        self._set_camera(None, "")
        if name == VIRTUAL_CAMERA:
            return None                          # the virtual lab owns it
        return self.device_call(lambda: close_camera(cam), "Disconnect the camera",
                                on_finished=lambda: self.message.emit("camera disconnected"))

    # ------------------------------------------------------------------ copy stand
    def stand(self, stand_in: str | Mapping[str, str] = "") -> Callable[[str, bool], Any] | None:
        """What places things on the stand: the virtual lab's sample changer (an original is shown as its virtual
        stand-in, e.g. 'shadow' - one for all, or per original identifier - loaded in the changer's magazine under
        its identifier), or None on a real stand (the run engine then asks the technician)."""
        lab = self.virtual_lab
        if lab is None:
            return None
        default = stand_in if isinstance(stand_in, str) else ""
        stand_ins = {} if isinstance(stand_in, str) else dict(stand_in)

        def place(what: str, nd: bool = False) -> str:
            return lab.place(what, nd, stand_ins.get(what.removeprefix("original:"), default))
        return place

    def copy_stand(self, settings: Any, hooks: Any = None, stand_in: str | Mapping[str, str] = "", *,
                   unlit: bool = False) -> Any:
        """An app.workflow.copystand.CopyStand on these devices and the current session (``hooks``: the
        callbacks of an app.workflow.engine.Run: progress, cancel, prompts, events, its control); ``unlit``: its
        sphere refuses to switch on (a Keep run takes only what the session holds: app.gui.calibration_keep)."""
        from dualrgb.app.gui.calibration_keep import UnlitSphere
        from dualrgb.app.workflow.copystand import CopyStand

        if self.camera is None or self.sphere is None:
            raise ValueError("connect the LED sphere and the camera in Devices first")
        if self.session is None:
            raise ValueError("no session: one is made when a calibration, a run or an original starts")
        sphere = UnlitSphere(self.sphere) if unlit else self.sphere
        return CopyStand(self.camera, sphere, self.session, stand=self.stand(stand_in), settings=settings,
                         **(hooks.stand_kwargs() if hooks is not None else {}))

    def lab_charts(self, charts: dict[str, Any]) -> None:
        """Virtual lab only (devices or worker thread): its stand holds ``charts`` (the stand's own; {}: the
        packaged targets), as a technician puts the day's charts on a physical stand."""
        if self.virtual_lab is not None:
            self.virtual_lab.use_charts(dict(charts))

    def lab_placement(self, charts: dict[str, Any]) -> dict[str, Any]:
        """Virtual lab only: the targets laid too small to be found in its frames (subject key -> PatchGrid, as the
        lab lays them: what a technician would place by hand; app.lab.targets.too_small_to_find); {} otherwise."""
        from dualrgb.app.lab.targets import too_small_to_find
        from dualrgb.app.workflow.vocabulary import Subject

        lab = self.virtual_lab
        if lab is None:
            return {}
        return {Subject.target(role).key: grid
                for role, (grid, _px) in too_small_to_find(lab.mode, (lab.width, lab.height), charts).items()}

    @staticmethod
    def virtual_originals() -> list[str]:
        from dualrgb.drivers.virtual.originals import ORIGINALS

        return list(ORIGINALS)

    # ------------------------------------------------------------------ session
    def session_definition(self) -> dict:
        """What defines the frames of a session made here (app.session: reopening with anything else is
        refused, naming the difference): the mode (the virtual lab's when it runs), the camera, its world and image
        area (app.workflow.stand_devices.stand_definition)."""
        return stand_definition(self.virtual_lab.mode if self.virtual_lab is not None else self.mode, self.camera)

    def set_session(self, session: CaptureSession | None, note: str = "") -> None:
        """Make ``session`` the current one; ``note`` says why it was made when it was made for the technician
        (the status bar and the guide show it)."""
        if self.session_log is not None:
            self.session_log.stop()
        self.session = session
        self.session_note = note if session is not None else ""
        self.session_log = SessionLog(session.path).start() if session is not None else None
        self.sessionChanged.emit()
        if session is not None:
            self.message.emit(f"new session {session.path.name} in {session.path.parent} ({note})" if note
                              else f"session folder {session.path}")

    # ------------------------------------------------------------------ shutdown
    def stop_polling(self) -> None:
        self._status_timer.stop()

    def shutdown(self) -> None:
        """Window closing: LEDs off, ports closed, the virtual lab stopped (on the devices thread)."""
        self.stop_light()
        sphere, lab, cam, owned = self.sphere, self.virtual_lab, self.camera, self._lab_devices
        self.sphere = self.camera = None
        self.virtual_lab, self._lab_devices = None, None
        lab_camera, lab_sphere = owned if owned is not None else (None, None)
        for s in {id(x): x for x in (sphere, lab_sphere) if x is not None}.values():
            with owning(StandDevices(sphere=s), "shutdown"):            # after the light held by hand has ended
                report = close_sphere(s)
            if not report.off:
                log.error("switching the sphere off at exit: %s", report.message)
        for c in {id(x): x for x in (cam, lab_camera) if x is not None}.values():
            close_camera(c)
        if lab is not None:
            lab.stop()
        if self.session_log is not None:
            self.session_log.stop()
            self.session_log = None


def current_levels(status: dict) -> LightSource:
    return light_from_levels(status.get("levels", [0.0] * 10))
