"""Opening the copy stand's devices and describing them to a session: written once, for the CLI
(app.commands.stand_options) and the GUI (app.gui.device_hub).

    sphere = open_sphere("/dev/ttyACM0")          # identified, every LED off (read back), closed on failure
    camera = open_camera("Nikon DSC D610 @ usb:001,004", iso=100)      # or 'auto', or a bridge 'tcp://HOST:PORT'
    changer = open_changer("socket://127.0.0.1:40125")                 # an automated sample changer, if any
    close_sphere(sphere)                          # every LED off (read back), then the port closed
    close_camera(camera)
    session.extend_definition(**camera_definition_of(camera))          # what a resumed session must match

These are the only ways the front ends open and close a device; everything in between - every light switched, every
frame - is the run engine's (app.workflow.engine). Both front ends thus start from the same state: a sphere is
switched off (and its answer read) before anything else, a camera named without its port is refused with the same
advice, and a session records the same camera identity and image area. Every device is named by its address: a
serial port or a pyserial URL for the sphere and the sample changer, 'MODEL @ PORT' or a camera bridge's ``tcp://``
address for the camera (drivers.camera.network; `dualrgb lab serve` serves the virtual lab's instruments so).
"""
from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.drivers.led_sphere import LedSphere, LightReport
    from dualrgb.drivers.sample_changer import SampleChanger

log = logging.getLogger(__name__)

AUTO_CAMERA = "auto"
NO_CAMERA_ADVICE = ("no camera found: connect the camera by USB, switch it on (mode dial to M) and look for it "
                    "again (`dualrgb devices`, or 'Detect' in Devices); on a desktop, close photo programs that grab "
                    "it (gvfs on Linux, ptpcamerad on macOS)")


def open_sphere(port: str) -> LedSphere:
    """The LED sphere on ``port``, identified and switched off (every LED 0); when any of that fails it is closed
    again and the SphereError says the light's state (its own words, or the read-back as a note)."""
    from dualrgb.drivers.led_sphere import LedSphere, SphereError

    sphere = LedSphere(port).open()
    try:
        info = sphere.identify()
        sphere.shutdown()                   # start from a known state: every LED 0, light off (read back)
    except SphereError as exc:
        if exc.light is None:               # the error does not say the light's state: read it back
            exc.add_note(sphere.ensure_off().message)
        sphere.close(leave_on=True)         # switched off above, as far as the sphere answered
        raise
    log.info("LED sphere on %s: %s firmware %s", port, info.get("model"), info.get("firmware"))
    return sphere


def close_sphere(sphere: LedSphere, keep_open: bool = False) -> LightReport:
    """Every LED 0 and the light off, read back, then the port closed (``keep_open``: left open, e.g. the virtual
    lab's, which its camera reads); never raises: what is known about the light (logged when not off)."""
    report = sphere.ensure_off()
    if not report.off:
        log.error("closing the LED sphere: %s", report.message)
    if not keep_open:
        sphere.close(leave_on=True)         # switched off just above, as far as the sphere answered
    return report


def close_camera(camera: Camera) -> None:
    """Close the camera's port; a failure is logged (nothing of it is lost: frames are in the session)."""
    from dualrgb.drivers.camera.base import CameraError

    try:
        camera.close()
    except CameraError as exc:
        log.warning("closing the camera: %s", exc)


def camera_choice(choice: str) -> tuple[str | None, str | None]:
    """'MODEL @ PORT' (as `dualrgb devices` and Devices list them) or 'auto' (the first camera found) ->
    (model, port); a CameraError with :data:`NO_CAMERA_ADVICE` when there is none."""
    from dualrgb.drivers.camera.base import CameraError

    if choice == AUTO_CAMERA:
        from dualrgb.drivers.usb_discovery import gphoto_cameras

        found = gphoto_cameras()
        if not found:
            raise CameraError(NO_CAMERA_ADVICE, -105)
        return found[0].model, found[0].port
    model, _, port = choice.partition(" @ ")
    if not port:
        raise CameraError(f"camera {choice!r}: expected 'MODEL @ PORT' or 'auto'; {NO_CAMERA_ADVICE}", -105)
    return model or None, port


def open_camera(choice: str, iso: int | None = None, aperture: float | None = None) -> Camera:
    """The tethered camera ``choice`` (:func:`camera_choice`; a camera bridge's ``tcp://HOST:PORT``:
    drivers.camera.network), opened, with ISO / aperture applied when given (closed again when that fails)."""
    from dualrgb.drivers.camera.bridge_protocol import is_address

    camera: Camera
    if is_address(choice):
        from dualrgb.drivers.camera.network import NetworkCamera

        camera = NetworkCamera(choice)
    else:
        from dualrgb.drivers.camera.gphoto import GPhotoCamera

        model, port = camera_choice(choice)
        camera = GPhotoCamera(model=model, port=port)
    camera.open()
    try:
        apply_settings(camera, iso, aperture)
    except BaseException:
        camera.close()
        raise
    return camera


def open_changer(port: str) -> SampleChanger:
    """The automated sample changer on ``port`` (a serial port or pyserial URL), identified (closed again when
    it does not answer)."""
    from dualrgb.drivers.sample_changer import SampleChanger

    changer = SampleChanger(port).open()
    try:
        info = changer.identify()
    except BaseException:
        changer.close()
        raise
    log.info("sample changer on %s: %s %s", port, info.get("model"), info.get("version"))
    return changer


def apply_settings(camera: Camera, iso: int | None = None, aperture: float | None = None) -> None:
    from dualrgb.drivers.camera.base import CameraSettings

    if iso is not None or aperture is not None:
        camera.apply(CameraSettings(iso=iso, aperture=aperture))


def camera_definition_of(camera: Camera) -> dict[str, Any]:
    """What a session records of the camera (its identity and image area): a session is resumed only with the
    same (app.session)."""
    from dualrgb.app.session.manifest import camera_definition, image_area_definition

    return {"camera": camera_definition(camera), **image_area_definition(camera)}


def stand_definition(mode: str, camera: Camera | None = None) -> dict[str, Any]:
    """A session's definition from the stand: the mode and the camera (:func:`camera_definition_of`: its identity,
    the world a simulated camera reports, its image area)."""
    out: dict[str, Any] = {"mode": mode}
    if camera is not None:
        out.update(camera_definition_of(camera))
    return out
