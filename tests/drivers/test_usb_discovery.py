"""dualrgb.drivers.usb_discovery: never raises for 'nothing found', bounded probes, claimed-camera hints."""
from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest

from dualrgb.drivers import usb_discovery as ud
from dualrgb.drivers.usb_discovery import CameraInfo, DeviceReport, SerialPortInfo, discover, parse_usb_port

D610_PTP = CameraInfo(model="Nikon DSC D610", source="gphoto2", port="usb:001,007", bus=1, address=7)
D610_USB = CameraInfo(model="Nikon D610", source="usb", vendor_id=0x04B0, product_id=0x0434, bus=1, address=7)
BUILTIN_UART = SerialPortInfo(device="/dev/ttyS0")
LED_CONTROLLER = SerialPortInfo(device="/dev/ttyACM0", description="Arduino Uno", vendor_id=0x2341,
                                product_id=0x0043)


@pytest.fixture
def probes(monkeypatch):
    """Replace the three hardware probes; tests fill in what each returns (or raises)."""
    state = SimpleNamespace(gphoto=[], usb=RuntimeError("pyusb has no libusb backend"), serial=[BUILTIN_UART],
                            holders=[], daemons=[], probe="ok")

    def result(value):
        if isinstance(value, Exception):
            raise value
        return [CameraInfo(**c.__dict__) if isinstance(c, CameraInfo) else c for c in value]

    monkeypatch.setattr(ud, "gphoto_cameras", lambda: result(state.gphoto))
    monkeypatch.setattr(ud, "usb_cameras", lambda: result(state.usb))
    monkeypatch.setattr(ud, "serial_ports", lambda: result(state.serial))
    monkeypatch.setattr(ud, "usb_device_holders", lambda bus, address: list(state.holders))
    monkeypatch.setattr(ud, "camera_daemons", lambda: list(state.daemons))
    monkeypatch.setattr(ud, "probe_camera", lambda cam: state.probe)
    return state


def test_nothing_attached_is_not_an_error(probes):
    report = discover()
    assert report.nothing_found
    assert report.gphoto_cameras == [] and report.usb_cameras == []
    assert report.serial_ports == [BUILTIN_UART]       # built-in UARTs don't count as 'found'
    assert any("pyusb" in n for n in report.notes)
    assert report.hints == []


def test_camera_on_usb_but_not_seen_by_gphoto2(probes):
    probes.usb = [D610_USB]
    probes.holders = ["gvfs-gphoto2-vo (pid 4242)"]
    report = discover()
    assert not report.nothing_found
    [hint] = report.hints
    assert hint.startswith("Nikon D610 (04b0:0434, bus 1 device 7) is on USB but gphoto2 does not list it")
    assert "held by gvfs-gphoto2-vo (pid 4242)" in hint
    assert "gio mount -s gphoto2" in hint and "pkill -f gvfs-gphoto2-volume-monitor" in hint


def test_camera_seen_by_both_gets_usb_id_and_no_hint(probes):
    probes.gphoto = [D610_PTP]
    probes.usb = [D610_USB]
    report = discover(probe=True)
    assert report.hints == []
    assert report.gphoto_cameras[0].usb_id == "04b0:0434"
    assert report.gphoto_cameras[0].status == "ok"


def test_camera_that_cannot_be_claimed(probes):
    probes.gphoto = [D610_PTP]
    probes.probe = ("open camera on usb:001,007: the camera's USB interface is claimed by another program, "
                    "usually the desktop's gvfs-gphoto2-volume-monitor: ... [gphoto2 -53]")
    probes.holders = ["gvfs-gphoto2-vo (pid 4242)"]
    report = discover(probe=True)
    [hint] = report.hints
    assert hint.startswith("Nikon DSC D610 on usb:001,007 cannot be opened (held by gvfs-gphoto2-vo (pid 4242))")
    assert "[gphoto2 -53]" in hint


def test_running_gvfs_monitor_is_mentioned(probes):
    probes.gphoto = [D610_PTP]
    probes.daemons = [("gvfs-gphoto2-volume-monitor", 31337)]
    report = discover()
    [hint] = report.hints
    assert "gvfs-gphoto2-volume-monitor is running (pid 31337)" in hint
    assert "killall -9 ptpcamerad" in hint                      # the advice names macOS' daemon too


def test_running_ptpcamerad_is_mentioned(probes):
    """macOS: the ptpcamerad daemon claims PTP cameras the way gvfs does on Linux."""
    probes.gphoto = [D610_PTP]
    probes.daemons = [("ptpcamerad", 512)]
    [hint] = discover().hints
    assert hint.startswith("ptpcamerad is running (pid 512)") and "Image Capture" in hint


def test_hung_probe_is_abandoned(probes, monkeypatch):
    release = threading.Event()

    def hangs():
        release.wait(30)
        return [D610_PTP]

    monkeypatch.setattr(ud, "gphoto_cameras", hangs)
    try:
        report = discover(timeout_s=0.2)
    finally:
        release.set()
    assert report.gphoto_cameras == []
    assert "gphoto2 autodetect: no answer within 0 s" in report.notes


class FakeUsbDevice(SimpleNamespace):
    """Like usb.core.Device: iterating gives configurations, iterating those gives interfaces."""

    def __iter__(self):
        return iter([[SimpleNamespace(bInterfaceClass=c) for c in self.interface_classes]])


def test_pyusb_listing_picks_nikon_and_ptp_devices(monkeypatch):
    def dev(vendor, product, bus, address, device_class=0, interface_classes=()):
        return FakeUsbDevice(idVendor=vendor, idProduct=product, bus=bus, address=address,
                             bDeviceClass=device_class, interface_classes=interface_classes)

    devices = [dev(0x04B0, 0x0434, 1, 7), dev(0x046D, 0xC077, 1, 3, interface_classes=[3]),
               dev(0x04A9, 0x32D2, 2, 4, interface_classes=[6]), dev(0x04B0, 0x0999, 2, 5)]
    import usb.core

    monkeypatch.setattr(ud, "_pyusb_backend", lambda: object())
    monkeypatch.setattr(usb.core, "find", lambda find_all, backend: iter(devices))
    cams = ud.usb_cameras()
    assert [(c.model, c.usb_id, c.bus, c.address) for c in cams] == [
        ("Nikon D610", "04b0:0434", 1, 7),
        ("USB camera 04a9:32d2", "04a9:32d2", 2, 4),
        ("Nikon camera 04b0:0999", "04b0:0999", 2, 5),
    ]


def test_pyusb_without_backend_raises_for_discover_to_note(monkeypatch):
    monkeypatch.setattr(ud, "_pyusb_backend", lambda: None)
    with pytest.raises(RuntimeError, match="no libusb backend"):
        ud.usb_cameras()


def test_real_machine_discovery_never_raises():
    report = discover(timeout_s=3.0)
    assert isinstance(report, DeviceReport)
    assert all(isinstance(p, SerialPortInfo) for p in report.serial_ports)
    d = report.to_dict()
    assert d["nothing_found"] == report.nothing_found


def test_parse_usb_port_and_holders():
    assert parse_usb_port("usb:001,007") == (1, 7)
    assert parse_usb_port("usb:") is None
    assert parse_usb_port("ptpip:192.168.1.2") is None
    assert ud.usb_device_holders(999, 999) == []
