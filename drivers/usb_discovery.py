"""What is plugged in: cameras (libgphoto2 autodetect, and pyusb for Nikon 04b0:*), serial ports (the LED
controller), and a hint when a camera is on USB but gphoto2 cannot see or claim it.

Every probe is bounded in time (a daemon thread with a deadline) and "nothing found" is never an error:
pyusb without a libusb backend, missing permissions or no gphoto2 simply contribute nothing (logged at
debug). ``discover()`` returns within a few seconds.
"""
from __future__ import annotations

import logging
import os
import re
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from typing import TypeVar

from dualrgb.drivers.camera.gphoto_errors import CAMERA_DAEMONS, FREE_CAMERA_ADVICE

log = logging.getLogger(__name__)

T = TypeVar("T")

NIKON_VENDOR_ID = 0x04B0
NIKON_PRODUCTS = {0x0434: "Nikon D610"}          # the copy stand's camera; other Nikon ids shown as numbers
STILL_IMAGE_CLASS = 6                             # USB interface class of PTP cameras



@dataclass
class CameraInfo:
    """A camera as one probe saw it. ``port`` is gphoto2's ('usb:001,007'), empty for pyusb-only entries."""

    model: str
    source: str                                   # 'gphoto2' or 'usb'
    port: str = ""
    vendor_id: int | None = None
    product_id: int | None = None
    bus: int | None = None
    address: int | None = None
    status: str = ""                              # after a probe: 'ok' or the problem

    @property
    def usb_id(self) -> str:
        if self.vendor_id is None or self.product_id is None:
            return ""
        return f"{self.vendor_id:04x}:{self.product_id:04x}"

    @property
    def bus_address(self) -> tuple[int, int] | None:
        if self.bus is not None and self.address is not None:
            return self.bus, self.address
        return parse_usb_port(self.port)


@dataclass
class SerialPortInfo:
    device: str
    description: str = ""
    hwid: str = ""
    vendor_id: int | None = None
    product_id: int | None = None
    serial_number: str | None = None
    manufacturer: str | None = None

    @property
    def is_usb(self) -> bool:
        """USB serial adapters (the LED controller) have vendor/product ids; built-in UARTs do not."""
        return self.vendor_id is not None


@dataclass
class DeviceReport:
    gphoto_cameras: list[CameraInfo] = field(default_factory=list)
    usb_cameras: list[CameraInfo] = field(default_factory=list)
    serial_ports: list[SerialPortInfo] = field(default_factory=list)
    hints: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)   # why a probe found nothing (no backend, timed out ...)

    @property
    def usb_serial_ports(self) -> list[SerialPortInfo]:
        return [p for p in self.serial_ports if p.is_usb]

    @property
    def nothing_found(self) -> bool:
        return not (self.gphoto_cameras or self.usb_cameras or self.usb_serial_ports)

    def to_dict(self) -> dict:
        d = asdict(self)
        for key in ("gphoto_cameras", "usb_cameras"):
            for cam, info in zip(d[key], getattr(self, key), strict=True):
                cam["usb_id"] = info.usb_id
        for port, info in zip(d["serial_ports"], self.serial_ports, strict=True):
            port["is_usb"] = info.is_usb
        d["nothing_found"] = self.nothing_found
        return d


def parse_usb_port(port: str) -> tuple[int, int] | None:
    """(bus, address) from a gphoto2 port 'usb:001,007'; None for other ports."""
    m = re.fullmatch(r"usb:(\d+),(\d+)", port or "")
    return (int(m.group(1)), int(m.group(2))) if m else None


def _bounded(fn: Callable[[], T], timeout_s: float, default: T, what: str, notes: list[str]) -> T:
    """Run ``fn`` in a daemon thread; give up after ``timeout_s`` (a hung USB call must not hang us)."""
    box: dict = {}

    def target():
        try:
            box["value"] = fn()
        except Exception as exc:  # noqa: BLE001 - any probe failure means 'found nothing', reported in notes
            box["error"] = exc

    t = threading.Thread(target=target, name=f"probe-{what}", daemon=True)
    t.start()
    t.join(timeout_s)
    if t.is_alive():
        notes.append(f"{what}: no answer within {timeout_s:.0f} s")
        log.debug("%s timed out after %.1f s", what, timeout_s)
        return default
    if "error" in box:
        notes.append(f"{what}: {box['error']}")
        log.debug("%s failed: %s", what, box["error"])
        return default
    return box["value"]


