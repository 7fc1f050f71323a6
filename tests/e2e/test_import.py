"""Raw files shot by "another program" through ``dualrgb import`` (issue 37): the virtual lab's frames of a calibration
and one original, copied into a flat folder under Capture One's names (Capture_0001.dng, ...) with a ROLES.csv,
imported into a new session: the calibration's test dE00 within 10 % of the captured session's, the ProPhoto master
of the same size within 0.5 mean dE00 of the captured one; the manifest names every original file and its sha256;
``dualrgb process`` delivers it again; without --preset the lights are unknown and said so; a folder with a scanner
NEF, a missing dark exposure and a duplicate is refused in one line each with nothing written; the roles template
guesses the captured roles.

The targets' corners are the virtual lab's scene geometry (drivers.virtual.scene), computed here in the test only:
on a real stand the technician gives them (--target-corners)."""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import colour
import numpy as np
import pytest
import tifffile
from doc_blocks import block_names, dualrgb_prelude, run_block
from import_folders import tree
from sidecar_schema import assert_valid_sidecar

FRAME = ["--frame-size", "240x160", "--settle", "0"]
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
RAW = Path(__file__).resolve().parents[1] / "data" / "raw"
HOWTO = Path(__file__).resolve().parents[2] / "docs" / "how-to" / "raw-import.md"


def dualrgb(*args: str, cwd: Path | None = None, ok: bool = True) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "dualrgb", *args], capture_output=True, text=True, env=ENV, timeout=900,
                       cwd=cwd)
    if ok:
        assert r.returncode == 0, r.stderr[-3000:]
    return r


def corner_options(width: int = 240, height: int = 160) -> list[str]:
    """--target-corners of the virtual lab's training and test targets (the scene's outer patch corners)."""
    from dualrgb.drivers.virtual.scene import Scene
    from dualrgb.simulation.datasets import default_setup

    setup = default_setup("reflective")
    out = []
    for name, target in (("train", setup.train), ("test", setup.test)):
        rc = Scene.with_target(target, width=width, height=height).corners()
        out += ["--target-corners", f"{name}=" + ",".join(f"{x:.4f},{y:.4f}" for y, x in rc)]
    return out


