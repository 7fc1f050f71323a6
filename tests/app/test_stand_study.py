"""``dualrgb study stand``'s parts that need no virtual lab (app.lab.stand_study, stand_study_report): the world
as a stand model, light sets that are the lights in use reuse their calibrations, the tables and the docs page's section
made from a saved document (the whole study runs in tests/e2e/test_stand.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from dualrgb.app.cli import main
from dualrgb.app.lab import stand_study
from dualrgb.app.workflow.stand_study_report import load_study, summary_lines, workflow_table
from dualrgb.drivers.virtual.world import load_world
from dualrgb.simulation.studies.common import replace_marked
from tests.readme_sections import page_and_run


@pytest.mark.parametrize("name", ["aged-leds", "worn-sphere"])
def test_the_world_model_emits_what_the_world_renders(name):
    world = load_world(name)
    model = stand_study.world_model(world)
    levels = np.linspace(0.0, 1.0, 20001)
    got = model.sphere().emitted(np.repeat(levels[:, None], 10, axis=1))
    want = world.led_low_level.output(np.round(levels * 65535) / 65535)
    assert np.abs(got - want[:, None]).max() < 2e-5
    assert stand_study.world_level_curves(load_world("mismatched-d700")) == ()


def test_a_light_set_equal_to_one_captured_reuses_its_calibrations(monkeypatch, tmp_path):
    made = []

    def calibrate(cfg, world, preset, seed, folder):
        made.append((preset.name, seed))
        return f"{preset.name}/{seed}"
    monkeypatch.setattr(stand_study, "calibrate_in_world", calibrate)
    a = np.zeros((2, 10))
    a[0, 0], a[1, 1] = 1.0, 1.0
    b = a.copy()
    b[0, 2] = 0.5
    cfg = stand_study.StandStudyConfig(seeds=(0, 1))
    done = {stand_study.PRESET: ["p0", "p1"]}
    out = stand_study.capture_lights(cfg, "nominal", {stand_study.PRESET: a, "kept": a.copy(), "new": b,
                                                      "new again": b.copy()}, tmp_path, done)
    assert out["kept"] == ["p0", "p1"] and out["new"] == out["new again"]
    assert made == [("study stand: new", 0), ("study stand: new", 1)]


def _doc() -> dict:
    entry = {"captured": {"train": 0.5, "test": 0.4, "train_each": [0.5, 0.5], "test_each": [0.38, 0.42]},
             "predicted": {"train": 0.51, "test": 0.41, "train_each": [0.51, 0.51], "test_each": [0.4, 0.42]},
             "miss": {"test": 0.025, "test_each": [0.0526, 0.0], "test_worst": 0.0526}}
    world = {"world": "aged-leds", "models": {"fitted, measured camera and LEDs": {}},
             "workflow": {"preset": entry, "re-optimised": {**entry, "preset_kept": True}}, "lights": {}}
    return {"format": "dualrgb-study-stand/2", "config": {"mode": "reflective", "frame_size": [600, 400],
                                                          "seeds": [0, 1]},
            "elapsed_s": 120.0, "worlds": {"aged-leds": world}}


def test_the_workflow_table_from_a_saved_study(tmp_path, capsys):
    doc = _doc()
    rows = workflow_table(doc)
    assert rows[2] == ("| `aged-leds` | 0.400 | 0.410 | +2.5 % (+0.0 % to +5.3 %) | 0.400 (the preset kept) | 0.410 | "
                       "+2.5 % (+0.0 % to +5.3 %) | +0.0 % |")
    assert "seeds 0, 1; 2 min" in summary_lines(doc)[0]
    path = tmp_path / "stand.json"
    path.write_text(json.dumps(doc))
    readme = tmp_path / "page.md"
    readme.write_text("intro\n<!-- stand:start -->\nold\n<!-- stand:end -->\nrest\n")
    assert main(["study", "stand", "--from-json", str(path), "--doc", str(readme), "--out",
                 str(tmp_path / "out")]) == 0
    text = readme.read_text()
    assert rows[2] in text and "old" not in text and text.endswith("<!-- stand:end -->\nrest\n")
    assert (tmp_path / "out" / "study_stand.png").stat().st_size > 10_000
    assert not (tmp_path / "out" / "stand.json").exists()                 # the saved document is not rewritten
    assert rows[2] in capsys.readouterr().out


@pytest.mark.fault("input")
def test_a_file_that_is_not_a_stand_study_is_one_line(tmp_path, capsys):
    path = tmp_path / "x.json"
    path.write_text(json.dumps({"format": "dualrgb-study-spectral/1"}))
    with pytest.raises(ValueError, match=r"x\.json: expected a study stand document"):
        load_study(path)
    assert main(["study", "stand", "--from-json", str(path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "expected a study stand document" in err[0]
    with pytest.raises(ValueError, match="needs one <!-- stand:start --> line"):
        replace_marked("no markers", "body", "stand")


def test_the_docs_stand_section_is_the_one_made_from_the_committed_study():
    from dualrgb.app.workflow.stand_study_report import DOC_PAGE, SECTION, readme_section

    text, committed = page_and_run(DOC_PAGE, "study_stand.json")
    doc = load_study(committed)
    assert replace_marked(text, readme_section(doc, "docs/data/study_stand.json"), SECTION) == text, \
        f"{DOC_PAGE}'s stand tables are not the ones `dualrgb study stand --from-json docs/data/study_stand.json " \
        f"--doc {DOC_PAGE}` writes"
    worlds = set(doc["worlds"])
    assert {"nominal", "nikon-d700", "sony-ilce-7rm2", "mismatched-d700", "aged-leds", "worn-sphere"} <= worlds
    for name in ("aged-leds", "worn-sphere"):                # Must show: within 10 % of each capture, 3 seeds
        for which in ("preset", "re-optimised"):
            misses = doc["worlds"][name]["workflow"][which]["miss"]["test_each"]
            assert len(misses) == 3 and max(abs(m) for m in misses) <= 0.10


def test_the_docs_film_section_is_the_one_made_from_the_committed_film_study():
    """The film tables of the page come from the committed transmissive run, in a section of their own (the
    reflective one is not touched by writing them)."""
    from dualrgb.app.workflow.stand_study_report import DOC_PAGE, SECTION, readme_section, section_of

    text, committed = page_and_run(DOC_PAGE, "study_stand_transmissive.json")
    doc = load_study(committed)
    assert doc["config"]["mode"] == "transmissive" and section_of(doc) == "stand-transmissive"
    body = readme_section(doc, "docs/data/study_stand_transmissive.json")
    assert replace_marked(text, body, section_of(doc)) == text, \
        f"{DOC_PAGE}'s film tables are not the ones `dualrgb study stand --from-json " \
        f"docs/data/study_stand_transmissive.json --doc {DOC_PAGE}` writes"
    assert replace_marked(text, body, SECTION) != text                  # the reflective section is another one