# ----------------------------------------------------------------------------------------- probes
def gphoto_cameras() -> list[CameraInfo]:
    """Cameras libgphoto2 autodetects (raises if gphoto2 is missing or fails; discover() catches)."""
    from dualrgb.drivers.camera.gphoto import GPhotoCamera

    out = []
    for model, port in GPhotoCamera.detect():
        ba = parse_usb_port(port)
        out.append(CameraInfo(model=model, source="gphoto2", port=port,
                              bus=ba[0] if ba else None, address=ba[1] if ba else None))
    return out


def _pyusb_backend():
    """pyusb's default libusb backend, else the libusb that the gphoto2 wheel bundles; None when neither."""
    import usb.backend.libusb1

    backend = usb.backend.libusb1.get_backend()
    if backend is not None:
        return backend
    try:
        import glob

        import gphoto2

        libs = glob.glob(os.path.join(os.path.dirname(gphoto2.__file__) + ".libs", "libusb-1*.so*"))
    except ImportError:
        libs = []
    for lib in libs:
        backend = usb.backend.libusb1.get_backend(find_library=lambda _name, lib=lib: lib)
        if backend is not None:
            return backend
    return None


def _is_camera(dev) -> bool:
    if dev.idVendor == NIKON_VENDOR_ID or dev.bDeviceClass == STILL_IMAGE_CLASS:
        return True
    try:
        return any(intf.bInterfaceClass == STILL_IMAGE_CLASS for cfg in dev for intf in cfg)
    except Exception as exc:  # noqa: BLE001 - pyusb raises USBError/NotImplementedError/ValueError per backend
        log.debug("cannot read descriptors of %04x:%04x: %s", dev.idVendor, dev.idProduct, exc)
        return False


def usb_cameras() -> list[CameraInfo]:
    """Nikon devices (vendor 04b0) and any USB still-image (PTP) device, from the USB descriptors."""
    import usb.core

    backend = _pyusb_backend()
    if backend is None:
        raise RuntimeError("pyusb has no libusb backend (USB listing skipped)")
    out = []
    for dev in usb.core.find(find_all=True, backend=backend):
        if not _is_camera(dev):
            continue
        if dev.idVendor == NIKON_VENDOR_ID:
            model = NIKON_PRODUCTS.get(dev.idProduct, f"Nikon camera {dev.idVendor:04x}:{dev.idProduct:04x}")
        else:
            model = f"USB camera {dev.idVendor:04x}:{dev.idProduct:04x}"
        out.append(CameraInfo(model=model, source="usb", vendor_id=dev.idVendor, product_id=dev.idProduct,
                              bus=dev.bus, address=dev.address))
    return out


def serial_ports() -> list[SerialPortInfo]:
    from serial.tools import list_ports

    out = []
    for p in sorted(list_ports.comports(), key=lambda p: p.device):
        out.append(SerialPortInfo(device=p.device, description="" if p.description == "n/a" else p.description,
                                  hwid="" if p.hwid == "n/a" else p.hwid, vendor_id=p.vid, product_id=p.pid,
                                  serial_number=p.serial_number, manufacturer=p.manufacturer))
    return out


def usb_device_holders(bus: int, address: int, time_budget_s: float = 1.0) -> list[str]:
    """'name (pid N)' of processes that have /dev/bus/usb/BBB/DDD open (Linux; only what we may read)."""
    target = f"/dev/bus/usb/{bus:03d}/{address:03d}"
    found = []
    deadline = time.monotonic() + time_budget_s
    try:
        pids = [d for d in os.listdir("/proc") if d.isdigit()]
    except OSError:
        return []
    for pid in pids:
        if time.monotonic() > deadline:
            break
        fd_dir = f"/proc/{pid}/fd"
        try:
            fds = os.listdir(fd_dir)
        except OSError:
            continue
        for fd in fds:
            try:
                if os.readlink(f"{fd_dir}/{fd}") == target:
                    with open(f"/proc/{pid}/comm") as fh:
                        found.append(f"{fh.read().strip()} (pid {pid})")
                    break
            except OSError:
                continue
    return found


