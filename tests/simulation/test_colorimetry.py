import colour
import numpy as np
import pytest

from dualrgb.simulation.colorimetry import delta_e_2000, delta_e_2000_components, tristimulus, white_point, xyz_to_lab
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.fast_de import de2000_lab, mean_de2000


def _pairs(n=20000, seed=1):
    rng = np.random.default_rng(seed)
    lab1 = np.c_[rng.uniform(0, 100, n), rng.uniform(-90, 90, n), rng.uniform(-90, 90, n)]
    lab2 = lab1 + rng.normal(0, 2.5, lab1.shape)
    lab1[:20, 1:] = 0.0             # achromatic samples exercise the zero-chroma rules
    lab2[10:30, 1:] = 0.0
    lab2[40:60] = lab1[40:60]       # identical pairs
    return lab1, lab2


# Sharma, Wu & Dalal (2005) test data (first pairs of their table)
SHARMA = [
    ((50.0, 2.6772, -79.7751), (50.0, 0.0, -82.7485), 2.0425),
    ((50.0, 3.1571, -77.2803), (50.0, 0.0, -82.7485), 2.8615),
    ((50.0, 2.8361, -74.0200), (50.0, 0.0, -82.7485), 3.4412),
    ((50.0, -1.3802, -84.2814), (50.0, 0.0, -82.7485), 1.0000),
    ((50.0, 0.0, 0.0), (50.0, -1.0, 2.0), 2.3669),
    ((50.0, 2.49, -0.001), (50.0, -2.49, 0.0011), 7.2195),
    ((50.0, 2.5, 0.0), (58.0, 24.0, 15.0), 19.4535),
    ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    ((22.7233, 20.0904, -46.6940), (23.0331, 14.9730, -42.5619), 2.0373),
]


def test_reference_matches_colour_science():
    lab1, lab2 = _pairs()
    ref = colour.delta_E(lab1, lab2, method="CIE 2000")
    assert np.abs(delta_e_2000(lab1, lab2) - ref).max() < 1e-8


@pytest.mark.parametrize("lab1,lab2,expected", SHARMA)
def test_reference_sharma_table(lab1, lab2, expected):
    assert delta_e_2000(np.array(lab1), np.array(lab2)) == pytest.approx(expected, abs=1e-4)


def test_float32_numpy_path_is_accurate():
    lab1, lab2 = _pairs()
    ref = colour.delta_E(lab1, lab2, method="CIE 2000")
    got = delta_e_2000_components(*lab1.T.astype(np.float32), *lab2.T.astype(np.float32))
    assert got.dtype == np.float32
    assert np.abs(got - ref).max() < 1e-3


def test_fast_kernel_matches_colour_science():
    lab1, lab2 = _pairs()
    ref = colour.delta_E(lab1, lab2, method="CIE 2000")
    out = np.empty(len(lab1), np.float32)
    de2000_lab(*(np.ascontiguousarray(x, dtype=np.float32) for x in (*lab1.T, *lab2.T)), out)
    assert np.abs(out - ref).max() < 1e-3
    assert np.abs(out - ref).mean() < 1e-5


def test_fast_mean_from_xyz_matches_colour_science():
    rng = np.random.default_rng(3)
    white = np.array([95.047, 100.0, 108.883])
    xyz_true = rng.uniform(0.2, 90.0, (60, 3))
    pred = xyz_true[None] * (1 + rng.normal(0, 0.03, (40, 60, 3)))
    pred[0, :4] = -0.5                       # negative predictions use the linear branch of CIELAB
    pred[1, :4] = 300.0                      # far too bright predictions still evaluate correctly
    lab_true = colour.XYZ_to_Lab(xyz_true / 100, colour.XYZ_to_xy(white / 100))
    ref = colour.delta_E(colour.XYZ_to_Lab(pred / 100, colour.XYZ_to_xy(white / 100)), lab_true[None],
                         method="CIE 2000").mean(axis=1)
    got = mean_de2000(pred, white, xyz_to_lab(xyz_true, white))
    assert np.abs(got - ref).max() < 1e-3


def test_eq_4_2_perfect_white_is_100_and_lab_matches_colour():
    s = default_setup()
    w = white_point(s.illuminant, s.cmfs)
    assert w[1] == pytest.approx(100.0)
    xyz = tristimulus(s.train.spectra, s.illuminant, s.cmfs)
    lab = xyz_to_lab(xyz, w)
    ref = colour.XYZ_to_Lab(xyz / 100, colour.XYZ_to_xy(w / 100))
    assert np.abs(lab - ref).max() < 1e-9
