"""Quality metrics of the target report, each on a synthetic case with a known answer."""
from __future__ import annotations

import colour
import numpy as np
import pytest
from synthetic_frames import BLACK, WHITE, vignette

from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef
from dualrgb.app.processing.quality import (
    CalibrationFrames,
    assess,
    grade_metrics,
    lab_differences,
    lightness_noise,
    neutral_patches,
    sensor_noise,
    shading,
    temporal_noise,
    tone_and_white_balance,
    uniformity,
)

RGGB = np.array([[0, 1], [1, 2]])


def test_lab_components_of_pure_lightness_chroma_and_hue_changes():
    ref = np.array([[50.0, 30.0, 40.0]] * 3)                    # C* = 50, h = 53.13 deg
    theta = np.radians(10.0)
    rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    cap = np.array([[53.0, 30.0, 40.0],                          # dL* = +3
                    [50.0, 36.0, 48.0],                          # chroma x1.2: dC* = +10
                    [50.0, *(rot @ [30.0, 40.0])]])              # hue +10 deg: dH* = 2 C sin(5 deg)
    d = lab_differences(ref, cap)
    assert d["dL"] == pytest.approx([3, 0, 0], abs=1e-12)
    assert d["dC"] == pytest.approx([0, 10, 0], abs=1e-9)
    assert d["dH"] == pytest.approx([0, 0, 2 * 50 * np.sin(np.radians(5))], abs=1e-9)
    assert lab_differences(cap[2:], ref[2:])["dH"][0] < 0          # signed like the hue difference


def test_tone_response_and_white_balance_of_the_neutral_patches():
    ref = np.array([[96, 0.3, -0.5], [81, -0.4, 0.2], [20, 60, 10], [50, 0.1, 1.0], [30, -0.5, -1.0]], float)
    cap = ref.copy()
    cap[:, 0] += [1.0, -2.0, 5.0, 0.5, 0.0]                      # tone errors (patch 2 is chromatic)
    cap[3, 1:] += [2.0, -1.0]                                    # a colour cast on one grey
    idx = neutral_patches(ref)
    assert idx.tolist() == [0, 1, 3, 4]                          # lightest first, the red patch excluded
    t = tone_and_white_balance(ref, cap, idx)
    assert t["dL"] == pytest.approx([1.0, -2.0, 0.5, 0.0]) and t["max_abs_dL"] == pytest.approx(2.0)
    # white balance = CIEDE2000 without the lightness term: colour-science on the pair with equal L*
    expect = colour.delta_E(ref[3], np.r_[ref[3, 0], cap[3, 1:]], method="CIE 2000")
    assert t["white_balance_de00_ab"][2] == pytest.approx(expect, abs=1e-9)
    assert t["white_balance_de00_ab"][0] == pytest.approx(0.0, abs=1e-12)
    assert t["max_white_balance"] == pytest.approx(expect, abs=1e-9)


def test_lightness_noise_propagates_channel_noise_to_l_star():
    white = np.array([95.047, 100.0, 108.883])
    A = np.array([[0.2, 0.1, 0.0], [0.3, 0.5, 0.1], [0.1, 0.2, 0.9]])     # 3 channels -> XYZ
    v = np.array([[20.0, 25.0, 30.0]])
    sd = np.array([[0.2, 0.1, 0.3]])
    y = float((v @ A[:, 1])[0])
    sy = float(np.sqrt(np.sum((sd[0] * A[:, 1]) ** 2)))
    eps = 1e-4                                                   # independent: finite difference of colour's L*

    def lab(yy: float) -> float:
        return colour.XYZ_to_Lab(np.array([0.3, yy, 0.3]) / 100, colour.XYZ_to_xy(white / 100))[0]

    slope = (lab(y + eps) - lab(y - eps)) / (2 * eps)
    assert lightness_noise(v, sd, A, white, np.array([0]))[0] == pytest.approx(slope * sy, rel=1e-5)


def test_shading_of_a_known_block_pattern():
    blocks = np.tile(np.array([[0.9, 1.0, 1.1]]), (3, 1))        # 3 x 3 blocks: -10 %, 0, +10 %
    mosaic = np.kron(blocks, np.ones((20, 20)))                   # 60 x 60 mosaic, each block 20 x 20 pixels
    s = shading(mosaic, RGGB, blocks=(3, 3))
    for ch in "RGB":
        assert s[ch]["range_pct"] == pytest.approx(20.0)
        assert s[ch]["max_abs_pct"] == pytest.approx(10.0)
        assert np.allclose(s[ch]["deviation_pct"], 100 * (blocks - 1.0))