def camera_daemons() -> list[tuple[str, int]]:
    """(name, pid) of the desktop daemons that claim PTP cameras as soon as they appear (gvfs's gphoto2 volume
    monitor on Linux, ptpcamerad on macOS)."""
    try:
        import psutil
    except ImportError:
        return []
    found: list[tuple[str, int]] = []
    for proc in psutil.process_iter(["name", "cmdline"]):
        try:
            name = proc.info.get("name") or ""
            cmd = " ".join(proc.info.get("cmdline") or [])
        except (psutil.Error, OSError):
            continue
        found += [(daemon, proc.pid) for daemon in CAMERA_DAEMONS if daemon in name or daemon in cmd]
    return found


def probe_camera(cam: CameraInfo) -> str:
    """Open and close one gphoto2 camera: 'ok', or the one-line problem (e.g. claimed by gvfs, -53)."""
    from dualrgb.drivers.camera.base import CameraError
    from dualrgb.drivers.camera.gphoto import GPhotoCamera

    try:
        with GPhotoCamera(model=cam.model, port=cam.port, busy_tries=1):
            return "ok"
    except CameraError as exc:
        return str(exc)


def claimed_camera_hints(report: DeviceReport) -> list[str]:
    """Hints for cameras that are on USB but that gphoto2 does not list, or lists but cannot open."""
    hints = []
    seen = {c.bus_address for c in report.gphoto_cameras if c.bus_address}
    for cam in report.usb_cameras:
        if cam.bus_address in seen:
            continue
        where = f"bus {cam.bus} device {cam.address}"
        ba = cam.bus_address
        holders = usb_device_holders(*ba) if ba else []
        held = f"held by {', '.join(holders)}; " if holders else ""
        hints.append(f"{cam.model} ({cam.usb_id}, {where}) is on USB but gphoto2 does not list it: {held}"
                     f"{FREE_CAMERA_ADVICE}, and check the camera's USB mode and your USB permissions")
    for cam in report.gphoto_cameras:
        if cam.status and cam.status != "ok":
            ba = cam.bus_address
            holders = usb_device_holders(*ba) if ba else []
            held = f" (held by {', '.join(holders)})" if holders else ""
            hints.append(f"{cam.model} on {cam.port} cannot be opened{held}: {cam.status}")
    if (report.gphoto_cameras or report.usb_cameras) and not any(d in h for h in hints for d in CAMERA_DAEMONS):
        running = camera_daemons()
        for name in sorted({name for name, _ in running}):
            pids = [pid for n, pid in running if n == name]
            hints.append(f"{name} is running (pid {', '.join(map(str, pids))}) and may claim the camera: "
                         f"{FREE_CAMERA_ADVICE}")
    return hints


def discover(*, probe: bool = False, timeout_s: float = 3.0) -> DeviceReport:
    """Everything attached. ``probe`` also opens each gphoto2 camera once to check it can be claimed."""
    report = DeviceReport()
    report.gphoto_cameras = _bounded(gphoto_cameras, timeout_s, [], "gphoto2 autodetect", report.notes)
    report.usb_cameras = _bounded(usb_cameras, timeout_s, [], "pyusb", report.notes)
    report.serial_ports = _bounded(serial_ports, timeout_s, [], "serial ports", report.notes)
    # pyusb knows the USB ids; copy them onto the gphoto2 entries for the same bus/address
    by_address = {c.bus_address: c for c in report.usb_cameras if c.bus_address}
    for cam in report.gphoto_cameras:
        twin = by_address.get(cam.bus_address) if cam.bus_address else None
        if twin is not None:
            cam.vendor_id, cam.product_id = twin.vendor_id, twin.product_id
    if probe:
        for cam in report.gphoto_cameras:
            cam.status = _bounded(partial(probe_camera, cam), timeout_s + 2.0,
                                  "no answer when opening it (switch the camera off and on)",
                                  f"open {cam.model}", report.notes)
    report.hints = _bounded(lambda: claimed_camera_hints(report), timeout_s, [], "USB hints", report.notes)
    from dualrgb.drivers.camera.gphoto import TETHERING_UNAVAILABLE, gphoto_available

    if not gphoto_available():
        report.hints.append(TETHERING_UNAVAILABLE)
    for note in report.notes:
        log.debug("discovery: %s", note)
    return report
