"""The search objective: mean CIEDE2000 on the training target of the characterisation fitted for a light set.

A *light set* is a weight array W (..., n_lights, n_leds): the level of every LED in every light (0 where an
LED is not used). Everything is precomputed at patch level, so one evaluation never touches spectra:
  per-LED responses R[k, j, c]  ->  camera values C = sum_k W[l, k] R[k, :, c]  (superposition)
  normal equations from Gram matrices G = R^T R, H = R^T XYZ  ->  A (rank-safe, batched)
  predictions XYZ' = R_flat @ M with M[k, c, :] = sum_l W[l, k] A[(l, c), :]  (one GEMM for the batch)
  mean dE00 by the fused float32 kernel (simulation.fast_de); reports use the float64 reference.
"""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from dataclasses import dataclass

import numba
import numpy as np

from dualrgb.simulation.camera_model import channel_names, channel_responses, led_responses, with_flare
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.datasets import SimulationSetup, Target, check_setup, target_xyz
from dualrgb.simulation.fast_de import mean_de2000_mapped
from dualrgb.simulation.fast_linalg import fit_light_sets
from dualrgb.simulation.matrix_fit import RIDGE, CharacterisationMatrix, _check_patches, fit_matrix

log = logging.getLogger(__name__)

# Below this many items a batch runs the numba kernels on one thread: starting and joining the second thread costs
# more than it gains (measured: a 7-point L-BFGS-B gradient batch 0.33 ms on one thread, 4.3 ms on two when the
# cores are busy), and successive halving's late rungs and the polish evaluate such small batches thousands of times.
SERIAL_BELOW = 1024


@contextlib.contextmanager
def kernel_threads(items: int) -> Iterator[None]:
    """Run the numba kernels inside on one thread for a small batch of ``items``, else on all."""
    if items >= SERIAL_BELOW or numba.get_num_threads() == 1:
        yield
        return
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


@dataclass(frozen=True)
class ErrorStats:
    mean: float
    median: float
    p90: float
    max: float

    @classmethod
    def of(cls, errors: np.ndarray) -> ErrorStats:
        e = np.asarray(errors, dtype=float)
        return cls(float(e.mean()), float(np.median(e)), float(np.percentile(e, 90)), float(e.max()))

    def to_dict(self) -> dict:
        return {"mean": self.mean, "median": self.median, "p90": self.p90, "max": self.max}


def check_kernel_batch(idx: np.ndarray, w: np.ndarray, n_leds: int) -> None:
    """The numba fit kernel reads G[idx] without bounds checks: refuse, with one line, any batch it was not
    written for (wrong rank or shapes, LED indices outside 0..n_leds-1, non-finite levels)."""
    if idx.ndim != 3 or idx.shape != w.shape or idx.shape[1] < 1 or idx.shape[2] < 1:
        raise ValueError(f"light-set batch: indices {idx.shape} and levels {w.shape} must both be (P, L, m)")
    if idx.size and (idx.min() < 0 or idx.max() >= n_leds):
        bad = int(idx.max() if idx.max() >= n_leds else idx.min()) + 1
        raise ValueError(f"light-set batch uses LED {bad}, but the LED spectra have {n_leds} LEDs (1..{n_leds})")
    if not np.isfinite(w).all():
        raise ValueError("light-set batch: levels must be finite numbers")


class PatchSet:
    """One target's patch-level data under one setup; ``reference``: the target whose spectra give the reference
    XYZ when they differ from what the camera sees (a robust world's measurement error), default ``target``."""

    def __init__(self, setup: SimulationSetup, target: Target, reference: Target | None = None):
        self.target = target
        self.xyz, self.white = target_xyz(setup, reference or target)    # eq 4.2 unless the setup says E308
        self.lab = xyz_to_lab(self.xyz, self.white)
        self.R = with_flare(led_responses(setup.leds, target.spectra, setup.camera), setup.flare)  # (K, n, 3)
        self._lab32 = [np.ascontiguousarray(self.lab[:, i], dtype=np.float32) for i in range(3)]

    def __len__(self) -> int:
        return self.xyz.shape[0]

    def camera_values(self, W: np.ndarray) -> np.ndarray:
        """(..., n_lights, K) -> (..., n, 3 * n_lights)."""
        C = np.einsum("...lk,knc->...nlc", W, self.R)
        return C.reshape(C.shape[:-2] + (-1,))


