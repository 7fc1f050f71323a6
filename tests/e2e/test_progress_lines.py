"""`dualrgb calibrate`'s progress lines move (issue 42 point 3): every report figure is a line of its own ("report:
figure 3 of 14, ..."), the processing's long steps say what they do, the lines carry the time left from the phase
costs, and the run's phases are recorded in the per-user data folder for the next run (the window's too); an
original shot alone says when it writes its deliverables and records its phases (metering, frames, delivery); a
queue of two has one progress for the whole queue, each line with its time left from those costs, and records both
originals' phases in the same store."""
from __future__ import annotations

import json
import re

from dualrgb.app.cli import main

LINE = re.compile(r"^\[\s*(\d+)%\] (.*)$", re.M)
FIGURE = re.compile(r"^\[\s*(\d+)%\] report: figure (\d+) of (\d+), \S.*\(time left ", re.M)


def test_calibrate_prints_each_report_figure_with_the_time_left(tmp_path, capsys, user_data_dir):
    assert main(["calibrate", "--virtual-lab", "--session", str(tmp_path / "day"), "--hdr", "off", "--dark-frames",
                 "1", "--flat-frames", "1", "--no-de-fit", "--settle", "0", "--json", str(tmp_path / "cal.json")]) == 0
    err = capsys.readouterr().err
    figures = [(int(pct), int(k), int(n)) for pct, k, n in FIGURE.findall(err)]
    report = tmp_path / "day" / "calibration" / "report"
    pngs = list(report.glob("*.png"))
    assert [k for _p, k, _n in figures] == list(range(1, len(pngs) + 1)) and len(pngs) >= 8, err[-3000:]
    assert {n for *_, n in figures} == {len(pngs)}
    percents = [p for p, *_ in figures]
    assert percents == sorted(percents) and 85 <= percents[0] < 100
    for step in ("finding the chart in the frame", "spectral estimate: ", "stand model: fitting"):
        assert step in err, step
    runs = json.loads((user_data_dir / "phase_costs.json").read_text())["runs"]
    assert {"darks", "flats", "processing: report", "saving"} <= set(runs["calibration"])
    assert main(["capture", "--virtual-lab", "--session", str(tmp_path / "day"), "--id", "PROG-1", "--settle",
                 "0"]) == 0
    err = capsys.readouterr().err
    merging = r"^\[ 80%\] PROG-1: merging its frames, writing its deliverables \(time left .+\)$"
    assert re.search(merging, err, re.M), err[-2000:]
    runs = json.loads((user_data_dir / "phase_costs.json").read_text())["runs"]
    assert {name: len(samples) for name, samples in runs["original"].items()} == \
        {"metering": 1, "frames": 1, "delivery": 1}, runs["original"]
    _queue_of_two(tmp_path, capsys, user_data_dir)


def _queue_of_two(tmp_path, capsys, user_data_dir) -> None:
    """A queue of 2 after the single original: every line before the end says its time left (the original's
    costs are measured), the percent is the whole queue's (it never starts again), both originals recorded."""
    csv_path = tmp_path / "queue.csv"
    csv_path.write_text("identifier\nPROG-Q1\nPROG-Q2\n", encoding="utf-8")
    assert main(["capture", "--virtual-lab", "--session", str(tmp_path / "day"), "--queue", str(csv_path),
                 "--settle", "0"]) == 0
    err = capsys.readouterr().err
    lines = [(int(pct), text) for pct, text in LINE.findall(err)]
    assert len(lines) >= 6 and lines[-1][0] == 100, err[-3000:]
    percents = [p for p, _t in lines]
    assert percents == sorted(percents), percents                      # one bar: never back to 0 for PROG-Q2
    assert any("PROG-Q2" in t and p >= 40 for p, t in lines), lines
    assert all("(time left " in t for p, t in lines if p < 100), [t for p, t in lines if "(time left" not in t]
    runs = json.loads((user_data_dir / "phase_costs.json").read_text())["runs"]
    assert {name: len(samples) for name, samples in runs["original"].items()} == \
        {"metering": 3, "frames": 3, "delivery": 3}, runs["original"]
