"""What an import checks before it writes anything (app.workflow.raw_import.import_checks, raw_import.plan_import):
each problem
one line naming the file or the roles file's row, all at once, and nothing written (the tree compared before and
after). Small DNGs (tests/app/import_folders.py) and the real public files of tests/data/raw."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from import_folders import SHOTS, T1, make_folder, shoot, tree, write_rows

from dualrgb.app.workflow.raw_import.import_checks import ImportRefused, ImportSettings, corner_grid
from dualrgb.app.workflow.raw_import.import_roles import read_roles
from dualrgb.app.workflow.raw_import.raw_import import plan_import
from dualrgb.simulation.presets import load_preset, packaged_presets

RAW = Path(__file__).resolve().parents[1] / "data" / "raw"
CORNERS = (2.0, 2.0, 45.0, 2.0, 45.0, 29.0, 2.0, 29.0)


def preset(name: str = "reflective_pso"):
    return load_preset(next(p for p in packaged_presets() if p.stem == name))


def settings(tmp_path: Path, **over) -> ImportSettings:
    grids = {n: corner_grid("reflective", n, CORNERS) for n in ("train", "test")}
    return ImportSettings(**{"mode": "reflective", "preset": preset(), "grids": grids,
                             "session": tmp_path / "session", **over})


def refused(tmp_path: Path, folder: Path, roles: Path, **over) -> list[str]:
    before = tree(tmp_path)
    with pytest.raises(ImportRefused) as err:
        plan_import(folder, read_roles(roles), settings(tmp_path, **over))
    assert tree(tmp_path) == before and not (tmp_path / "session").exists()      # nothing written
    return err.value.lines


def rows_of(roles: Path) -> list[list[str]]:
    import csv

    return list(csv.reader(roles.read_text().splitlines()))


def test_a_good_folder_is_planned_in_capture_order(tmp_path):
    folder, roles = make_folder(tmp_path)
    before = tree(tmp_path)
    plan = plan_import(folder, read_roles(roles), settings(tmp_path))
    assert tree(tmp_path) == before
    assert [f.row.file for f in plan.frames] == [f"Capture_{n:04d}.dng" for n in range(1, len(SHOTS) + 1)]
    assert (plan.camera.model, plan.camera.serial, plan.camera.iso, plan.camera.aperture) == ("Nikon D610", "3012345",
                                                                                              100, 8.0)
    assert plan.steps["Capture_0005.dng"] == "flat/dual-RGB-PSO reflective light 1/0.5/0"
    assert plan.steps["Capture_0013.dng"] == "original/original:ACC-1/dual-RGB-PSO reflective light 1/0.5/0"
    assert [o.identifier for o in plan.originals] == ["ACC-1"] and plan.originals[0].title == "A painting"


def test_a_raw_file_the_roles_file_does_not_list_is_named_not_skipped_silently(tmp_path):
    folder, roles = make_folder(tmp_path)
    shutil.copy(folder / "Capture_0001.dng", folder / "Test_shot.NEF")
    shutil.copy(folder / "Capture_0002.dng", folder / "Capture_0999.dng")
    (folder / "notes.txt").write_text("not a raw file")
    plan = plan_import(folder, read_roles(roles), settings(tmp_path))
    assert f"2 raw files in {folder} not in the roles file, left out of the import: Capture_0999.dng, " \
           "Test_shot.NEF" in plan.notes
    assert "Test_shot.NEF" not in [f.row.file for f in plan.frames]


@pytest.mark.fault("input")
def test_a_scanner_nef_a_missing_dark_and_a_duplicate_give_one_line_each(tmp_path):
    """The issue's case: a real Coolscan NEF, no darks at 1/60 s, the same file twice: three lines, each naming its
    file, nothing written."""
    no_short_darks = [s for s in SHOTS if not (s[0] == "dark" and s[3] != T1)]
    folder, roles = make_folder(tmp_path, no_short_darks)
    shutil.copyfile(RAW / "Nikon_uncompressed.nef", folder / "Scan_0001.nef")
    shutil.copyfile(folder / "Capture_0011.dng", folder / "Capture_0099.dng")
    write_rows(roles, rows_of(roles) + [["Scan_0001.nef", "flat", "1", "", ""],
                                        ["Capture_0099.dng", "original", "1", "ACC-2", ""],
                                        ["Capture_0098.dng", "original", "2", "ACC-2", ""]][:2])
    lines = refused(tmp_path, folder, roles)
    assert len(lines) == 3, lines
    assert f"{folder / 'Scan_0001.nef'}: not a Bayer mosaic (the file holds demosaiced/linear RGB data)" in lines
    assert any(x.startswith(f"{folder / 'Capture_0099.dng'}: the same file as Capture_0011.dng (sha256 ")
               for x in lines)
    assert any(x.startswith(f"{folder / 'Capture_0005.dng'}: its exposure 1/60 s has no dark frame (darks at: 1/2 s)")
               for x in lines)


@pytest.mark.fault("input")
@pytest.mark.parametrize("info, what", [({"serial": "999"}, "camera 'Nikon D610' serial '999', the other files "
                                                            "'Nikon D610' serial '3012345' (one camera per import)"),
                                        ({"iso": 400}, "ISO 400, the other files 100 (one ISO per import)"),
                                        ({"aperture": 5.6}, "aperture f/5.6, the other files f/8 (one aperture per "
                                                            "import)")])
def test_one_camera_iso_and_aperture(tmp_path, info, what):
    folder, roles = make_folder(tmp_path)
    shoot(folder / "Capture_0012.dng", 1 / 60, 2500, 12, **info)
    assert refused(tmp_path, folder, roles) == [f"{folder / 'Capture_0012.dng'}: {what}"]


@pytest.mark.fault("input")
def test_a_real_dng_without_exposure_is_refused(tmp_path):
    """The Blackmagic DNG is a Bayer raw but records no exposure (and is another camera): each line names it."""
    folder, roles = make_folder(tmp_path)
    shutil.copyfile(RAW / "Blackmagic.dng", folder / "Capture_0012.dng")
    lines = refused(tmp_path, folder, roles)
    assert lines and all(line.startswith(f"{folder / 'Capture_0012.dng'}: ") for line in lines)
    assert any("no exposure time in its metadata" in line for line in lines)


@pytest.mark.fault("input")
@pytest.mark.parametrize("edit, line", [
    (lambda r: r[:5] + r[7:], "light 1 (dual-RGB-PSO reflective light 1): no flat (open-gate) frame under it in the "
                              "roles file"),
    (lambda r: [x if x[0] != "Capture_0014.dng" else [x[0], "original", "3", "ACC-1", ""] for x in r],
     "ROLES.csv row 15: Capture_0014.dng: light 3, but preset dual-RGB-PSO reflective has 2 lights"),
    (lambda r: [x if x[0] != "Capture_0014.dng" else [x[0], "original", "", "ACC-1", ""] for x in r],
     "ROLES.csv row 15: an original frame needs its light's number in the preset (1, 2, ...)"),
    (lambda r: r[:11] + r[13:], "light 1 (dual-RGB-PSO reflective light 1): no frame of the test target under it in "
                                "the roles file"),
    (lambda r: r + [["Capture_0404.dng", "dark", "", "", ""]], "no such file"),
    (lambda r: r + [["Capture_0001.dng", "dark", "", "", ""]], "ROLES.csv row 16: Capture_0001.dng is also row 2 "
                                                                "(one role per file)"),
    (lambda r: r + [["Capture_0001.dng", "drak", "", "", ""]], "ROLES.csv row 16: role 'drak': expected dark, flat, "
                                                               "target or original"),
])
def test_roles_that_cannot_be_imported(tmp_path, edit, line):
    folder, roles = make_folder(tmp_path)
    write_rows(roles, edit(rows_of(roles)))
    lines = refused(tmp_path, folder, roles)
    assert any(line in x for x in lines), lines


@pytest.mark.fault("input")
def test_one_mode_per_import(tmp_path):
    folder, roles = make_folder(tmp_path)
    rows = rows_of(roles)
    write_rows(roles, [r + ["mode"] if i == 0 else r + ["transmissive" if r[1] == "original" else ""]
                       for i, r in enumerate(rows)])
    assert refused(tmp_path, folder, roles) == ["ROLES.csv: original 'ACC-1' is transmissive, the import calibrates "
                                                "reflective (one mode per import: import the other mode's files with "
                                                "--mode and their own targets)"]


@pytest.mark.fault("input")
def test_a_folder_that_holds_other_files_is_no_session(tmp_path):
    folder, roles = make_folder(tmp_path)
    (tmp_path / "session").mkdir()
    (tmp_path / "session" / "notes.txt").write_text("mine")
    with pytest.raises(ImportRefused) as err:
        plan_import(folder, read_roles(roles), settings(tmp_path))
    assert err.value.lines == [f"{tmp_path / 'session'}: holds files but no session; choose a new or empty --session "
                               "folder"]


def test_no_grid_is_needed_before_writing_the_charts_are_found_in_their_frames(tmp_path):
    """Without corners the targets' specs carry no grid: the calibration finds every chart in its frames
    (app.processing.chart_detect), so the checks before writing ask for none (issue 36)."""
    from dualrgb.app.workflow.raw_import.import_checks import ImportSettings, target_specs

    specs, problems = target_specs(ImportSettings("reflective", grids={}, session=tmp_path / "session"))
    assert problems == [] and {n: s.grid for n, s in specs.items()} == {"train": None, "test": None}
    assert specs["train"].geometry is not None and specs["test"].geometry is not None


def test_the_originals_metadata_are_read_as_in_a_queue_csv(tmp_path):
    """title, operator, notes, mode and any other column: the queue CSV's rules (one reader), once per original."""
    folder, roles = make_folder(tmp_path)
    rows = rows_of(roles)
    write_rows(roles, [r + ["Inventory"] if i == 0 else r + (["Inv 7"] if r[0] == "Capture_0013.dng" else [""])
                       for i, r in enumerate(rows)])
    table = read_roles(roles)
    assert not table.problems and dict(table.originals["ACC-1"].extra) == {"Inventory": "Inv 7"}
    rows[-1][4] = "Another title"
    write_rows(roles, rows)
    assert read_roles(roles).problems == ["ROLES.csv row 15: column 'title': 'Another title' differs from row 14 of "
                                          "the same original ('A painting'); say it once"]
    rows[-1][4], rows[-2][3], rows[-1][3] = "", "ACC\x011", "ACC\x011"
    write_rows(roles, rows)
    assert read_roles(roles).problems[0].startswith("ROLES.csv row 14: identifier: control character U+0001")