class Evaluator:
    """Fits on the training target and evaluates on training and test targets (noise-free: the thesis' cost).

    ``reference``: a setup whose targets give the reference XYZ (default ``setup``'s own)."""

    objective = "noise-free"

    def __init__(self, setup: SimulationSetup, reference: SimulationSetup | None = None):
        check_setup(setup)                       # shapes the kernels rely on, before anything is precomputed
        self.setup = setup
        ref = reference or setup
        self.train = PatchSet(setup, setup.train, ref.train)
        self.test = PatchSet(setup, setup.test, ref.test)
        scale = float(np.abs(self.train.R).max()) or 1.0
        self.scale = scale                       # per-LED responses are stored divided by this
        self.train.R = self.train.R / scale      # the fit is scale-free; keep numbers near 1
        self.test.R = self.test.R / scale
        K, n, _ = self.train.R.shape
        self.n_leds = K
        R_flat = self.train.R.transpose(1, 0, 2).reshape(n, K * 3)            # (n, K*3), column (k, c)
        self._R_flat = R_flat
        self._RT = np.ascontiguousarray(R_flat.T)
        self._G = (R_flat.T @ R_flat).reshape(K, 3, K, 3)
        self._H = (R_flat.T @ self.train.xyz).reshape(K, 3, 3)
        self.evaluations = 0

    # ---- batched path (optimisers) ----
    def fit_indexed(self, idx: np.ndarray, w: np.ndarray,
                    extra: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Batch characterisation: idx (P, L, m) 0-based LED indices, w (P, L, m) levels -> (M, A).

        ``extra`` (P, 3L): added to the normal equations' diagonal (None: plain least squares)."""
        idx = np.ascontiguousarray(idx, dtype=np.int64)
        w = np.ascontiguousarray(w, dtype=np.float64)
        check_kernel_batch(idx, w, self.n_leds)
        P, L, m = w.shape
        _check_patches(len(self.train), 3 * L)
        M = np.empty((3, self.n_leds * 3, P))
        A = np.empty((P, 3 * L, 3))
        extra = np.zeros((P, 3 * L)) if extra is None else np.ascontiguousarray(extra, dtype=np.float64)
        fit_light_sets(idx, w, self._G, self._H, RIDGE, M, A, extra)
        return M, A

    def cost_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Mean training dE00 for a batch given as LED indices and levels: the optimisers' objective.

        """
        with kernel_threads(len(w)):
            M, _ = self.fit_indexed(idx, w)
            out = np.empty(M.shape[2], dtype=np.float32)
            L1, a1, b1 = self.train._lab32
            if M.shape[:2] != (3, self._RT.shape[0]) or len(L1) != self._RT.shape[1]:   # the kernel indexes blindly
                raise ValueError(f"internal: maps {M.shape} do not fit responses {self._RT.shape} / {len(L1)} "
                                 "patches")
            mean_de2000_mapped(M, self._RT, self.train.white, L1, a1, b1, out)
        self.evaluations += M.shape[2]
        return out.astype(np.float64)

    def cost(self, W: np.ndarray) -> np.ndarray:
        """Mean training dE00 for dense light sets W (P, L, K) (every LED listed; zeros allowed)."""
        W = np.asarray(W, dtype=float)
        P, L, K = W.shape
        idx = np.broadcast_to(np.arange(K), (P, L, K))
        return self.cost_indexed(idx, W)

    # ---- exact path (reports) ----
    def characterise(self, W: np.ndarray) -> CharacterisationMatrix:
        W = np.asarray(W, dtype=float)
        return fit_matrix(self.train.camera_values(W), self.train.xyz, channel_names(W.shape[0]))

    def patch_errors(self, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-patch float64 dE00 (train, test) for one light set W (L, K)."""
        W = np.asarray(W, dtype=float)
        A = self.characterise(W)
        out = []
        for ps in (self.train, self.test):
            pred = A.apply(ps.camera_values(W))
            out.append(delta_e_2000(ps.lab, xyz_to_lab(pred, ps.white)))
        return out[0], out[1]

    def stats(self, W: np.ndarray) -> tuple[ErrorStats, ErrorStats]:
        tr, te = self.patch_errors(W)
        return ErrorStats.of(tr), ErrorStats.of(te)


def three_channel(setup: SimulationSetup) -> tuple[np.ndarray, np.ndarray, CharacterisationMatrix]:
    """The 3-channel baseline: the camera under D65 (thesis 5.4.2). Returns per-patch dE00 (train, test)."""
    train = PatchSet(setup, setup.train)
    test = PatchSet(setup, setup.test)
    C_train = channel_responses(setup.illuminant, setup.train.spectra, setup.camera)
    A = fit_matrix(C_train, train.xyz, channel_names(1))
    errs = []
    for ps, target in ((train, setup.train), (test, setup.test)):
        pred = A.apply(channel_responses(setup.illuminant, target.spectra, setup.camera))
        errs.append(delta_e_2000(ps.lab, xyz_to_lab(pred, ps.white)))
    return errs[0], errs[1], A
