"""The CSRF processing (app.processing.csrf) on a session of synthetic DNGs with known levels: signal rates, the
uncertainty terms and the normalisation checked against hand computations; missing darks and damaged frames
refused in one line; the written CSV read back."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb.app.processing.csrf import compute_csrf, session_signals, write_camera_csv
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.session.manifest import DamagedFramesError
from dualrgb.core.vocabulary import Role, monochromatic_light, step_id
from dualrgb.drivers.camera.base import RawCapture
from dualrgb.drivers.virtual.dng import DngInfo, dng_bytes
from dualrgb.simulation.datasets import load_camera
from dualrgb.simulation.radiance_reference import RadianceReference
from dualrgb.simulation.spectral_io import SpectralDataError, read_spectral_csv

H, W = 40, 60
BLACK = 600


def mosaic(levels_rgb, noise: float, rng) -> np.ndarray:
    """An RGGB mosaic: BLACK + the channel's level + gaussian noise."""
    m = np.empty((H, W))
    r, g, b = levels_rgb
    m[0::2, 0::2], m[0::2, 1::2], m[1::2, 0::2], m[1::2, 1::2] = r, g, g, b
    return np.clip(np.rint(BLACK + m + rng.normal(0, noise, m.shape)), 0, 15520).astype(np.uint16)


def record(session, role, step, data, t, **meta):
    raw = RawCapture(dng_bytes(data, DngInfo(exposure_s=t)), "X.DNG", t, 50, 8.0, "test")
    return session.record(raw, role.value, step_id=step, **meta)


@pytest.fixture
def session(tmp_path):
    """Two wavelengths: 500 nm at 0.5 s, 600 nm at 2 s; 3 darks at each exposure (dark levels 10 / 40 DN)."""
    rng = np.random.default_rng(0)
    s = CaptureSession.create(tmp_path / "s")
    plan = {500.0: (0.5, [(1000, 4000, 2000), (1010, 4040, 2020)]), 600.0: (2.0, [(8000, 2000, 100)] * 2)}
    for nm, (t, frames) in plan.items():
        for k, levels in enumerate(frames):
            record(s, Role.CSRF, step_id(Role.CSRF, light=monochromatic_light(nm), exposure_s=t, frame=k),
                   mosaic(np.add(levels, 40 * t / 2), 3.0, rng), t, wavelength_nm=nm)
    for t in (0.5, 2.0):
        for k in range(3):
            record(s, Role.DARK, step_id(Role.DARK, exposure_s=t, frame=k), mosaic([40 * t / 2] * 3, 3.0, rng), t)
    yield s
    s.close()


def test_signal_rates_and_uncertainty_by_hand(session):
    sig = {s.wavelength_nm: s for s in session_signals(session, region=1.0)}
    s500 = sig[500.0]
    assert s500.exposure_s == 0.5 and s500.frames == 2 and s500.dark_frames == 3
    assert s500.rate == pytest.approx(np.array([1005, 4020, 2010]) / 0.5, abs=0.5)       # mean of the frames / t
    # frame repeatability dominates here: frames 10/40/20 DN apart -> sd/sqrt(2) = |a-b|/2
    assert s500.u_rate == pytest.approx(np.array([5, 20, 10]) / 0.5, rel=0.05)
    s600 = sig[600.0]
    assert s600.rate == pytest.approx(np.array([8000, 2000, 100]) / 2.0, abs=0.2)
    # identical frames: the pixel noise (3 DN / sqrt(pixels x frames)) and the dark's repeatability remain
    pixels = np.array([H * W / 4, H * W / 2, H * W / 4])
    assert np.all(s600.u_rate * 2.0 >= 3.0 / np.sqrt(pixels * 2) * 0.8) and np.all(s600.u_rate * 2.0 < 0.5)


def test_csrf_is_rate_over_radiance_normalised_to_the_green_maximum(session, tmp_path):
    reference = RadianceReference(np.array([500.0, 600.0]), np.array([2.0, 4.0]), np.array([0.01, 0.0]), "ref",
                                  "radiance table")
    result = compute_csrf(session_signals(session, region=1.0), reference)
    raw = np.array([np.array([1005, 4020, 2010]) / 0.5 / 2.0, np.array([8000, 2000, 100]) / 2.0 / 4.0])
    assert result.values == pytest.approx(raw / raw[:, 1].max(), rel=2e-3)
    assert result.values[:, 1].max() == 1.0
    # the 1 % radiance uncertainty at 500 nm is in the propagated uncertainty: at least 1 % of the value
    assert np.all(result.uncertainty[0] >= 0.01 * result.values[0])
    path = write_camera_csv(result, tmp_path / "out.csv", {"camera": "synthetic"})
    table = read_spectral_csv(path)
    assert table.columns == ["red", "green", "blue", "u_red", "u_green", "u_blue"]
    assert table.meta["camera"] == "synthetic" and table.meta["units"].startswith("relative spectral sensitivity")
    assert table.values[:, :3] == pytest.approx(result.values, rel=1e-6)
    with pytest.raises(SpectralDataError, match="covers 500-600 nm"):      # two wavelengths: too short to use
        load_camera(path)


@pytest.mark.fault("input")
def test_missing_darks_are_a_one_line_error(tmp_path):
    s = CaptureSession.create(tmp_path / "s")
    rng = np.random.default_rng(1)
    record(s, Role.CSRF, "csrf/x/0.25/0", mosaic((10, 10, 10), 1, rng), 0.25, wavelength_nm=500.0)
    with pytest.raises(ValueError, match=r"no dark frames at 1/4 s \(used at 500 nm\)"):
        session_signals(s)


@pytest.mark.fault("session integrity")
def test_a_damaged_frame_is_not_processed(session):
    frame = session.entries(Role.CSRF.value)[0]
    path = session.file_path(frame)
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(DamagedFramesError, match="not processed"):
        session_signals(session)
