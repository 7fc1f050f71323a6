"""The Qt-free display helpers behind the panels."""
from __future__ import annotations

import numpy as np
import pytest

from app.gui.viewmodel import (
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
