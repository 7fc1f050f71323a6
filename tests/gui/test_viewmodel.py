"""The Qt-free display helpers behind the panels."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb.app.gui.viewmodel import (
    DoseFeed,
    format_duration,
    light_from_levels,
    mixed_spectrum,
    preview_histogram,
    raw_histogram,
)


def test_light_from_levels_and_mix():
    light = light_from_levels([1, 0, 0, 0, 0, 0.5, 0, 0, 0, 0])
    assert light.leds == (1, 6) and light.levels == (1.0, 0.5)
    assert light_from_levels([0] * 10).is_dark
    leds = np.eye(10, 5)
    assert np.allclose(mixed_spectrum([1, 0, 0, 0, 0.5, 0, 0, 0, 0, 0], leds), [1, 0, 0, 0, 0.5])


def test_raw_histogram_counts_clipped_and_nonlinear():
    planes = {"R": np.array([[100, 12000], [15520, 5000]]), "G1": np.full((2, 2), 600)}
    h = raw_histogram(planes, 15520)
    assert h.fraction_clipped == pytest.approx(1 / 8)
    assert h.fraction_nonlinear == pytest.approx(2 / 8)
    assert sum(c.sum() for c in h.counts.values()) == 8
    assert "clipped" in h.summary()


def test_preview_histogram_inverts_the_encoding():
    black, white = 600, 15520
    dn = np.array([1000.0, 11000.0, 15520.0])
    enc = np.round(((dn - black) / (white - black)) ** (1 / 2.2) * 255).astype(np.uint8)
    frame = np.repeat(enc[:, None], 3, axis=1).reshape(1, 3, 3)
    h = preview_histogram(frame, black, white)
    assert h.fraction_clipped == pytest.approx(1 / 3)
    assert h.max_dn == pytest.approx(white)


def test_dose_feed_counts_time_with_the_light_on():
    feed = DoseFeed()
    feed.update(0.0, True, [1.0] + [0.0] * 9)
    feed.update(2.0, True, [1.0] + [0.0] * 9)
    feed.update(3.0, False, [1.0] + [0.0] * 9)
    dose = feed.update(10.0, False, [1.0] + [0.0] * 9)
    assert dose.level_s[0] == pytest.approx(3.0)
    assert dose.on_s == pytest.approx(3.0)
    assert dose.lux_s > 0


def test_format_duration():
    assert format_duration(None) == "—"
    assert format_duration(42.4) == "42 s"
    assert format_duration(185) == "3 min 05 s"
    assert format_duration(3720) == "1 h 02 min"


def test_units_for_people():
    from dualrgb.app.gui.units import NBSP, dn, dose, level_pct, light_pct, parse_exposure, shutter
    from dualrgb.simulation.lightsource import LightSource

    assert level_pct(0.002242) == f"0.2242{NBSP}%" and level_pct(1) == f"100{NBSP}%"
    assert light_pct(LightSource((1, 6, 7), (0.002242, 0.4164, 1.0))) == \
        f"LEDs 1, 6, 7 at 0.2242{NBSP}%, 41.64{NBSP}%, 100{NBSP}%"
    assert shutter(1 / 80) == f"1/80{NBSP}s" and shutter(2.0) == f"2{NBSP}s"
    for text, seconds in (("1/80", 1 / 80), ("1/80 s", 1 / 80), ("0.0125", 0.0125), ("2 s", 2.0), ("2,5", 2.5),
                          (shutter(1 / 80), 1 / 80)):
        assert parse_exposure(text) == pytest.approx(seconds), text
    for bad in ("", "fast", "0", "-1", "1/0"):
        with pytest.raises(ValueError, match="expected a positive time"):
            parse_exposure(bad)
    assert dose(138.0) == f"0.0383{NBSP}lux·h (138{NBSP}lux·s)"          # 138 / 3600, as conservators budget
    assert dn(11000) == f"11\u2009000{NBSP}DN"


def test_de_bands_follow_the_grading_thresholds():
    from dualrgb.app.gui.de_scale import SCALE_MAX, de_band, de_bands, lookup_table
    from dualrgb.app.processing.quality import STANDARD_LIMITS

    bands = de_bands()
    edges = [b.high for b in bands[:-1]]
    assert edges == [STANDARD_LIMITS["FADGI 4-star"]["colour_mean_de00"].value,
                     STANDARD_LIMITS["FADGI 4-star"]["colour_p90_de00"].value,
                     STANDARD_LIMITS["Metamorfoze 2.0 Full"]["colour_max_de00"].value,
                     STANDARD_LIMITS["ISO 19264-1:2021 A"]["colour_max_de00"].value] == [2.0, 4.0, 7.0, 10.0]
    assert de_band(0.96).colour == de_band(1.99).colour != de_band(4.28).colour     # no longer both yellow
    assert de_band(4.28) is not None and de_band(50).label == "≥ 10"
    lut = lookup_table(120)
    assert lut.shape == (120, 3) and tuple(lut[0]) == (0x2e, 0x7d, 0x32) and SCALE_MAX > 10


def test_patch_names_fit_their_cells():
    from dualrgb.app.gui.results_plots import cell_name, vector_pairs

    assert cell_name("dark skin") == "dark skin"
    assert cell_name("neutral 6.5 (.44 D)") == "neutral\n6.5 (.44 …"              # two lines at most
    assert all(len(line) <= 10 for line in cell_name("a very long patch name indeed").split("\n"))
    x, y = vector_pairs(np.array([[0.0, 1.0], [2.0, 3.0]]), np.array([[0.5, 1.5], [2.5, 3.5]]))
    assert list(x) == [0.0, 0.5, 2.0, 2.5] and list(y) == [1.0, 1.5, 3.0, 3.5]


def test_calibration_lines_name_what_matters():
    from types import SimpleNamespace

    from dualrgb.app.gui.viewmodel import calibration_lines
    from dualrgb.app.workflow.calibration.profile import CameraIdentity, ReuseCheck
    from dualrgb.core.vocabulary import NamedLight
    from dualrgb.simulation.lightsource import LightSource

    prof = SimpleNamespace(id="cal-1", preset="p", mode="reflective", age_h=lambda: 1.25,
                           camera=CameraIdentity("Nikon D610", "123", "", 50, 8.0), test_mean=0.4,
                           statistics={"best": "ls", "methods": {"ls": {"train": {"mean": 0.6}}}},
                           lights=[NamedLight("p light 1", LightSource((1, 6), (1.0, 0.5)))],
                           exposures={"p light 1": [1 / 80, 1.0]}, matrix=SimpleNamespace(method="least-squares"))
    lines = calibration_lines(prof, ReuseCheck(refusals=["ISO 100 differs from the calibration's 50"]))
    text = "\n".join(lines)
    assert "made 1.2 h ago" in text and "ISO 50, f/8" in text and "serial 123" in text
    assert "LEDs 1, 6 at 100\u00a0%, 50\u00a0%" in text and "1/80\u00a0s, 1\u00a0s" in text
    assert "train 0.60 / test 0.40" in text and "does not match the stand: ISO 100" in text


def test_convergence_tap_keeps_the_best_light_set():
    from dualrgb.app.gui.viewmodel import ConvergenceTap
    from dualrgb.simulation.datasets import default_setup

    seen = []
    tap = ConvergenceTap.make(default_setup("reflective"), lambda n, best: seen.append((n, best)))
    assert tap.partial() is None
    idx = np.array([[[0, 3, 6], [2, 4, 8]], [[0, 5, 7], [2, 4, 8]]])
    w = np.array([[[1.0, 1.0, 1.0], [1.0, 1.0, 1.0]], [[0.0, 0.5, 1.0], [1.0, 0.2, 1.0]]])
    costs = tap.cost_indexed(idx, w)
    k = int(np.argmin(costs))
    cand = tap.partial()
    assert seen[-1] == (tap.evaluations, pytest.approx(float(costs[k]))) and tap.evaluations == 2
    first = cand.sources[0]
    assert first.leds == tuple(int(i) + 1 for i, v in zip(idx[k, 0], w[k, 0], strict=True) if v > 0)
    # the float64 re-evaluation of the default objective (expected captured) agrees; noise-free is lower
    assert cand.expected_train.mean == pytest.approx(float(costs[k]), abs=2e-3)
    assert cand.train.mean < cand.expected_train.mean
