"""Re-sealed profile edits (issue 38 item 5): the digest is a plain SHA-256 anyone can recompute, so a calibration
profile is checked field by field against its JSON Schema (resources/schemas/dualrgb-calibration-1.schema.json:
types, ranges, array lengths) and the cross-checks between fields (app/workflow/calibration/profile_check.py) before
any use.
An edit is refused in one line naming the field whether or not the digest was recomputed, and `calibration show`
never crashes on an edited profile (it did on 12 of 250 in the issue, e.g. ``stand_model.r2.start.train[0]=null``).

An edit that keeps every type, range and relation (a figure changed to another plausible figure) is accepted when
re-sealed: only a signature with a key the editor does not have could tell, which the profile does not carry."""
from __future__ import annotations

import json

import pytest
from profile_edits import EDITS, PROFILE, edits, write

from dualrgb.app.cli import main
from dualrgb.app.workflow.calibration.profile import describe, load_profile
from dualrgb.app.workflow.calibration.profile_check import ProfileError, seal


def test_the_profile_calibrate_wrote_is_shown(tmp_path, capsys):
    assert main(["calibration", "show", str(write(tmp_path, json.loads(PROFILE.read_text())))]) == 0
    assert "stand model: fitted" in capsys.readouterr().out


@pytest.mark.fault("edited files")
@pytest.mark.parametrize("kind", list(EDITS))
def test_every_field_edited_and_resealed_is_refused_in_one_line_or_shown(tmp_path, kind):
    """Every field of a real profile set to ``kind`` with the digest recomputed: load_profile (what every command
    does first) refuses it with one ProfileError line naming the field, or it loads and `calibration show`'s
    description is written; nothing else escapes."""
    refused, shown, crashed = 0, 0, []
    for field, doc in edits(kind):
        path = write(tmp_path, doc)
        try:
            describe(load_profile(path, arrays=field.startswith(("arrays", "raw"))))
            shown += 1
        except ProfileError as exc:
            text = str(exc)
            if "\n" in text or not text.startswith(f"{path}: "):
                crashed.append(f"{field}: not one line naming the file: {text!r}")
            refused += 1
        except Exception as exc:  # noqa: BLE001 - the case looks for exactly these
            crashed.append(f"{field}: {type(exc).__name__}: {exc}")
    print(f"[edited files] re-sealed edits to {kind}: {refused} refused, {shown} shown")
    assert crashed == [], crashed[:10]
    assert refused > 0


ISSUE = ("stand_model.r2.start.train", 0, None)


def _issue_edit(reseal: bool) -> dict:
    doc = json.loads(PROFILE.read_text())
    doc["stand_model"]["r2"]["start"]["train"][0] = None
    if reseal:
        doc.pop("digest")
        doc = seal(doc)
    return doc


@pytest.mark.fault("edited files")
@pytest.mark.parametrize("reseal", [True, False], ids=["digest recomputed", "digest as it was"])
def test_the_issues_edit_is_refused_in_one_line_either_way(tmp_path, capsys, reseal):
    path = write(tmp_path, _issue_edit(reseal))
    rc = main(["calibration", "show", str(path)])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert rc == 1 and captured.out == "" and len(lines) == 1, captured.err
    assert lines[0] == (f"dualrgb: error: {path}: stand_model.r2.start.train[0]: None is not of type 'number' "
                        "(resources/schemas/dualrgb-calibration-1.schema.json)"), lines[0]


CROSS = {
    "matrix channels for another number of lights": (lambda d: d["matrix"].update(
        channels=d["matrix"]["channels"][:3], matrix=d["matrix"]["matrix"][:3]),
        "matrix.channels: 3 channels for 2 light(s): expected 3 per light"),
    "best method not fitted": (lambda d: d["statistics"].update(best="delta-e"),
                               "statistics.best: 'delta-e' is not one of its methods (least-squares)"),
    "estimator of other channels": (lambda d: d["spectral"]["estimator"].update(channels=["R1", "G1", "B1", "R2",
                                                                                          "G2", "X"]),
                                    "spectral.estimator.channels: the spectral estimator maps R1, G1, B1, R2, G2, "
                                    "X but the matrix"),
    "estimator one wavelength short": (lambda d: d["spectral"]["estimator"]["wavelengths_nm"].pop(),
                                       "spectral.estimator.matrix: expected 37 rows (one per wavelength) of 6"),
    "R2 of fewer channels": (lambda d: d["stand_model"]["r2"]["fitted"]["test"].pop(),
                             "stand_model.r2.fitted.test: 5 channels, stand_model.r2.start.train has 6"),
    "more patches used than the chart has": (lambda d: d["charts"]["test"].update(used=25),
                                             "charts.test.used: 25 of 24 patches"),
}


@pytest.mark.fault("edited files")
@pytest.mark.parametrize("case", list(CROSS))
def test_fields_that_disagree_with_each_other_are_refused(tmp_path, capsys, case):
    edit, says = CROSS[case]
    doc = json.loads(PROFILE.read_text())
    edit(doc)
    doc.pop("digest")
    path = write(tmp_path, seal(doc))
    rc = main(["capture", "--virtual-lab", "--calibration", str(path), "--id", "ACC-1", "--session",
               str(tmp_path / "session")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and lines[0].startswith(f"dualrgb: error: {path}: {says}"), lines
    assert not (tmp_path / "session").exists()
