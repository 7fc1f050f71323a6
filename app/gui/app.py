"""Starting the GUI: display check, QApplication, the window, the virtual lab, the screenshot run."""
from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

log = logging.getLogger(__name__)

HEADLESS_PLATFORMS = ("offscreen", "minimal", "vnc", "eglfs", "linuxfb", "vkkhrdisplay")
NO_DISPLAY = ("no display found; set QT_QPA_PLATFORM=offscreen for headless use or run on a desktop")


def display_problem(env: Mapping[str, str] | None = None) -> str | None:
    """A one-line reason the GUI cannot open a window here, or None. Checked before Qt is touched (Qt would
    abort the whole process with a core dump)."""
    env = os.environ if env is None else env
    platform = (env.get("QT_QPA_PLATFORM") or "").split(":")[0].strip().lower()
    if platform in HEADLESS_PLATFORMS:
        return None
    if sys.platform in ("win32", "darwin"):
        return None
    if platform.startswith("wayland") and env.get("WAYLAND_DISPLAY"):
        return None
    if platform == "xcb" and env.get("DISPLAY"):
        return None
    if not platform and (env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")):
        return None
    if platform in ("xcb",) or platform.startswith("wayland"):
        return f"QT_QPA_PLATFORM={platform} but no matching display is set; " + NO_DISPLAY
    return NO_DISPLAY


def live_display_problem(env: Mapping[str, str] | None = None,
                         loader: Callable[[str], bool] | None = None) -> str | None:
    """After :func:`display_problem`'s rules: does the display really answer, and can Qt's platform plugin load
    here? One line (missing system libraries with the install command, a stale DISPLAY or WAYLAND_DISPLAY) or
    None. A stale Wayland socket beside a live X display makes Qt use xcb (QT_QPA_PLATFORM is set)."""
    from dualrgb.app.gui import platform_check

    env = os.environ if env is None else env
    platform = (env.get("QT_QPA_PLATFORM") or "").split(":")[0].strip().lower()
    if platform in HEADLESS_PLATFORMS or sys.platform in ("win32", "darwin"):
        return None
    problem, use = platform_check.platform_problem(platform, env, loader)
    if problem is None and use and use != platform and env is os.environ:
        log.info("using the Qt platform %s (WAYLAND_DISPLAY does not answer)", use)
        os.environ["QT_QPA_PLATFORM"] = use
    return problem


def pyside_drops_none_references() -> bool:
    """True for a PySide6 build that loses a reference to None on every void call (6.12.0 on Python < 3.12):
    such a window aborts with 'deallocating None' after a while, so it is refused up front."""
    if sys.version_info >= (3, 12):          # None is immortal there
        return False
    from PySide6.QtCore import QObject

    probe = QObject()
    before = sys.getrefcount(None)
    for _ in range(200):
        probe.setObjectName("probe")
    return before - sys.getrefcount(None) >= 150


def application(argv: list[str] | None = None):
    """The QApplication (created once), with pyqtgraph's defaults for white plots."""
    import pyqtgraph as pg
    from PySide6.QtWidgets import QApplication

    app = QApplication.instance()
    if app is None:
        QApplication.setOrganizationName("dualrgb")
        QApplication.setApplicationName("dualrgb")
        app = QApplication(argv or [sys.argv[0]])
    pg.setConfigOptions(antialias=True, background="w", foreground="k", imageAxisOrder="row-major")
    return app


def run(virtual_lab: bool = False, screenshot_dir: Path | None = None,
        frame_size: tuple[int, int] | None = None, world: str | None = None) -> int:
    if screenshot_dir is not None and (display_problem() or live_display_problem()) is not None:
        os.environ["QT_QPA_PLATFORM"] = "offscreen"      # screenshots need no screen
    problem = display_problem() or live_display_problem()
    if problem is not None:
        from dualrgb.app.cli import UserError
        raise UserError(problem)
    if pyside_drops_none_references():
        import PySide6

        from dualrgb.app.cli import UserError
        raise UserError(f"PySide6 {PySide6.__version__} has a reference-count bug that crashes the window on this "
                        "Python; install another version: pip install 'PySide6-Essentials!=6.12.0'")
    app = application()
    from dualrgb.app.gui.main_window import MainWindow

    if screenshot_dir is not None:
        import tempfile

        from PySide6.QtCore import QSettings

        from dualrgb.app.gui.screenshots import ScreenshotRun

        tmp = Path(tempfile.mkdtemp(prefix="dualrgb-screens-"))
        settings = QSettings(str(tmp / "dualrgb.ini"), QSettings.Format.IniFormat)
        # the virtual D610's shutter bumps on, so the Characterise picture shows what the sweep flags
        window = MainWindow(settings, frame_size=(300, 200), show_dialogs=False, shutter_bumps=True)
        window.lab.world = world
        window.resize(1400, 900)
        window.show()
        run_ = ScreenshotRun(window, Path(screenshot_dir), tmp)
        run_.start()
        app.exec()
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)          # the session made for the pictures
        return run_.exit_code

    window = MainWindow(frame_size=frame_size) if frame_size else MainWindow()
    window.lab.world = world                 # what the virtual lab renders (drivers.virtual.world)
    window.show()
    if virtual_lab:
        window.lab.start_virtual_lab()
    _close_on_signals(window)
    return app.exec()


def _close_on_signals(window) -> None:
    """Ctrl-C / SIGTERM / SIGHUP (the terminal closed) close the window the normal way (LEDs off, ports closed).
    Python runs signal handlers only when it gets control, so a timer hands it control a few times a second."""
    import signal

    from PySide6.QtCore import QTimer

    def close(signum, _frame) -> None:
        log.info("signal %d: closing the window", signum)
        window.close()
        from PySide6.QtWidgets import QApplication
        QApplication.quit()

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, close)
    timer = QTimer(window)
    timer.setInterval(250)
    timer.timeout.connect(lambda: None)
    timer.start()