def test_temporal_noise_ignores_hot_pixels_and_is_not_quantised():
    rng = np.random.default_rng(1)
    a, b = (np.rint(600 + rng.normal(0, 2.5, (200, 300))) for _ in range(2))
    a[rng.random(a.shape) < 0.002] += 3000                        # hot pixels / spikes in one frame
    n = temporal_noise(a, b, RGGB)
    for ch in "RGB":
        assert n[ch] == pytest.approx(np.sqrt(2.5 ** 2 + 1 / 12), rel=0.03)


def _flats_and_darks(gain=4.0, read=2.5, seed=3):
    """Darks and flats (2 frames per exposure) of a vignetted light with photon noise at ``gain`` e-/DN."""
    rng = np.random.default_rng(seed)
    h, w = 80, 120
    light = 60000.0 * vignette(h, w, 0.3)                          # DN/s
    refs_d, refs_f = [], []
    for t in (0.05, 0.1):
        for _ in range(3):
            refs_d.append(ExposureRef(np.rint(BLACK + rng.normal(0, read, (h, w))).astype(np.uint16), t))
        for _ in range(2):
            e = rng.poisson(light * t * gain) / gain
            refs_f.append(ExposureRef(np.clip(np.rint(BLACK + e + rng.normal(0, read, (h, w))), 0, WHITE)
                                      .astype(np.uint16), t))
    return refs_d, refs_f, light


def test_sensor_noise_and_uniformity_from_darks_and_flats():
    darks, flats, light = _flats_and_darks()
    proc = CaptureProcessor(dark_frames=darks, white_level=WHITE, black_level=BLACK)
    proc.set_white("LS1", flats)
    cal = CalibrationFrames(proc, darks, {"LS1": flats})
    noise = sensor_noise(cal, RGGB)
    assert noise["read_noise_dn"]["G"] == pytest.approx(np.sqrt(2.5 ** 2 + 1 / 12), rel=0.05)
    g = noise["flats"]["LS1"]["G"]
    assert noise["flats"]["LS1"]["exposure_s"] == 0.1 and g["gain_e_per_dn"] == pytest.approx(4.0, rel=0.08)
    assert g["snr"] == pytest.approx(g["signal_dn"] / np.sqrt(g["signal_dn"] / 4 + 2.5 ** 2), rel=0.05)
    u = uniformity(cal, RGGB)["LS1"]
    expect = shading(light, RGGB)["G"]["range_pct"]                # the light field's own shading
    assert u["light_field"]["G"]["range_pct"] == pytest.approx(expect, rel=0.02)
    assert u["after_flat_field"]["G"]["range_pct"] < 0.5           # a flat-fielded uniform white is flat


def test_grading_statuses_scope_and_sources():
    colour_only = grade_metrics({"colour_mean_de00": 1.0, "colour_p90_de00": 2.0, "colour_max_de00": 3.0})
    for g in colour_only.values():
        assert g["scope"] == "colour accuracy only" and "SFR / MTF and sampling efficiency" in g["not_assessed"]
        assert g["metrics"]["tone_max_abs_dl"]["status"] == "not assessed"
        assert all(r["source"] for r in g["metrics"].values())
    full = grade_metrics({"colour_mean_de00": 1.0, "colour_p90_de00": 2.0, "colour_max_de00": 3.0,
                          "tone_max_abs_dl": 1.5, "white_balance_max_de": 0.5, "noise_max_lstar": 1.0,
                          "illuminance_nonuniformity_pct": 0.4})
    fadgi, iso = full["FADGI 4-star"], full["ISO 19264-1:2021 A"]
    assert fadgi["metrics"]["tone_max_abs_dl"]["status"] == "fail"       # FADGI: < 1.5
    assert iso["metrics"]["tone_max_abs_dl"]["status"] == "pass"         # ISO: <= 2
    assert fadgi["verdict"] == "fail" and iso["verdict"] == "pass (measured criteria)"
    assert iso["scope"] == "measured criteria only (not a full grade)"


def test_assess_collects_everything_for_the_report():
    ref = np.array([[96, 0.3, -0.5], [50, 0.1, 1.0], [40, 40, 20]], float)
    cap = ref + [[0.5, 0, 0], [-0.5, 0.5, 0], [0, 1, 1]]
    q = assess(ref, cap, ["white", "grey", "red"], np.array([0.3, 0.6, 1.0]))
    assert q["measured"]["tone_max_abs_dl"] == pytest.approx(0.5) and "noise_max_lstar" not in q["measured"]
    assert q["grading"]["FADGI 4-star"]["metrics"]["noise_max_lstar"]["status"] == "not assessed"
    assert q["lab_differences"]["summary"]["dL"]["max_abs"] == pytest.approx(0.5)
