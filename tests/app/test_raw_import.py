"""app.workflow.raw_import.raw_import run whole on small DNGs whose targets show their charts' patches: the session it
makes,
an import run again into it (resumed: nothing copied twice), a file changed after its check, the roles template, the
linear limit of another camera."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from import_folders import PATCHED, corners, make_folder, tree

from dualrgb.app.workflow.raw_import.import_checks import ImportRefused, ImportSettings, corner_grid, parse_corners
from dualrgb.app.workflow.raw_import.import_roles import read_roles
from dualrgb.app.workflow.raw_import.import_session import check_copy
from dualrgb.app.workflow.raw_import.import_template import template_table
from dualrgb.app.workflow.raw_import.raw_import import ImportOptions, linear_limit, plan_import, run_import

RAW = Path(__file__).resolve().parents[1] / "data" / "raw"


def settings(tmp_path: Path, **over) -> ImportSettings:
    grids = {n: corner_grid("reflective", n, parse_corners(corners(PATCHED))) for n in ("train", "test")}
    return ImportSettings(**{"mode": "reflective", "grids": grids, "session": tmp_path / "session", **over})


def test_an_import_makes_a_session_and_runs_again_into_it(tmp_path):
    folder, roles = make_folder(tmp_path / "shot", shape=PATCHED)
    source = tree(folder)
    result = run_import(plan_import(folder, read_roles(roles), settings(tmp_path)), ImportOptions(False))
    assert (result.copied, result.kept) == (14, 0) and tree(folder) == source
    session = json.loads((tmp_path / "session" / "session.json").read_text())
    assert session["definition"]["workflow"] == "raw import" and session["definition"]["preset"] == "unknown"
    assert session["originals"]["ACC-1"]["calibration"] == str(result.profile.path)
    assert result.profile.unavailable and result.profile.stand == {} and result.profile.lights[0].light.leds == ()

    again = run_import(plan_import(folder, read_roles(roles), settings(tmp_path)), ImportOptions(False))
    assert (again.copied, again.kept) == (0, 14)              # resumed: what the session holds is kept
    manifest = (tmp_path / "session" / "manifest.jsonl").read_text().splitlines()
    assert len(manifest) == 14
    first = json.loads(manifest[0])
    assert first["camera_filename"] == "Capture_0001.dng" and first["camera"] == "Nikon D610"
    assert first["settings"] == {"serial": "3012345", "format": "DNG", "iso": 100, "aperture": 8.0}
    assert first["captured_at"].startswith("2026-05-04T10:00") and first["exposure_s"] == 0.5
    assert (tmp_path / "session" / "deliverables" / "ACC-1" / "previous").is_dir()

    from dualrgb.simulation.presets import load_preset, packaged_presets

    preset = load_preset(next(p for p in packaged_presets() if p.stem == "reflective_pso"))
    with pytest.raises(ImportRefused) as err:                 # the same session with a preset: another import
        plan_import(folder, read_roles(roles), settings(tmp_path, preset=preset))
    assert err.value.lines[0].startswith(f"{tmp_path / 'session'}: a session made otherwise (")


def test_a_file_changed_after_its_check_is_not_copied(tmp_path):
    folder, roles = make_folder(tmp_path / "shot", shape=PATCHED)
    plan = plan_import(folder, read_roles(roles), settings(tmp_path))
    check_copy(plan.frames[0])
    path = plan.frames[0].path
    path.write_bytes(path.read_bytes()[:-1] + b"\x01")
    with pytest.raises(ValueError, match="changed since it was checked"):
        check_copy(plan.frames[0])


def test_the_template_lists_every_raw_file(tmp_path):
    """Roles guessed for the DNGs; the scanner NEF listed with its reason, never left out silently."""
    folder, _roles = make_folder(tmp_path / "shot", shape=PATCHED)
    shutil.copyfile(RAW / "Nikon_uncompressed.nef", folder / "Scan_0001.nef")
    (folder / "notes.txt").write_text("not a raw file")
    header, rows = template_table(folder)
    assert header[:4] == ["file", "role", "light", "identifier"] and len(rows) == 15
    assert [r[1] for r in rows[:14]] == ["dark"] * 4 + ["flat"] * 4 + ["target"] * 4 + ["original"] * 2
    assert rows[-1][0] == "Scan_0001.nef" and rows[-1][1] == "" and "not a Bayer mosaic" in rows[-1][-1]


def test_the_linear_limit_follows_the_white_level():
    """The D610's measured 11 000 DN of 15 520 (thesis Fig 4.2), in proportion for another camera's white level."""
    assert linear_limit(15520) == 11000.0 and linear_limit(65535) == 11000.0
    assert linear_limit(4095) == pytest.approx(4095 * 11000 / 15520, abs=0.05)
