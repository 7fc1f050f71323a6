"""What the window adds around its panels: the File and Help menus (open a session, open the deliverables, import
raw files, the documentation, about, quit) and the wheel guard (a mouse wheel turned over a drop-down list or a
number field changes it only when it has the keyboard focus: scrolling the left panel never silently changes a
choice)."""
from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import QCoreApplication, QEvent, QObject, Qt, QUrl
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QAbstractSpinBox, QComboBox, QFileDialog, QMainWindow, QMessageBox, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.simulation.versions import dualrgb_version

log = logging.getLogger(__name__)

DOCS_URL = "https://github.com/dualrgb/dualrgb#readme"          # pyproject's Documentation URL when not installed
ABOUT = ("dualrgb {version}: dual-RGB multispectral capture at the copy stand - an RGB camera, two lights mixed "
         "from a 10-LED sphere, a matrix to CIE XYZ fitted on a colour target. The method: the thesis "
         "'Dual-RGB HDR multispectral imaging', chapters 4-9.")


class WheelGuard(QObject):
    """Event filter: wheel events go to a combo box or spin box only while it has the focus (else to the scroll
    area behind it)."""

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Type.Wheel and isinstance(watched, QWidget) and not watched.hasFocus():
            parent = watched.parentWidget()
            if parent is not None:                  # the panel behind scrolls, as if the field were not there
                QCoreApplication.sendEvent(parent, event)
            return True
        return False

    def guard(self, root: QWidget) -> int:
        """Guard every combo box and spin box under ``root`` (they take the focus by click or Tab, not by wheel);
        returns how many."""
        found = [*root.findChildren(QComboBox), *root.findChildren(QAbstractSpinBox)]
        for w in found:
            w.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
            w.installEventFilter(self)
        return len(found)


def build_menus(window: QMainWindow, ctx: AppContext, open_session) -> dict[str, QAction]:
    """File (Open session…, Open deliverables, Quit) and Help (Documentation, About) in ``window``'s menu bar;
    ``open_session(folder)`` resumes a session (Calibrate & capture's). Returns the actions by name."""
    bar = window.menuBar()
    file_menu = bar.addMenu("&File")
    actions = {
        "open_session": QAction("&Open session…", window),
        "open_deliverables": QAction("Open &deliverables", window),
        "import_raw": QAction("&Import raw files…", window),
        "quit": QAction("&Quit", window),
        "documentation": QAction("&Documentation", window),
        "about": QAction("&About dualrgb", window),
    }
    actions["open_session"].setShortcut(QKeySequence.StandardKey.Open)
    actions["open_session"].triggered.connect(lambda: _ask_session(window, ctx, open_session))
    actions["open_deliverables"].setToolTip("Show the session's deliverables folder.")
    actions["open_deliverables"].triggered.connect(lambda: open_deliverables(ctx))
    actions["quit"].setShortcut(QKeySequence.StandardKey.Quit)
    actions["quit"].triggered.connect(window.close)          # asks first when work is left (closeEvent)
    actions["import_raw"].setToolTip("Calibrate and deliver raw files another program shot (dualrgb import).")
    actions["import_raw"].triggered.connect(lambda: import_raw_files(window, ctx))
    for name in ("open_session", "open_deliverables", "import_raw"):
        file_menu.addAction(actions[name])
    file_menu.addSeparator()
    file_menu.addAction(actions["quit"])
    help_menu = bar.addMenu("&Help")
    actions["documentation"].setShortcut(QKeySequence.StandardKey.HelpContents)
    actions["documentation"].triggered.connect(lambda: ctx.open_url(QUrl(documentation_url()), "the documentation"))
    actions["about"].triggered.connect(lambda: about(window, ctx))
    help_menu.addAction(actions["documentation"])
    help_menu.addAction(actions["about"])
    return actions


def documentation_url() -> str:
    """The installed distribution's Documentation URL (pyproject's [project.urls]), else :data:`DOCS_URL`."""
    from importlib import metadata

    try:
        urls = metadata.metadata("dualrgb").get_all("Project-URL") or []
    except metadata.PackageNotFoundError:
        return DOCS_URL
    return next((u.split(",", 1)[1].strip() for u in urls if u.lower().startswith("documentation,")), DOCS_URL)


def _ask_session(window: QMainWindow, ctx: AppContext, open_session) -> None:
    folder = QFileDialog.getExistingDirectory(window, "Open a session folder", str(ctx.captures_dir))
    if folder:
        open_session(Path(folder))


def open_deliverables(ctx: AppContext) -> None:
    session = ctx.lab.session
    if session is None:
        ctx.errors.report("Open deliverables", "no session yet: calibrate or capture first, or File > Open session")
        return
    ctx.open_path(Path(session.path) / "deliverables")


def import_raw_files(window: QMainWindow, ctx: AppContext) -> QWidget:
    """*File -> Import raw files...*: the import dialog (app.gui.import_dialog), one per window, shown again."""
    from dualrgb.app.gui.import_dialog import ImportDialog

    dialog = window.findChild(ImportDialog)
    if dialog is None:
        dialog = ImportDialog(ctx, window)
    dialog.show()
    dialog.raise_()
    return dialog


def about_text() -> str:
    return ABOUT.format(version=dualrgb_version())


def about(window: QMainWindow, ctx: AppContext) -> None:
    ctx.asker.history.append(("About dualrgb", about_text()))
    if ctx.asker.show_dialogs:
        QMessageBox.about(window, "About dualrgb", about_text())
