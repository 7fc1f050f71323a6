"""Run drivers.camera.gphoto against libgphoto2's own virtual camera and print one JSON object.

libgphoto2 reads ``VCAMERADIR`` when gphoto2 is first imported, so this runs in a subprocess started by
test_gphoto_vcam.py with the environment already set (VCAMERADIR, XDG_CONFIG_HOME at a temp dir). The
virtual camera appears as 'Nikon DSC D750' on usb:001,001; capture() copies a JPEG from the folder; DNG
files in the folder download byte-identical.

usage: python gphoto_vcam_helper.py detect|session|errors|nocamera|locale
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root

from dualrgb.drivers.camera.base import CameraError, CameraSettings
from dualrgb.drivers.camera.gphoto import GPhotoCamera, camera_error


def _err(exc: CameraError) -> dict:
    return {"code": exc.code, "message": str(exc)}


def detect() -> dict:
    return {"cameras": [list(c) for c in GPhotoCamera.detect()]}


def session() -> dict:
    out: dict = {}
    folder = Path(os.environ["VCAMERADIR"])
    cam = GPhotoCamera(model="Nikon DSC D750", port="usb:001,001", busy_delay_s=0.01)
    with cam:
        out["model"] = cam.model
        config = cam.list_config()
        out["config"] = {name: {"kind": e.kind, "value": e.value, "choices": e.choices, "readonly": e.readonly}
                         for name, e in config.items() if isinstance(e.value, (str, int, float, type(None)))}
        out["settings_before"] = cam.settings().__dict__
        out["shutter_speeds"] = cam.shutter_speeds()
        taken = cam.apply(CameraSettings(shutter_s=0.011, aperture=7.9, capture_target="Internal RAM"))
        out["applied"] = taken.__dict__
        out["shutter_widget_after"] = cam.get_config_value("shutterspeed")
        out["f_number_after"] = cam.get_config_value("f-number")
        # a capture returns the raw bytes in memory and the camera-side name
        cap = cam.capture(0.1)
        out["capture"] = {"filename": cap.filename, "size": len(cap.data), "head": cap.data[:3].hex(),
                          "exposure_s": cap.exposure_s, "camera": cap.camera, "aperture": cap.aperture,
                          "mime": cap.extra.get("mime"), "bulb": cap.extra.get("bulb"),
                          "latency_s": cap.extra.get("latency_s")}
        out["trigger_waits"] = cam._trigger_waits
        # files placed in VCAMERADIR are on the camera's store; DNG downloads byte-identical
        files = cam.list_files()
        out["files"] = files
        dng = next(f for f in files if f.upper().endswith(".DNG"))
        d_folder, d_name = dng.rsplit("/", 1)
        data, mime = cam.download(d_folder, d_name)
        out["dng"] = {"name": d_name, "mime": mime, "identical": data == (folder / d_name).read_bytes()}
        # set by name, then the errors a user can run into
        out["capturetarget_set"] = cam.set_config_value("capturetarget", "memory card")
        errors = {}
        for key, call in {
            "bad_choice": lambda: cam.set_config_value("capturetarget", "Nowhere"),
            "read_only": lambda: cam.set_config_value("serialnumber", "x"),
            "missing_setting": lambda: cam.apply(CameraSettings(iso=200)),
            "too_long_no_bulb": lambda: cam.capture(120.0),
            "preview": lambda: cam.preview(),
            "missing_file": lambda: cam.download("/store_00010001", "NOPE.NEF"),
        }.items():
            try:
                call()
                errors[key] = None
            except CameraError as exc:
                errors[key] = _err(exc)
        out["errors"] = errors
        cam.reopen()  # the recovery after -52 (the virtual camera resets its settings; a real one keeps them)
        out["reopened"] = {"open": cam.is_open, "f_number": cam.get_config_value("f-number")}
    out["closed"] = not cam.is_open
    try:
        cam.settings()
    except CameraError as exc:
        out["after_close"] = _err(exc)
    # a second open/close cycle works (the device was released)
    with GPhotoCamera() as again:
        out["reopen_model"] = again.model
    out["wrong_port"] = None
    try:
        GPhotoCamera(port="usb:009,009").open()
    except CameraError as exc:
        out["wrong_port"] = _err(exc)
    return out


def errors() -> dict:
    import gphoto2 as gp

    out = {}
    for code in (-105, -53, -110, -52, -10, -6, -7, -1):
        exc = gp.GPhoto2Error(code)
        out[str(code)] = _err(camera_error(exc, "open camera"))
    return out


def locale_scenario() -> dict:
    """Labels and error texts under a translated locale (LANGUAGE set by the test), before and after the driver."""
    import locale

    locale.setlocale(locale.LC_ALL, "")             # what Qt does at start-up
    import gphoto2 as gp

    out: dict = {"before": {"error": gp.GPhoto2Error(-105).string}}
    with GPhotoCamera(model="Nikon DSC D750", port="usb:001,001") as cam:
        out["after"] = {"error": gp.GPhoto2Error(-105).string,
                        "capturetarget": cam.list_config()["capturetarget"].choices,
                        "set_target": cam.set_config_value("capturetarget", "interner Speicher")}
    return out


def nocamera() -> dict:
    """Nothing attached (VCAMERADIR unset): the raw library error and ours."""
    import gphoto2 as gp

    out: dict = {"detect": [list(c) for c in GPhotoCamera.detect()]}
    try:
        gp.Camera().init()
        out["raw"] = None
    except gp.GPhoto2Error as exc:
        out["raw"] = {"code": exc.code, "message": str(exc)}
    try:
        GPhotoCamera().open()
        out["ours"] = None
    except CameraError as exc:
        out["ours"] = _err(exc)
    return out


if __name__ == "__main__":
    scenario = sys.argv[1]
    result = {"detect": detect, "session": session, "errors": errors, "nocamera": nocamera,
              "locale": locale_scenario}[scenario]()
    print(json.dumps(result, default=str))
