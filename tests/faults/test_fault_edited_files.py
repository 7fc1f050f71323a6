"""Edited files (issue 28 item 2-3, 8): a calibration profile changed by hand (or damaged) is refused when it is
loaded, in one line naming the field, before any device opens or a frame is shot: it is checked like a frame
(app/workflow/calibration/profile_check.py: size, finite numbers, schema, value ranges, the digest stored in it, the
.npz's
size, sha256 and arrays)."""
from __future__ import annotations

import io
import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.app.workflow.calibration.profile import load_profile
from dualrgb.app.workflow.calibration.profile_check import MAX_JSON_BYTES, seal

pytestmark = pytest.mark.fault("edited files")


def _set(path: str, value) -> Callable[[dict], None]:
    """An edit: the field at ``path`` ('matrix.matrix.0.1') set to ``value``."""
    def edit(doc: dict) -> None:
        *parents, last = path.split(".")
        node = doc
        for p in parents:
            node = node[int(p)] if isinstance(node, list) else node[p]
        node[int(last) if isinstance(node, list) else last] = value
    return edit


# case -> (edit of the JSON document, what the one error line says)
EDITS = {
    "matrix cell NaN": (_set("matrix.matrix.0.1", float("nan")), "matrix.matrix[0][1] is nan, expected a finite"),
    "matrix cell Infinity": (_set("matrix.matrix.2.2", float("inf")), "matrix.matrix[2][2] is inf"),
    "matrix cell 1e308": (_set("matrix.matrix.1.0", 1e308), "matrix.matrix[1][0]: 1e+308 is greater than the maximum"),
    "matrix cell as a string": (_set("matrix.matrix.0.0", "12"), "matrix.matrix[0][0]: '12' is not of type 'number'"),
    "matrix row missing": (lambda d: d["matrix"]["matrix"].pop(), "matrix.matrix: 2 rows for 3 channels"),
    "white point 1e308": (_set("white_xyz.1", 1e308), "white_xyz[1]: 1e+308 is greater than the maximum"),
    "white point 0, 0, 0": (_set("white_xyz", [0, 0, 0]), ": 0 is less than or equal to the minimum of 0"),
    "ppi -5": (_set("ppi", -5), "ppi: -5 is less than or equal to the minimum of 0"),
    "no lights": (_set("lights", []), "lights: [] should be non-empty"),
    "a light that lights nothing": (_set("lights.0.levels", [0.0, 0.0, 0.0]),
                                    "lights[0].levels: every level of P light 1 is 0: it lights nothing"),
    "a level of 1.5": (_set("lights.0.levels.2", 1.5), "lights[0].levels[2]: 1.5 is greater than the maximum of 1"),
    "an exposure of 3600 s": (_set("exposures.P light 1.1", 3600.0),
                              "exposures.P light 1: 3600 s is over the 10 s light-on cap"),
    "an exposure of -1 s": (_set("exposures.P light 1.0", -1.0), "exposures.P light 1[0]: -1.0 is less than or equal"),
    "a dark taken away": (lambda d: d["arrays"]["darks"].pop(), "arrays.darks: no master dark at 0.5 s"),
    "created_at not a date": (_set("created_at", "not a date"),
                              "created_at: 'not a date' is not a date and time (ISO 8601"),
    "black level above white": (_set("raw.black_level", 20000), "raw: expected black level < linear limit"),
    "an unknown field": (_set("notes", "mine"), "Additional properties are not allowed ('notes' was unexpected)"),
    "a valid-looking ppi": (_set("ppi", 600.0), "edited after it was written (field ppi changed; the digest"),
    "the camera serial": (_set("camera.serial", "3099999"), "edited after it was written (field camera changed"),
    "the digest removed": (lambda d: d.pop("digest"), "no digest (written by a dualrgb before 0.2"),
    "the digest edited": (_set("digest.sha256", "0" * 64), "edited after it was written (its digest was edited"),
}


@pytest.fixture
def profile_path(tmp_path) -> Path:
    return make_profile(tmp_path / "cal").path


def _capture(profile: Path, session: Path, capsys) -> tuple[int, str]:
    rc = main(["capture", "--virtual-lab", "--calibration", str(profile), "--id", "ACC-1", "--session", str(session),
               "--frame-size", "96x64"])
    out, err = capsys.readouterr()
    return rc, err


@pytest.mark.parametrize("case", list(EDITS))
def test_an_edited_profile_is_refused_before_a_frame_is_shot(profile_path, tmp_path, capsys, monkeypatch, case):
    edit, says = EDITS[case]
    load_profile(profile_path)                         # as written: it loads
    doc = json.loads(profile_path.read_text())
    edit(doc)
    profile_path.write_text(json.dumps(doc))           # Python writes NaN / Infinity as JSON's extension does
    opened = []
    monkeypatch.setattr("dualrgb.drivers.virtual.lab.VirtualLab.start", lambda self: opened.append(self))
    rc, err = _capture(profile_path, tmp_path / "session", capsys)
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and lines[0].startswith(f"dualrgb: error: {profile_path}: "), err
    assert says in lines[0], lines[0]
    assert opened == [] and not (tmp_path / "session").exists()      # no device opened, nothing shot


