"""The delivery applies every calibration model per pixel: root-polynomial terms made in the encoder's row kernels
(app.processing.colour_kernels) give the XYZ of the model applied in float64 (simulation.colour_models, checked
against colour-science in tests/simulation/test_colour_models.py) within one 16-bit code, on the half-resolution
bands and on the full-resolution rows demosaiced as they are encoded."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb.app.processing.calibration import DarkFrame, FlatField, MasterDark
from dualrgb.app.processing.colour_kernels import (
    expand_row,
    expansion_scratch,
    root_polynomial_xyz_row,
    terms_for,
)
from dualrgb.app.processing.demosaic import HALO
from dualrgb.app.processing.encode import RGB_SPACES, XYZ_ONE, DeliveryEncoder, encode_deliverables
from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef
from dualrgb.simulation.colour_models import expand, n_terms
from dualrgb.simulation.matrix_fit import CharacterisationMatrix

D65 = [95.047, 100.0, 108.883]


def _model(degree: int, seed: int = 0) -> CharacterisationMatrix:
    rng = np.random.default_rng(seed)
    A = rng.normal(0.0, 8.0, (n_terms(6, degree), 3))
    A[:6] += 15.0                                               # a positive linear part, as a fitted model has
    return CharacterisationMatrix(A, [f"c{i}" for i in range(6)], f"root-polynomial-{degree}", degree)


@pytest.mark.parametrize("degree", [2, 3])
def test_the_row_expansion_is_the_float64_expansion(degree):
    rng = np.random.default_rng(degree)
    S = (rng.uniform(-0.05, 2.0, (6, 501)) * np.exp(rng.uniform(-12, 0, (6, 501)))).astype(np.float32)
    S[1, 7] = np.nan
    terms = terms_for(6, degree)
    _, roots, seed = expansion_scratch(terms, 6, 501)
    E = np.empty((len(terms), 501), np.float32)
    expand_row(S, terms, roots, seed, E)
    want = expand(np.nan_to_num(S.T.astype(np.float64)), degree).T
    assert E[1, 7] == 0.0 and np.isfinite(E).all()         # a NaN channel is 0, as the linear encoder takes it
    assert np.allclose(E, want, rtol=2e-6, atol=1e-30)


@pytest.mark.parametrize("degree", [2, 3])
def test_the_row_model_adds_the_terms_in_order_bit_for_bit(degree):
    """The kernel adds two terms per pass over the row: each pixel's X, Y, Z are still the float32 sums of the
    terms (expand_row, one at a time) times the matrix, in term order, bit for bit (numpy, one term at a time)."""
    rng = np.random.default_rng(20 + degree)
    S = rng.uniform(-0.05, 2.0, (6, 333)).astype(np.float32)
    S[4, 9] = np.nan
    terms = terms_for(6, degree)
    A = rng.normal(0.0, 20.0, (len(terms), 3)).astype(np.float32)
    ex = expansion_scratch(terms, 6, 333)
    E = np.empty((len(terms), 333), np.float32)
    expand_row(S, terms, ex[1], ex[2], E)
    want = np.zeros((3, 333), np.float32)
    for t in range(len(terms)):
        want = want + E[t] * A[t][:, None]
    got = np.empty((3, 333), np.float32)
    assert root_polynomial_xyz_row(S, terms, A, ex, got[0], got[1], got[2]) == 1
    assert np.array_equal(got, want)


@pytest.mark.parametrize("degree", [2, 3])
def test_delivered_xyz_is_the_model_per_pixel(degree):
    rng = np.random.default_rng(10 + degree)
    stack = rng.uniform(-0.02, 1.3, (23, 31, 6)).astype(np.float32)
    stack[rng.random((23, 31)) < 0.05, 4] = np.nan
    m = _model(degree)
    enc = encode_deliverables(stack, m.matrix, D65, degree=degree)
    clean = np.nan_to_num(stack.astype(np.float64))
    want = np.clip(np.round(m.apply(clean) / np.asarray(D65) * XYZ_ONE), 0, 65535)     # X / Xn, Y / Yn, Z / Zn
    assert np.abs(enc.xyz.astype(np.int64) - want).max() <= 1
    assert enc.invalid_fraction == pytest.approx(np.isnan(stack).any(axis=2).mean())
    linear = encode_deliverables(stack, m.matrix[:6], D65)          # the channel images do not depend on the model
    assert np.array_equal(enc.channels, linear.channels)
    with pytest.raises(ValueError, match=f"degree {degree}"):
        DeliveryEncoder(stack, m.matrix[:-1], D65, degree=degree)


def _master_stack():
    H, W, black, white = 21, 30, 600, 15520
    rng = np.random.default_rng(4)
    darks = MasterDark()
    darks.put(DarkFrame(0.01, np.full((H, W), black, np.float32), 10))
    proc = CaptureProcessor(darks=darks, white_level=white, black_level=black, cfa="RGGB")
    frames = {}
    for name in ("a", "b"):
        proc.put_white(name, FlatField(np.full((H, W), 1.5e5, np.float32)))
        rad = rng.uniform(1e4, 8e5, (H, W))
        frames[name] = np.clip(black + rad * 0.01 + rng.normal(0, 2, (H, W)), 0, white).astype(np.uint16)
    builder = proc.begin_master(list(frames))
    for name, m in frames.items():
        builder.add(name, ExposureRef(m, 0.01))
    return builder.result(threads=1), H, W


def test_full_resolution_rows_demosaiced_as_encoded_are_the_banded_path_for_a_root_polynomial():
    m = _model(3, seed=9)
    got = {}
    for fused in (True, False):
        stack, H, W = _master_stack()
        with stack, DeliveryEncoder((H, W, 6), m.matrix, D65, threads=1, degree=3) as enc:
            out = [np.empty((H, W, 3), np.uint16) for _ in range(5)]
            for r0 in range(0, H, 8):
                rows = min(8, H - r0)
                bands = (out[0][r0:r0 + rows], [o[r0:r0 + rows] for o in out[1:3]], [o[r0:r0 + rows] for o in out[3:]])
                if fused:
                    enc.encode_mosaic(r0, *bands, mosaic=stack.mosaic_band(r0, rows), p0=HALO, cfa=stack.cfa_index)
                else:
                    enc.encode(r0, *bands, band=np.ascontiguousarray(stack.band(r0, rows)))
            got[fused] = out
    assert all(np.array_equal(a, b) for a, b in zip(got[True], got[False], strict=True))
    assert got[True][0].any() and len(RGB_SPACES) == 2
