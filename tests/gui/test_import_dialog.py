"""*File -> Import raw files...* (issue 37): the roles table guessed from a folder, edited, checked with the command's
checks (one line per problem, nothing written) and imported into a session: calibration and delivery, off the GUI
thread. Small DNGs whose targets show their charts' patches (tests/import_folders.py)."""
from __future__ import annotations

from import_folders import PATCHED, corners, make_folder, tree

from tests.gui.conftest import HANG_GUARD_MS, click


def test_import_raw_files_from_the_window(qtbot, make_window, tmp_path):
    from dualrgb.app.gui.import_dialog import ImportDialog

    w = make_window()
    folder, _roles = make_folder(tmp_path / "shot", shape=PATCHED)
    source = tree(folder)
    w.menu_actions["import_raw"].trigger()
    dialog = w.findChild(ImportDialog)
    assert dialog is not None and dialog.isVisible() and not dialog.import_button.isEnabled()
    dialog.folder.setText(str(folder))
    dialog.session.setText(str(tmp_path / "session"))
    click(qtbot, dialog.guess_button)
    qtbot.waitUntil(lambda: dialog.table.rowCount() == 14 and dialog.handle is None, timeout=HANG_GUARD_MS)
    cells = dialog.cells()
    assert [r[1] for r in cells] == ["dark"] * 4 + ["flat"] * 4 + ["target"] * 4 + ["original"] * 2
    assert [r[2] for r in cells[4:]] == ["1", "1", "2", "2"] + ["1", "2"] * 3
    assert [r[3] for r in cells[8:]] == ["train", "train", "test", "test", "ORIGINAL-1", "ORIGINAL-1"]
    for r in (12, 13):                                          # the technician names the original
        dialog.table.item(r, 3).setText("ACC-1")
    dialog.table.item(12, 4).setText("A painting")

    def written() -> dict[str, str]:                          # the window's own settings file aside
        return {k: v for k, v in tree(tmp_path).items() if not k.startswith("config/")}

    before = written()
    dialog.table.item(0, 1).setText("drak")                  # a typo in a role: one line naming it, nothing written
    click(qtbot, dialog.check_button)
    qtbot.waitUntil(lambda: dialog.problems.count() > 0 and dialog.handle is None, timeout=HANG_GUARD_MS)
    assert "drak" in dialog.problems.item(0).text()
    assert "nothing was written" in dialog.message.text() and written() == before
    assert dialog.plan is None and not dialog.import_button.isEnabled()
    dialog.table.item(0, 1).setText("dark")

    for name in ("train", "test"):
        dialog.corners[name].setText(corners(PATCHED))
    click(qtbot, dialog.check_button)
    qtbot.waitUntil(lambda: dialog.plan is not None and dialog.handle is None, timeout=HANG_GUARD_MS)
    assert dialog.problems.count() == 0 and dialog.message.text().startswith("ready: 14 files, 1 original")
    assert written() == before

    click(qtbot, dialog.import_button)
    qtbot.waitUntil(lambda: dialog.imported is not None and dialog.handle is None, timeout=HANG_GUARD_MS)
    (delivery,) = dialog.imported.deliveries
    assert delivery.original.identifier == "ACC-1" and delivery.original.title == "A painting"
    assert delivery.sidecar.is_file() and "lights unknown" in delivery.qa.text()
    assert dialog.imported.profile.preset == "unknown" and dialog.imported.copied == 14
    assert tree(folder) == source                             # copied, never moved or changed
