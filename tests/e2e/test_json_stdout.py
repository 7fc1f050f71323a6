"""``--json PATH|-`` one way everywhere (issue 27): every command that has ``--json`` is run with ``-``; its stdout
is exactly one JSON document (nothing else), starting with "format" and "software", holding no NaN or Infinity;
no file named ``-`` appears. The list of commands comes from the parser itself, so a new command with --json
that this test does not run fails it."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from import_folders import PATCHED, corners, make_folder

from dualrgb.app.cli import build_parser

FRAME = ["--frame-size", "160x112", "--settle", "0"]
QUEUE = "identifier,title,mode\nQ-1,One,reflective\nQ-2,Two,transmissive\n"


def json_commands(parser: argparse.ArgumentParser, prefix: str = "") -> set[str]:
    """'calibration show', 'sphere status', ...: every (sub)command whose parser has a --json option."""
    found = {prefix} if prefix and any("--json" in a.option_strings for a in parser._actions) else set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found |= json_commands(sub, f"{prefix} {name}".strip())
    return found


def strict(text: str, what: str) -> dict:
    def refuse(token: str) -> float:
        raise AssertionError(f"{what}: {token} in the JSON")
    doc = json.loads(text, parse_constant=refuse)
    assert isinstance(doc, dict) and list(doc)[:2] == ["format", "software"], f"{what}: {list(doc)[:3]}"
    assert doc["format"].startswith("dualrgb-") and doc["software"]["dualrgb"], what
    return doc


@pytest.fixture(scope="module")
def stand(tmp_path_factory):
    """A working folder, the environment, and a sphere emulator for `sphere status`."""
    from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator

    root = tmp_path_factory.mktemp("json")
    (root / "queue.csv").write_text(QUEUE, encoding="utf-8")
    make_folder(root / "shot", shape=PATCHED)                   # raw files "shot by another program" (import)
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "DUALRGB_DATA_DIR": str(root / "data")}
    emulator = SphereEmulator(watchdog_s=30)
    emulator.start()
    yield root, env, emulator.port
    emulator.stop()


def cases(port: str) -> dict[str, list[str]]:
    day = ["--session", "day", "--virtual-lab", *FRAME]
    return {
        "calibrate": ["calibrate", *day, "--hdr", "off", "--dark-frames", "2", "--flat-frames", "2", "--no-de-fit"],
        "capture": ["capture", *day, "--id", "J-1"],
        "process": ["process", "day"],
        "cube": ["cube", "day/deliverables/J-1"],
        "verify": ["verify", "day"],
        "bag": ["bag", "day/deliverables", "--out", "bag"],
        "report": ["report", "day"],
        "import": ["import", "shot/raw", "--roles", "shot/ROLES.csv", "--session", "imported", "--target-corners",
                   f"train={corners(PATCHED)}", "--target-corners", f"test={corners(PATCHED)}"],
        "calibration show": ["calibration", "show", "CAL", "--virtual-lab", *FRAME],
        "devices": ["devices"],
        "sphere status": ["sphere", "--port", port, "status"],
        "simulate": ["simulate", "--method", "exhaustive", "--objective", "noise-free", "--top", "1"],
        "study thesis": ["study", "thesis", "--budget", "small", "--out", "thesis"],
        "raw-info": ["raw-info", "DNG"],
        "measure csrf": ["measure", "csrf", "--virtual-lab", "--start", "500", "--end", "600", "--step", "50",
                         "--frame-size", "96x64", "--out", "cam.csv"],
        "lab score": ["lab", "score", "day"],
        "collection show": ["collection", "show", "GEM", "--collections", "collections"],
    }


def test_every_command_with_json_is_run_here():
    assert json_commands(build_parser()) == set(cases("PORT"))


def run(root: Path, env: dict, args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dualrgb", *args, "--json", "-"], cwd=root, env=env,
                          capture_output=True, text=True, timeout=900)


def test_json_to_stdout_in_every_command(stand):
    root, env, port = stand
    from dualrgb.app.workflow.day.collection_presets import make_preset, save_preset

    save_preset(make_preset("GEM", rights="CC BY 4.0", extra=[("department", "Paintings")]), root / "collections")
    docs = {}
    for name, args in cases(port).items():          # in order: calibrate first, the others use its session
        if "CAL" in args:
            args = [str(next((root / "day" / "calibration").glob("cal-*.json"))) if a == "CAL" else a for a in args]
        if "DNG" in args:
            args = [str(next((root / "day").rglob("*.DNG"))) if a == "DNG" else a for a in args]
        r = run(root, env, args)
        ok = (0, 1) if name == "devices" else (0,)       # devices: exit 1 when nothing is connected (here)
        assert r.returncode in ok, f"{name}: {r.stderr[-2000:]}"
        docs[name] = strict(r.stdout, name)
    assert not (root / "-").exists()
    assert docs["calibrate"]["format"] == "dualrgb-calibration/1" and docs["calibrate"]["charts"]["train"]["packaged"]
    stats = docs["calibrate"]["statistics"]             # issue 40: per pixel beside the patch means, the model table
    for target in ("train", "test"):
        px = stats["per_pixel_de00"][target]
        assert px["p90"] > px["mean"] > stats["methods"][stats["best"]][target]["mean"]
    models = {row["model"]: row for row in stats["models"]}
    assert {"least-squares", "root-polynomial-2"} <= set(models) and models[stats["best"]]["chosen"]
    assert models["root-polynomial-2"]["terms"] == 21 and models["root-polynomial-2"]["per_pixel_de00_mean"] > 0
    assert 1 < stats["condition_number"] < 1e3 and 1 < stats["condition_number_planned"] < 1e3
    assert docs["calibration show"]["statistics"]["models"] == stats["models"]
    assert docs["capture"]["qa"]["calibration_test_per_pixel_de00"] == stats["per_pixel_de00"]["test"]
    assert f"per pixel test {stats['per_pixel_de00']['test']['mean']:.2f}" in docs["capture"]["qa"]["text"]
    sidecar = json.loads((root / docs["capture"]["sidecar"]).read_text(encoding="utf-8"))
    assert sidecar["calibration"]["per_pixel_de00"] == {k: stats["per_pixel_de00"][k] for k in ("train", "test")}
    assert sidecar["calibration"]["model"]["method"] == stats["best"] and sidecar["calibration"]["noise_gain"]
    assert docs["capture"]["original"]["identifier"] == "J-1" and docs["process"]["originals"]
    assert docs["calibration show"]["check"]["refusals"] == []
    assert docs["verify"]["ok"] and docs["bag"]["originals"] == ["J-1"] and docs["cube"]["samples"] == 160
    assert docs["report"]["originals"][0]["identifier"] == "J-1" and docs["report"]["originals"][0]["problems"] == []
    assert docs["import"]["originals"][0]["identifier"] == "ACC-1" and docs["import"]["copied"] == 14
    assert [o["identifier"] for o in docs["lab score"]["originals"]] == ["J-1"]
    assert docs["collection show"]["rights"] == "CC BY 4.0"
    assert docs["collection show"]["extra"] == {"department": "Paintings"}


def test_queue_check_json_to_stdout(stand):
    """`capture --queue --check --json -`: the plan as JSON alone on stdout, no device opened."""
    root, env, _port = stand
    if not (root / "day" / "calibration").is_dir():
        pytest.skip("needs the calibration of test_json_to_stdout_in_every_command")
    r = run(root, env, ["capture", "--session", "day", "--queue", "queue.csv", "--check", "--skip-invalid"])
    assert r.returncode == 0, r.stderr
    plan = strict(r.stdout, "capture --check")
    assert plan["format"] == "dualrgb-queue-plan/1"
    assert [(row["identifier"], row["state"]) for row in plan["rows"]] == [("Q-1", "shoot"), ("Q-2", "refused")]
    assert "transmissive original, reflective calibration" in plan["rows"][1]["reason"]
