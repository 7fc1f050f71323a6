"""Before Qt is touched: can its platform plugin open a window here? (Qt-free)

Qt aborts the whole process (exit 134, a core dump) when its platform plugin cannot load or its display does
not answer. This module finds those cases first and says, in one line, what to do:

* the xcb plugin's system libraries (``missing_xcb_libraries``): each is loaded with ``dlopen`` as Qt would;
  when one is missing, the line names it and gives the install command (Debian/Ubuntu and Fedora names);
* an X display that does not answer (``x_display_problem``: a stale ``DISPLAY=:99``), through libxcb itself;
* a Wayland socket that does not answer (``wayland_problem``: a stale ``WAYLAND_DISPLAY``).

macOS and Windows need none of this (their platform plugins ship with PySide6).
"""
from __future__ import annotations

import ctypes
import logging
import os
import re
import socket
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Optional

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SystemLibrary:
    soname: str           # what Qt's xcb plugin loads
    apt: str              # Debian / Ubuntu package
    dnf: str              # Fedora package
    checked: bool = True  # False: installed for completeness, not linked by current Qt (xinerama)


# the xcb plugin's libraries (issue 13: with these the GUI opens on a fresh Debian machine under Xvfb)
XCB_LIBRARIES = (
    SystemLibrary("libxcb.so.1", "libxcb1", "libxcb"),
    SystemLibrary("libxcb-cursor.so.0", "libxcb-cursor0", "xcb-util-cursor"),
    SystemLibrary("libxcb-icccm.so.4", "libxcb-icccm4", "xcb-util-wm"),
    SystemLibrary("libxcb-image.so.0", "libxcb-image0", "xcb-util-image"),
    SystemLibrary("libxcb-keysyms.so.1", "libxcb-keysyms1", "xcb-util-keysyms"),
    SystemLibrary("libxcb-randr.so.0", "libxcb-randr0", "libxcb"),
    SystemLibrary("libxcb-render-util.so.0", "libxcb-render-util0", "xcb-util-renderutil"),
    SystemLibrary("libxcb-shape.so.0", "libxcb-shape0", "libxcb"),
    SystemLibrary("libxcb-xinerama.so.0", "libxcb-xinerama0", "libxcb", checked=False),
    SystemLibrary("libxcb-xkb.so.1", "libxcb-xkb1", "libxcb"),
    SystemLibrary("libxkbcommon-x11.so.0", "libxkbcommon-x11-0", "libxkbcommon-x11"),
    SystemLibrary("libEGL.so.1", "libegl1", "libglvnd-egl"),
    SystemLibrary("libGL.so.1", "libgl1", "libglvnd-glx"),
    SystemLibrary("libfontconfig.so.1", "libfontconfig1", "fontconfig"),
    SystemLibrary("libdbus-1.so.3", "libdbus-1-3", "dbus-libs"),
)


def _packages(field: str) -> str:
    return " ".join(dict.fromkeys(getattr(lib, field) for lib in XCB_LIBRARIES if lib.soname != "libxcb.so.1"))


def install_command(os_release: Optional[Mapping[str, str]] = None) -> str:
    """The command that installs the GUI's system libraries on this distribution (both when unknown)."""
    info = _os_release() if os_release is None else os_release
    family = f"{info.get('ID', '')} {info.get('ID_LIKE', '')}".lower()
    apt = f"sudo apt-get install {_packages('apt')}"
    dnf = f"sudo dnf install {_packages('dnf')}"
    if re.search(r"\b(debian|ubuntu)\b", family):
        return apt
    if re.search(r"\b(fedora|rhel|centos)\b", family):
        return dnf
    return f"{apt} (Debian/Ubuntu) or {dnf} (Fedora)"


def _os_release() -> dict[str, str]:
    try:
        text = Path("/etc/os-release").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return {}
    out = {}
    for line in text.splitlines():
        key, sep, value = line.partition("=")
        if sep:
            out[key.strip()] = value.strip().strip('"')
    return out


def _dlopen(soname: str) -> bool:
    try:
        ctypes.CDLL(soname)
    except OSError:
        return False
    return True


