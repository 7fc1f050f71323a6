"""``dualrgb report SESSION`` (issue 39): one HTML page with a thumbnail, identifier, QA line and grades per original
and the calibration's figures and grading; a delivery that does not match its sidecar shows its problems instead
of a thumbnail (exit 1). The page is parsed with a strict HTML parser here, and rendered by headless Chromium where
it is installed (the docs' screenshot comes from tools/report_screenshot.py)."""
from __future__ import annotations

import shutil
import subprocess
from dataclasses import replace
from html.parser import HTMLParser

import numpy as np
import pytest
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver

QUALITY = {"measured": {"colour_mean_de00": 0.81, "colour_max_de00": 2.4},
           "grading": {"FADGI 4-star": {"verdict": "pass (measured criteria)", "scope": "colour accuracy only",
                                        "passed": 2, "failed": 0, "metrics": {"colour_mean_de00": "pass"}},
                       "Metamorfoze 2.0 Full": {"verdict": "fail", "scope": "colour accuracy only", "passed": 1,
                                                "failed": 1, "metrics": {"colour_max_de00": "fail"}}}}


class Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.images: list[dict] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs))

    def handle_data(self, data):
        self.text.append(data)


@pytest.fixture
def session(tmp_path):
    root = tmp_path / "day1"
    prof = make_profile(root / "calibration")
    prof = replace(prof, statistics={**prof.statistics, "quality": QUALITY})
    prof.save(root / "calibration")
    for i, ident in enumerate(("ACC-1", "ACC-2")):
        data = np.random.default_rng(i).uniform(0, 1, (20, 30, 3)).astype(np.float32)
        deliver(replace(ChannelStack(data, ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0}), resolution="full"),
                prof, Original(ident, title=f"Blatt {i} <&>"), root / "deliverables", camera=prof.camera,
                dose=LightDoseRecord(1.0, 0.1))
    return root


def test_report_is_one_page_with_every_original(session, capsys):
    assert main(["report", str(session)]) == 0
    assert "2 original(s), 0 with problems" in capsys.readouterr().out
    text = (session / "report.html").read_text(encoding="utf-8")
    page = Page()
    page.feed(text)
    thumbs = [i for i in page.images if i.get("class") == "thumb"]
    assert [i["alt"] for i in thumbs] == ["ACC-1", "ACC-2"] and all(i["src"].startswith("data:image/png;base64,")
                                                                    for i in thumbs)
    words = "".join(page.text)
    assert "Blatt 0 <&>" in words and "&lt;&amp;&gt;" in text                     # escaped in the HTML
    assert "ACC-1: clipped" in words and "calibration dE00 train 0.40 / test 0.30" in words
    assert words.count("FADGI 4-star: pass (measured criteria)") == 2 and "Metamorfoze 2.0 Full: fail" in words
    assert "Calibration cal-test" in words and "mean dE00 train 0.4, test 0.3" in words


def test_a_tampered_delivery_shows_its_problem_and_exits_1(session, capsys):
    xyz = session / "deliverables" / "ACC-2" / "ACC-2_srgb_16bit.tif"
    data = bytearray(xyz.read_bytes())
    data[len(data) // 2] ^= 1
    xyz.write_bytes(bytes(data))
    assert main(["report", str(session)]) == 1
    assert "ACC-2:" in capsys.readouterr().err
    page = Page()
    page.feed((session / "report.html").read_text(encoding="utf-8"))
    assert [i["alt"] for i in page.images if i.get("class") == "thumb"] == ["ACC-1"]
    assert "no thumbnail: the files do not match their sidecar" in "".join(page.text)


def test_chromium_renders_the_page(session, tmp_path):
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium); the HTML was checked above")
    assert main(["report", str(session)]) == 0
    png = tmp_path / "shot.png"
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", f"--screenshot={png}",
                    "--window-size=1200,900", (session / "report.html").as_uri()], capture_output=True, timeout=120)
    from PIL import Image

    with Image.open(png) as im:
        pixels = np.asarray(im.convert("RGB"))
    assert pixels.shape[:2] == (900, 1200) and pixels.std() > 10          # something was drawn, not a blank page


@pytest.mark.fault("edited files")
def test_an_edited_sidecar_or_profile_is_named_not_shown(session, capsys):
    """Nothing unverified is shown: a sidecar edited against its schema is a row with its problem (no crash, exit
    1); a calibration profile edited after it was written is named with the check's one line instead of figures."""
    import json

    sidecar = session / "deliverables" / "ACC-2" / "ACC-2.json"
    doc = json.loads(sidecar.read_text(encoding="utf-8"))
    doc["qa"] = 5
    sidecar.write_text(json.dumps(doc), encoding="utf-8")
    cal = next((session / "calibration").glob("*.json"))
    prof = json.loads(cal.read_text(encoding="utf-8"))
    prof["mode"] = "transmissive" if prof["mode"] == "reflective" else "reflective"
    cal.write_text(json.dumps(prof), encoding="utf-8")
    assert main(["report", str(session)]) == 1
    err = capsys.readouterr().err
    assert "a bug in dualrgb" not in err and "ACC-2:" in err
    page = Page()
    page.feed((session / "report.html").read_text(encoding="utf-8"))
    words = "".join(page.text)
    assert "qa: 5 is not of type 'object'" in words and "edited after it was written" in words
    assert "mean dE00 train 0.4, test 0.3" not in words