def _rewrite_npz(profile: Path, drop: str) -> None:
    """The .npz without array ``drop``, its sha256 in the JSON and the digest brought up to date (as a buggy
    writer would leave them)."""
    doc = json.loads(profile.read_text())
    npz = profile.with_name(doc["arrays"]["file"])
    with np.load(npz) as arrays:
        kept = {k: arrays[k] for k in arrays.files if k != drop}
    buf = io.BytesIO()
    np.savez(buf, **kept)
    npz.write_bytes(buf.getvalue())
    import hashlib

    doc["arrays"]["sha256"] = hashlib.sha256(buf.getvalue()).hexdigest()
    profile.write_text(json.dumps(seal(doc)))


def _pickled_npz(profile: Path) -> None:
    doc = json.loads(profile.read_text())
    npz = profile.with_name(doc["arrays"]["file"])
    buf = io.BytesIO()
    np.savez(buf, **{name: np.array([{"a": 1}], dtype=object) for name in ("dark_0", "dark_1", "white_0")})
    npz.write_bytes(buf.getvalue())
    import hashlib

    doc["arrays"]["sha256"] = hashlib.sha256(buf.getvalue()).hexdigest()
    profile.write_text(json.dumps(seal(doc)))


ARRAYS = {
    "npz without white_0": (lambda p: _rewrite_npz(p, "white_0"), "no array white_0, which cal-test.json names"),
    "npz edited": (lambda p: p.with_suffix(".npz").write_bytes(p.with_suffix(".npz").read_bytes()[:-4] + b"0000"),
                   "damaged (sha256 differs"),
    "npz missing": (lambda p: p.with_suffix(".npz").unlink(), "the calibration's arrays are missing"),
    "npz of 1 GB": (lambda p: os.truncate(p.with_suffix(".npz"), 2 ** 30), "more than the"),
    "npz holding objects": (_pickled_npz, "not a calibration's arrays"),
    "JSON of 1 GB": (lambda p: os.truncate(p, 2 ** 30),
                     f"is too large for a calibration JSON file (limit {MAX_JSON_BYTES >> 20} MiB)"),
    "JSON cut short": (lambda p: p.write_bytes(p.read_bytes()[:200]), "not valid JSON ("),
    "JSON not UTF-8": (lambda p: p.write_bytes(b'{"format": "\xff"}'), "binary or not UTF-8 (UTF-16?); expected a"),
}


@pytest.mark.parametrize("case", list(ARRAYS))
def test_damaged_profile_files_are_refused_in_one_line(profile_path, tmp_path, capsys, case):
    damage, says = ARRAYS[case]
    damage(profile_path)
    rc, err = _capture(profile_path, tmp_path / "session", capsys)
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and says in lines[0], err
    assert "allow_pickle" not in err and not (tmp_path / "session").exists()


def test_what_the_product_writes_validates_and_a_nan_profile_is_never_written(tmp_path):
    from dualrgb.app.workflow.calibration.profile_check import check_document

    prof = make_profile(tmp_path / "ok")
    check_document(json.loads(prof.path.read_text()), prof.path)          # schema, ranges and digest
    prof.white_xyz = [95.0, float("nan"), 108.0]           # e.g. from an all-zero camera curve
    with pytest.raises(ValueError, match=r"calibration cal-test \(not saved\): white_xyz\[1\] is nan"):
        prof.save(tmp_path / "bad")
    assert not (tmp_path / "bad").exists() or not list((tmp_path / "bad").iterdir())


# ---- the QA of every delivery refuses an output that holds nothing (issue 28 item 2) --------------------------
BLANK = {
    "a NaN matrix cell": (lambda p, s: p.matrix.matrix.__setitem__((0, 1), np.nan),
                          r"no pixel is a finite number \(calibration cal-test has a matrix or white point that is"),
    "no finite pixel": (lambda p, s: s.data.__setitem__(slice(None), np.nan),
                        r"no pixel is a finite number in the encoded images \(calibration cal-test"),
    "a zero matrix": (lambda p, s: p.matrix.matrix.__setitem__(slice(None), 0.0),
                      r"every pixel is 0 in the encoded images \(calibration cal-test"),
    "black frames": (lambda p, s: s.data.__setitem__(slice(None), 0.0), "every pixel is 0 in the encoded images"),
}


@pytest.mark.parametrize("case", list(BLANK))
def test_the_qa_refuses_an_output_that_holds_nothing(tmp_path, case):
    from dualrgb.app.processing.pipeline import ChannelStack
    from dualrgb.app.workflow.delivery.delivery import DeliveryQaError, LightDoseRecord, Original, deliver

    prof = make_profile(tmp_path / "cal")
    stack = ChannelStack(np.full((10, 14, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
    spoil, says = BLANK[case]
    spoil(prof, stack)
    with pytest.raises(DeliveryQaError, match=f"ACC-1: QA refused the delivery: {says}"):
        deliver(stack, prof, Original("ACC-1"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord(1.0, 0.1))
    assert not (tmp_path / "out" / "ACC-1").exists() and not list((tmp_path / "out").glob(".*"))