def missing_xcb_libraries(loader: Optional[Callable[[str], bool]] = None) -> list[str]:
    """The sonames of the xcb plugin's libraries that cannot be loaded here (``loader``: dlopen by default)."""
    load = loader or _dlopen
    return [lib.soname for lib in XCB_LIBRARIES if lib.checked and not load(lib.soname)]


def xcb_libraries_problem(loader: Optional[Callable[[str], bool]] = None,
                          os_release: Optional[Mapping[str, str]] = None) -> Optional[str]:
    missing = missing_xcb_libraries(loader)
    if not missing:
        return None
    return (f"the Qt xcb platform plugin cannot load {', '.join(missing)} (not installed); install the GUI's "
            f"system libraries: {install_command(os_release)}")


def _parse_display(display: str) -> tuple[str, int]:
    m = re.fullmatch(r"(?:([^:]*)/)?([^:]*):(\d+)(?:\.\d+)?", display.strip())
    if not m:
        raise ValueError(display)
    return m.group(2), int(m.group(3))


def x_display_problem(display: str, timeout_s: float = 2.0) -> Optional[str]:
    """None when the X server of ``display`` accepts a connection (libxcb, as Qt does), else one line."""
    try:
        host, number = _parse_display(display)
    except ValueError:
        return f"DISPLAY={display!r} is not an X display name like :0"
    stale = (f"DISPLAY={display} but no X server answers there (a stale display?); open the GUI from a desktop "
             "session or set QT_QPA_PLATFORM=offscreen for headless use")
    if host and host != "unix":              # TCP (e.g. ssh -X): do not let libxcb wait for a TCP timeout
        try:
            socket.create_connection((host, 6000 + number), timeout=timeout_s).close()
        except OSError:
            return stale
    try:
        xcb = ctypes.CDLL("libxcb.so.1")
    except OSError:
        return None                           # reported by the library check
    xcb.xcb_connect.restype = ctypes.c_void_p
    xcb.xcb_connect.argtypes = [ctypes.c_char_p, ctypes.c_void_p]
    xcb.xcb_connection_has_error.argtypes = [ctypes.c_void_p]
    xcb.xcb_disconnect.argtypes = [ctypes.c_void_p]
    conn = xcb.xcb_connect(display.encode(), None)
    try:
        failed = xcb.xcb_connection_has_error(conn) != 0
    finally:
        xcb.xcb_disconnect(conn)
    return stale if failed else None


def wayland_problem(env: Mapping[str, str], timeout_s: float = 2.0) -> Optional[str]:
    """None when the Wayland compositor named by WAYLAND_DISPLAY accepts a connection, else one line."""
    name = env.get("WAYLAND_DISPLAY", "")
    path = Path(name) if name.startswith("/") else Path(env.get("XDG_RUNTIME_DIR", "")) / name
    stale = (f"WAYLAND_DISPLAY={name} but no Wayland compositor answers at {path} (a stale session?); open the "
             "GUI from a desktop session or set QT_QPA_PLATFORM=offscreen for headless use")
    try:
        if not stat.S_ISSOCK(os.stat(path).st_mode):
            return stale
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(timeout_s)
            s.connect(str(path))
    except OSError:
        return stale
    return None


def platform_problem(platform: str, env: Mapping[str, str],
                     loader: Optional[Callable[[str], bool]] = None) -> tuple[Optional[str], Optional[str]]:
    """(problem, platform to use) for a Linux desktop: ``platform`` is QT_QPA_PLATFORM's name ('' = Qt's
    choice). With no platform named and a stale Wayland socket beside a live X display, 'xcb' is chosen."""
    wayland_set, x_set = bool(env.get("WAYLAND_DISPLAY")), bool(env.get("DISPLAY"))
    if platform.startswith("wayland"):
        return wayland_problem(env), None
    if not platform and wayland_set:
        problem = wayland_problem(env)
        if problem is None:
            return None, None
        if not x_set:
            return problem, None
        platform = "xcb"                      # Qt would try the dead compositor first
    problem = xcb_libraries_problem(loader) or x_display_problem(env.get("DISPLAY", ""))
    return problem, (platform or None) if problem is None else None
