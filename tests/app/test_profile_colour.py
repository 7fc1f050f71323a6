"""`calibration show`'s colour lines (app.workflow.calibration.profile_colour): the delivered model and why, the
models' table with
the root-polynomials, the per-pixel figures beside the patch means; a profile made before says so."""
from __future__ import annotations

import numpy as np

from dualrgb.app.processing.characterise import characterise
from dualrgb.app.workflow.calibration.profile_colour import colour_lines
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.objective import PatchSet


def test_the_lines_hold_the_choice_the_table_and_the_per_pixel_figures():
    setup = default_setup("reflective")
    train, test = PatchSet(setup, setup.train), PatchSet(setup, setup.test)
    W = np.stack([LightSource((1, 6, 8)).weights(), LightSource((3, 5, 9)).weights()])
    rng = np.random.default_rng(1)
    vt = train.camera_values(W) * (1 + 0.005 * rng.standard_normal((len(train), 6)))
    vs = test.camera_values(W)
    pixels = {"test": [v * (1 + 0.02 * rng.standard_normal((40, 6))) for v in vs]}
    c = characterise(vt, train.xyz, train.white, vs, test.xyz, optimise=False, pixels=pixels)
    stats = {**c.to_dict(), "condition_number_planned": 140.1}
    lines = colour_lines(stats, c.best, 6)
    assert lines[0].startswith(f"matrix: {c.best} (") and "5-fold cross-validation" in lines[0]
    assert "one standard error rule" in lines[0]
    px = stats["per_pixel_de00"]["test"]
    assert f"dE00 test mean {px['mean']:.3f} / p90 {px['p90']:.3f}" in lines[1] and "140 planned" in lines[1]
    rows = [line for line in lines if line.startswith(("  root-polynomial-", "  least-squares"))]
    assert len(rows) == 3 and sum("<- delivered" in line for line in rows) == 1
    assert any(line.startswith("  root-polynomial-2     21") for line in rows)


def test_a_profile_made_before_per_pixel_figures_says_so():
    old = {"best": "least-squares", "methods": {"least-squares": {"train": {"mean": 0.5}, "test": {"mean": 0.4}}},
           "selection": {"chosen": "least-squares", "folds": 0}}
    lines = colour_lines(old, "least-squares", 6)
    assert lines[0].startswith("matrix: least-squares (6 terms of 6 channels") and "train mean dE00 0.500" in lines[0]
    assert lines[1].startswith("per pixel: not measured") and len(lines) == 2