def flatten(session: Path, folder: Path) -> Path:
    """The session's darks, flats, targets and original frames copied to ``folder`` as Capture_NNNN.dng, in the
    order they were shot, and the ROLES.csv another program's user would write for them (beside the folder)."""
    folder.mkdir()
    rows = [["file", "role", "light", "identifier", "title", "operator"]]
    for line in (session / "manifest.jsonl").read_text().splitlines():
        d = json.loads(line)
        if d.get("kind", "frame") != "frame" or d["role"] not in ("dark", "flat", "target", "original"):
            continue
        name = f"Capture_{len(rows):04d}.dng"
        shutil.copyfile(session / d["file"], folder / name)
        light = (d["meta"].get("light_name") or "").rpartition(" light ")[2]
        ident = (d["meta"].get("subject") or "").partition(":")[2]
        original = d["role"] == "original"
        rows.append([name, d["role"], light, ident, "A painting" if original else "", "E2E" if original else ""])
    roles = folder.parent / "ROLES.csv"
    with open(roles, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return roles


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    """A captured day (calibrate + capture PAINT-1 in one session), its frames as another program's, imported."""
    root = tmp_path_factory.mktemp("import")
    dualrgb("calibrate", "--session", str(root / "captured"), "--virtual-lab", "--hdr", "off", "--dark-frames", "3",
            "--flat-frames", "4", "--no-de-fit", "--json", str(root / "cal.json"), *FRAME)
    cal = json.loads((root / "cal.json").read_text())
    dualrgb("capture", "--session", str(root / "captured"), "--calibration", cal["calibration"], "--id", "PAINT-1",
            "--title", "A painting", "--operator", "E2E", "--virtual-lab", "--virtual-original", "painting",
            "--json", str(root / "cap.json"), *FRAME)
    cap = json.loads((root / "cap.json").read_text())
    roles = flatten(root / "captured", root / "raw")
    source = tree(root / "raw")
    dualrgb("import", str(root / "raw"), "--roles", str(roles), "--session", str(root / "imported"), "--preset",
            "reflective_pso", "--no-de-fit", *corner_options(), "--json", str(root / "imp.json"))
    imp = json.loads((root / "imp.json").read_text())
    return root, cal, cap, imp, source


def lab(path: str | Path) -> np.ndarray:
    rgb = tifffile.imread(path).astype(float) / 65535.0
    space = colour.RGB_COLOURSPACES["ProPhoto RGB"]
    xyz = colour.RGB_to_XYZ(rgb, space, apply_cctf_decoding=True)
    return colour.XYZ_to_Lab(xyz, space.whitepoint)


def test_the_imported_calibration_matches_the_captured_one(day):
    root, cal, _cap, imp, _ = day
    captured = cal["statistics"]["methods"][cal["statistics"]["best"]]["test"]["mean"]
    imported = imp["profile"]["statistics"]["methods"][imp["profile"]["statistics"]["best"]]["test"]["mean"]
    print(f"test mean dE00: captured {captured:.4f}, imported {imported:.4f}")
    assert abs(imported - captured) <= 0.10 * captured
    assert imp["profile"]["camera"]["model"] == cal["camera"]["model"] == "dualrgb virtual D610"
    assert imp["profile"]["camera"]["serial"] == cal["camera"]["serial"] and imp["profile"]["camera"]["iso"] == 50
    assert imp["profile"]["preset"] == cal["preset"] and "unavailable" not in imp["profile"]
    assert imp["profile"]["stand_model"] and imp["profile"]["spectral"]["estimator"]


def test_the_prophoto_master_matches_the_captured_one(day):
    root, _cal, cap, imp, _ = day
    (original,) = imp["originals"]
    a, b = cap["files"]["prophoto"], original["files"]["prophoto"]
    assert tifffile.imread(a).shape == tifffile.imread(b).shape == (160, 240, 3)
    de = float(np.mean(colour.delta_E(lab(a), lab(b), method="CIE 2000")))
    print(f"ProPhoto master: mean dE00 {de:.4f} between the captured and the imported delivery")
    assert de <= 0.5


def test_the_files_are_copied_named_and_hashed_never_changed(day):
    root, _cal, _cap, imp, source = day
    assert tree(root / "raw") == source                      # the source folder is untouched
    entries = [json.loads(x) for x in (root / "imported" / "manifest.jsonl").read_text().splitlines()]
    assert [e["camera_filename"] for e in entries] == sorted(source)
    for e in entries:
        assert e["sha256"] == source[e["camera_filename"]] and e["meta"]["imported"]["sha256"] == e["sha256"]
        assert (root / "imported" / e["file"]).read_bytes() == (root / "raw" / e["camera_filename"]).read_bytes()
    side = assert_valid_sidecar(Path(imp["originals"][0]["sidecar"]))
    assert side["original"]["title"] == "A painting" and side["original"]["operator"] == "E2E"
    assert side["fixity"] and side["calibration"]["lights"]
    assert side["calibration"]["preset"] == imp["profile"]["preset"]
    assert [f["file"] for f in side["imported"]["files"]] == ["Capture_0019.dng", "Capture_0020.dng"]
    assert "light dose unknown" in imp["originals"][0]["qa"]["text"]


def _xmp(tiff: str | Path) -> str:
    with tifffile.TiffFile(tiff) as tif:
        return bytes(tif.pages[0].tags["XMP"].value).decode()


def test_the_dose_of_frames_another_program_shot_is_unknown_never_zero(day):
    """No lit period of an imported frame was recorded: the sidecar, the session's originals and the master's XMP
    hold no dose figure (null / left out) and the QA line says not recorded; the captured delivery holds its own."""
    root, _cal, cap, imp, _ = day
    side = assert_valid_sidecar(Path(imp["originals"][0]["sidecar"]))
    assert side["light_dose"] == side["qa"]["light_dose"] == {"lux_s": None, "lux_h": None, "on_s": None}
    assert "light dose not recorded" in side["qa"]["text"] and "lux.h" not in side["qa"]["text"]
    session = json.loads((root / "imported" / "session.json").read_text())
    assert session["originals"]["PAINT-1"]["light_dose"]["lux_s"] is None
    assert "LightDose" not in _xmp(imp["originals"][0]["files"]["prophoto"])
    captured = assert_valid_sidecar(Path(cap["sidecar"]))
    assert captured["light_dose"]["lux_s"] > 0
    assert "<dualrgb:LightDoseLuxSeconds>" in _xmp(cap["files"]["prophoto"])


def test_process_delivers_it_again(day):
    root, _cal, _cap, imp, _ = day
    r = dualrgb("process", str(root / "imported"), "--json", str(root / "process.json"))
    out = json.loads((root / "process.json").read_text())
    assert [o["identifier"] for o in out["originals"]] == ["PAINT-1"], r.stderr
    side = assert_valid_sidecar(Path(out["originals"][0]["sidecar"]))
    assert side["reprocessed"] is True and "light dose unknown" in side["qa"]["text"]
    assert side["light_dose"]["lux_s"] is None                  # re-delivered: still unknown, never a zero
    logged = (root / "imported" / "session.log").read_text(encoding="utf-8").split("dualrgb.app.commands.process")
    assert len(logged) >= 3 and "PAINT-1" in logged[-1], logged[1:]     # the run in the session's own log
    assert (root / "imported" / "deliverables" / "PAINT-1" / "previous").is_dir()


def test_without_a_preset_the_lights_are_unknown(day):
    root, _cal, _cap, imp, _ = day
    dualrgb("import", str(root / "raw"), "--roles", str(root / "ROLES.csv"), "--session", str(root / "unknown"),
            "--no-de-fit", *corner_options(), "--json", str(root / "unknown.json"))
    prof = json.loads((root / "unknown.json").read_text())["profile"]
    assert prof["preset"] == "unknown" and all(light["leds"] == [] for light in prof["lights"])
    assert set(prof["unavailable"]) == {"stand_model", "spectral_model"} and "stand_model" not in prof
    assert prof["spectral"]["estimator"]["method"] != "wiener"               # no model: fitted to the target alone
    # the same frames and the same placement as the import with the preset: the same least-squares fit
    assert abs(prof["statistics"]["methods"]["least-squares"]["test"]["mean"]
               - imp["profile"]["statistics"]["methods"]["least-squares"]["test"]["mean"]) < 0.01
    side = json.loads(next((root / "unknown" / "deliverables").glob("*/*.json")).read_text())
    assert side["calibration"]["lights"] == "unknown" and "stand_model" in side["calibration"]["unavailable"]
    assert "lights unknown" in side["qa"]["text"]
    shown = dualrgb("calibration", "show", str(next((root / "unknown" / "calibration").glob("cal-*.json"))))
    assert "unknown light 1: LEDs and levels unknown" in shown.stdout and "unavailable: stand_model" in shown.stdout


@pytest.mark.fault("input")
def test_a_scanner_nef_a_missing_dark_and_a_duplicate_are_refused(day, tmp_path):
    """The issue's folder: one line each, exit 1, nothing written."""
    root = day[0]
    folder = tmp_path / "raw"
    shutil.copytree(root / "raw", folder)
    rows = list(csv.reader((root / "ROLES.csv").read_text().splitlines()))
    darks = [r[0] for r in rows if r[1] == "dark"][:3]                 # the shortest exposure's darks: 1/60 s
    for name in darks:
        (folder / name).unlink()
    shutil.copyfile(RAW / "Nikon_uncompressed.nef", folder / "Scan_0001.nef")
    shutil.copyfile(folder / "Capture_0019.dng", folder / "Capture_0021.dng")
    rows = [r for r in rows if r[0] not in darks] + [["Scan_0001.nef", "flat", "1", "", "", ""],
                                                     ["Capture_0021.dng", "original", "1", "COPY-1", "", ""]]
    with open(tmp_path / "ROLES.csv", "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    before = tree(tmp_path)
    r = dualrgb("import", str(folder), "--roles", str(tmp_path / "ROLES.csv"), "--session", str(tmp_path / "s"),
                "--preset", "reflective_pso", *corner_options(), ok=False)
    assert r.returncode == 1 and tree(tmp_path) == before and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 4 and lines[-1] == "dualrgb: error: import refused: 3 problems; nothing was written", lines
    assert any(f"{folder / 'Scan_0001.nef'}: not a Bayer mosaic" in x for x in lines)
    assert any(f"{folder / 'Capture_0021.dng'}: the same file as Capture_0019.dng" in x for x in lines)
    assert any("has no dark frame (darks at: 0.7692 s)" in x for x in lines)


def test_the_roles_template_guesses_the_captured_roles(day, tmp_path):
    root = day[0]
    dualrgb("import", str(root / "raw"), "--roles-template", str(tmp_path / "T.csv"))
    guessed = [r[:4] for r in csv.reader((tmp_path / "T.csv").read_text().splitlines())]
    real = [r[:4] for r in csv.reader((root / "ROLES.csv").read_text().splitlines())]
    assert [[c.replace("ORIGINAL-1", "PAINT-1") for c in r] for r in guessed] == real


def test_the_how_to_runs_as_written(day, tmp_path):
    """docs/how-to/raw-import.md's block, run as written where raw/ holds the day's frames and ROLES.csv their roles
    (the corners in it are the virtual lab's targets at 240x160, as the technician would read them off the frame)."""
    root, cal, *_ = day
    shutil.copytree(root / "raw", tmp_path / "raw")
    shutil.copyfile(root / "ROLES.csv", tmp_path / "ROLES.csv")
    assert block_names(HOWTO) == ["raw-import"]
    run_block(HOWTO, "raw-import", tmp_path, env=ENV, prelude=dualrgb_prelude())
    guess = list(csv.reader((tmp_path / "ROLES-guess.csv").read_text().splitlines()))
    assert [r[1] for r in guess[1:]] == [r[1] for r in csv.reader((root / "ROLES.csv").read_text().splitlines())][1:]
    profile = json.loads(next((tmp_path / "day3" / "calibration").glob("cal-*.json")).read_text())
    best = profile["statistics"]["best"]
    assert profile["statistics"]["methods"][best]["test"]["mean"] == pytest.approx(
        cal["statistics"]["methods"][best]["test"]["mean"], rel=0.10)
    assert (tmp_path / "day3" / "deliverables" / "PAINT-1" / "previous").is_dir()          # process ran after it
