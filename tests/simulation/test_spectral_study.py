"""``dualrgb study spectral`` at a tiny budget: outputs, every method under every light set, the invariants the
README's figures rest on."""
from __future__ import annotations

import json

import pytest

from dualrgb.app.cli import main
from dualrgb.simulation.spectral_estimation import SPECTRAL_METHODS
from dualrgb.simulation.studies.spectral import LIGHT_SETS


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("spectral-study")
    assert main(["study", "spectral", "--budget", "tiny", "--modes", "reflective", "--out", str(out)]) == 0
    return out, json.loads((out / "spectral.json").read_text())


def test_outputs_and_every_method_under_every_light_set(study):
    out, data = study
    assert (out / "spectral.png").stat().st_size > 10_000 and "| reflective |" in (out / "SUMMARY.md").read_text()
    assert data["format"] == "dualrgb-study-spectral/1"
    (mode,) = data["modes"]
    assert {(r["lights"], r["method"]) for r in mode["rows"]} == {(k, m) for k in LIGHT_SETS for m in SPECTRAL_METHODS}
    for r in mode["rows"]:
        assert 0 < r["rmse_seen"] < r["rmse"] < 0.2 and 0.9 < r["gfc"] <= 1 and r["time_s"] >= r["fit_s"] > 0
        assert set(r["de00"]) == {"D65", "A", "D50", "FL11", "LED 2880 K"}
        assert r["rmse"] >= mode["linear_bound"][r["lights"]] - 1e-9      # no linear map beats the bound


def test_six_channels_and_spectral_lights_estimate_spectra_better(study):
    _, data = study
    rows = {(r["lights"], r["method"]): r for r in data["modes"][0]["rows"]}
    assert rows[("colour-chosen", "wiener")]["rmse"] < rows[("3-channel", "wiener")]["rmse"]
    assert rows[("colour-chosen", "wiener")]["rmse"] < rows[("colour-chosen", "pinv")]["rmse"]
    expected = data["modes"][0]["expected_spectral_rmse"]
    assert expected["spectral-chosen"]["train"]["rmse"] <= expected["colour-chosen"]["train"]["rmse"]
