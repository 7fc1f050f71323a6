"""Choosing lights for spectra: the expected captured spectral RMSE of a light set, batched over particles, and
the optimisers' objectives built on it (``spectral``, ``mixed``).

For light sets W (B, L, K) the flat-fielded values have sensitivities S = sum_k W_lk E_k / gate_l (E_k: LED k
times the camera's CSRF, per channel; gate: the open gate's response, eq 7.1), the Wiener estimate
(simulation.spectral_estimation) is M = K S (S^T K S + N)^-1 with K the prior and N the capture model's
noise of a training patch mean (its mean over the patches: simulation.capture_model, simulation.expected_error),
and the expected squared error of patch j, captured with noise n_j of variances sigma_jc^2, is

    E|M (v_j + n_j) - r_j|^2 = v_j^T (M^T M) v_j - 2 (r_j^T M) v_j + |r_j|^2 + sum_c sigma_jc^2 (M^T M)_cc,

v_j = S^T r_j. Every term comes from per-LED Gram matrices computed once (E_k^T K E_k', E_k^T K^2 E_k',
r_j^T K E_k, r_j^T E_k), so a batch never touches the wavelength axis. A patch's expected RMSE is the root of
that over n_wl, the error counted only where the target's reference was measured (a diagonal 0/1 weight P in the
norm: M^T P M, r_j^T P M, |P r_j|^2; the packaged CC24 ends at 730 nm, the training target is measured
throughout); the objective is its mean over the training patches (the clip to [0, 1] is left out: it only moves an
estimate towards a reference inside [0, 1]). The prior is chosen once per setup by 5-fold
cross-validation on the training target under the mode's packaged colour preset, then held fixed while the
lights move (choosing it per candidate would cost ~250 fits per evaluation).

Film (the modes whose estimates may be affine, simulation.spectral_selection.map_forms): the estimate is the affine
Wiener about the training mean mu, r = mu + M (v - S^T mu) with K the centred prior; its error M (S^T (r_j - mu) +
n_j) - (r_j - mu) is the linear case's with every spectrum centred, so the same algebra runs on centred spectra,
while the noise variances still come from the uncentred values (two more Gram matrices).

``mixed``: expected captured mean CIEDE2000 (the default objective) + ``spectral_weight`` x 100 x the expected
spectral RMSE: with the default weight 0.1, 1 % RMSE (0.01) costs as much as 0.1 dE00.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from dualrgb.simulation.camera_model import flat_fielded_sensitivities
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.choices import DEFAULT_SPECTRAL_WEIGHT
from dualrgb.simulation.datasets import SimulationSetup
from dualrgb.simulation.expected_error import ExpectedErrorEvaluator, ExpectedErrorModel, dense_weights
from dualrgb.simulation.matrix_fit import solve_normal_equations
from dualrgb.simulation.objective import ErrorStats, check_kernel_batch
from dualrgb.simulation.spectral_estimation import SpectralPrior, SpectralTraining, quantity_of
from dualrgb.simulation.spectral_selection import map_forms, select_estimator

log = logging.getLogger(__name__)

CHUNK = 2048                           # light sets per vectorised block (keeps the (B, n, 3L) blocks small)


def reference_prior(setup: SimulationSetup, model: ExpectedErrorModel) -> SpectralPrior:
    """The Wiener prior chosen by cross-validation on the training target under the mode's packaged colour
    preset (``resources/presets/<mode>_pso.json``) with this capture's noise; the default prior when there is
    no such preset."""
    from dualrgb import resources
    from dualrgb.simulation.presets import PresetError, load_preset

    try:
        preset = load_preset(resources.path("presets", f"{setup.mode}_pso.json"), setup.leds.shape[0])
    except (OSError, PresetError) as exc:
        log.info("no packaged %s preset to choose the spectral prior with (%s): default prior", setup.mode, exc)
        return SpectralPrior()
    W = model.emitted(np.stack([s.weights(setup.leds.shape[0]) for s in preset.sources]))
    lights = W @ setup.leds
    S = flat_fielded_sensitivities(lights, setup.camera)
    V = model.values(W[None], "train")
    noise = model.variances(V, model.noise_coefficients(W[None], "train"))[0].mean(axis=0)
    training = SpectralTraining(V[0], setup.train.spectra, setup.grid.wavelengths, sensitivities=S, noise_var=noise,
                                quantity=quantity_of(setup.mode))
    prior = select_estimator(training, ("wiener",)).chosen.prior
    return prior or SpectralPrior()


GRAMS = ("G1", "G2", "H1 train", "H1", "H2")    # the per-LED Gram matrices one batch contracts, in this order
RAW_GRAMS = ("H1 train raw", "H1 raw")          # ... and, for an affine estimate, the uncentred H1s (the noise)


@dataclass
class _TargetGrams:
    """One target's per-LED Gram matrices for the pooled error and its per-patch responses for the per-patch one."""

    n: int
    n_wl: int               # the wavelengths the error counts (where the reference was measured)
    G2: np.ndarray          # (K, K, 3, 3) E_k^T K P K E_j (P: where measured)
    H1: np.ndarray          # (K, K, 3, 3) E_k^T (R^T R) E_j
    H2: np.ndarray          # (K, K, 3, 3) E_k^T (R^T R) P K E_j
    rsum: np.ndarray        # (K, 3) (sum_j r_j)^T E_k, of the uncentred spectra (the noise's signal)
    rr: np.ndarray          # (n,) |P r_j|^2
    RE: np.ndarray          # (n, K, 3) r_j^T E_k
    RKE: np.ndarray         # (n, K, 3) r_j^T P K E_k
    H1raw: np.ndarray       # H1 of the uncentred spectra (the noise's sum of v^2; H1 itself without a centre)
    REraw: np.ndarray       # RE of the uncentred spectra (the noise's values)

    @classmethod
    def of(cls, R: np.ndarray, E: np.ndarray, KE: np.ndarray, mean: np.ndarray | None = None,
           measured: np.ndarray | None = None) -> _TargetGrams:
        """``R`` (n, n_wl) spectra; ``mean``: the centre of an affine estimate (the bias terms use R - mean);
        ``measured``: the wavelengths where the error counts (None: all)."""
        P = np.ones(R.shape[1]) if measured is None else np.asarray(measured, dtype=float)
        Rc = R if mean is None else R - mean
        RtRE = np.einsum("nw,nv,kvc->kwc", Rc, Rc, E, optimize=True)
        H1 = np.einsum("kwc,jwd->kjcd", E, RtRE)
        RE = np.einsum("nw,kwc->nkc", Rc, E)
        H1raw, REraw = (H1, RE) if mean is None else (
            np.einsum("kwc,jwd->kjcd", E, np.einsum("nw,nv,kvc->kwc", R, R, E, optimize=True)),
            np.einsum("nw,kwc->nkc", R, E))
        PKE = KE * P[None, :, None]
        return cls(len(R), int(P.sum()), np.einsum("kwc,jwd->kjcd", PKE, KE), H1,
                   np.einsum("kwc,jwd->kjcd", RtRE, PKE), np.einsum("w,kwc->kc", R.sum(axis=0), E),
                   np.sum(P * Rc * Rc, axis=1), RE, np.einsum("nw,kwc->nkc", Rc, PKE), H1raw, REraw)


class SpectralModel:
    """Expected captured spectral RMSE of light sets with the Wiener estimate (float64, batched; module
    docstring). ``model``: the expected-error model whose capture (noise, level grid) it uses.

    :meth:`pooled_rmse` (the objective) pools the squared errors of every patch and wavelength of a target: it
    contracts per-LED Gram matrices with the levels (two matrix products per batch), a few microseconds per
    light set. :meth:`patch_rmse` gives each patch's own expected RMSE (reports, tests)."""

    def __init__(self, setup: SimulationSetup, model: ExpectedErrorModel, prior: SpectralPrior | None = None):
        self.setup, self.model = setup, model
        self.prior = prior or reference_prior(setup, model)
        # film: the affine estimate about the training mean (module docstring), as the calibration may deliver
        self.affine = True in map_forms(quantity_of(setup.mode))
        mean = np.asarray(setup.train.spectra, dtype=float).mean(axis=0) if self.affine else None
        K = self.prior.matrix(setup.train.spectra - (0.0 if mean is None else mean), setup.grid.wavelengths)
        E = setup.leds[:, :, None] * setup.camera[None]                  # (K, n_wl, 3)
        self.open = E.sum(axis=1)                                       # (K, 3): each LED's open gate
        KE = np.einsum("wv,kvc->kwc", K, E)
        self.G1 = np.einsum("kwc,jwd->kjcd", E, KE)                      # E_k^T K E_j
        self.targets = {which: _TargetGrams.of(np.asarray(t.spectra, dtype=float), E, KE, mean,
                                               t.measured_mask(setup.grid.wavelengths))
                        for which, t in (("train", setup.train), ("test", setup.test))}
        tr = self.targets["train"]
        n_leds = len(E)
        self._names = GRAMS + (RAW_GRAMS if self.affine else ())
        # the grams the noise sums read: the uncentred H1s where the estimate is affine, else H1 itself
        self._noise_train, self._noise_target = (self._names.index(g + (" raw" if self.affine else ""))
                                                 for g in ("H1 train", "H1"))
        # stack[j, (k, g, c, d)] = Gram g [k, j, c, d]: one GEMM with the levels contracts all of the grams over j
        self._stacks = {which: np.ascontiguousarray(np.stack(
            [self.G1, t.G2, tr.H1, t.H1, t.H2] + ([tr.H1raw, t.H1raw] if self.affine else []), axis=2)
            .transpose(1, 0, 2, 3, 4).reshape(n_leds, -1)) for which, t in self.targets.items()}

    def _inverse_gate(self, W: np.ndarray) -> np.ndarray:
        """1 / the open gate's response per light and channel (B, 3L); 0 for a dark channel."""
        gate = (W @ self.open).reshape(W.shape[0], -1)
        return np.divide(1.0, gate, out=np.zeros_like(gate), where=gate > 0)

    def _grams(self, W: np.ndarray, inv: np.ndarray, which: str) -> np.ndarray:
        """S^T G S (B, 5 or 7, 3L, 3L) for each of :data:`GRAMS` (+ :data:`RAW_GRAMS` for an affine estimate; S:
        the flat-fielded values' sensitivities)."""
        B, L, K = W.shape
        g = len(self._names)
        T = (W.reshape(B * L, K) @ self._stacks[which]).reshape(B, L, K, -1)     # sum over j
        Y = np.einsum("blk,bmkx->blmx", W, T).reshape(B, L, L, g, 3, 3)                         # over k
        P = Y.transpose(0, 3, 1, 4, 2, 5).reshape(B, g, 3 * L, 3 * L)
        return P * inv[:, None, :, None] * inv[:, None, None, :]

    def _noise_sums(self, W: np.ndarray, inv: np.ndarray, which: str, h1: np.ndarray) -> np.ndarray:
        """Sum over the target's patches of each channel's noise variance (B, 3L): a0 n + a1 sum v + a2 sum v^2
        (``h1``: S^T H1 S of that target)."""
        t = self.targets[which]
        coef = self.model.noise_coefficients(W, which)                          # (3, B, 3L)
        vsum = (W @ t.rsum).reshape(W.shape[0], -1) * inv
        return coef[0] * t.n + coef[1] * vsum + coef[2] * np.einsum("bcc->bc", h1)

    def _estimator(self, W: np.ndarray, inv: np.ndarray, grams: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """X = (S^T K S + N)^-1 and M^T M = X^T S^T K^2 S X, both (B, 3L, 3L), N the training patches' mean
        noise."""
        P = grams[:, 0].copy()
        p = P.shape[1]
        P[:, np.arange(p), np.arange(p)] += (self._noise_sums(W, inv, "train", grams[:, self._noise_train])
                                             / self.targets["train"].n)
        X = solve_normal_equations(P, np.broadcast_to(np.eye(p), P.shape).copy())
        return X, X.transpose(0, 2, 1) @ grams[:, 1] @ X

    def pooled_rmse(self, W: np.ndarray, which: str = "train") -> np.ndarray:
        """Expected captured RMSE over every patch and wavelength of the target (B,): the objective."""
        W = np.asarray(W, dtype=float)
        return np.concatenate([self._pooled(W[lo:lo + CHUNK], which) for lo in range(0, len(W), CHUNK)])

    def _pooled(self, W: np.ndarray, which: str) -> np.ndarray:
        inv = self._inverse_gate(W)
        t = self.targets[which]
        grams = self._grams(W, inv, which)
        X, MtM = self._estimator(W, inv, grams)
        bias = (np.einsum("bcd,bdc->b", MtM, grams[:, 3]) - 2 * np.einsum("bcd,bdc->b", grams[:, 4], X)
                + t.rr.sum())
        noise = np.einsum("bc,bcc->b", self._noise_sums(W, inv, which, grams[:, self._noise_target]), MtM)
        return np.sqrt(np.maximum(bias + noise, 0.0) / (t.n * t.n_wl))

    def patch_rmse(self, W: np.ndarray, which: str = "train") -> np.ndarray:
        """Each patch's expected captured spectral RMSE (B, n) (float64; for reports and a few light sets)."""
        W = np.asarray(W, dtype=float)
        B = W.shape[0]
        inv = self._inverse_gate(W)
        t = self.targets[which]
        X, MtM = self._estimator(W, inv, self._grams(W, inv, which))
        V = np.einsum("blk,nkc->bnlc", W, t.RE).reshape(B, t.n, -1) * inv[:, None]          # v_j = S^T r_j
        RM = (np.einsum("blk,nkc->bnlc", W, t.RKE).reshape(B, t.n, -1) * inv[:, None]) @ X   # r_j^T M
        Vraw = V if not self.affine else np.einsum("blk,nkc->bnlc", W, t.REraw).reshape(B, t.n, -1) * inv[:, None]
        noise = self.model.variances(Vraw, self.model.noise_coefficients(W, which))         # (B, n, 3L)
        mse = (np.einsum("bnc,bcd,bnd->bn", V, MtM, V) - 2 * np.einsum("bnc,bnc->bn", RM, V) + t.rr[None]
               + np.einsum("bnc,bcc->bn", noise, MtM))
        return np.sqrt(np.maximum(mse, 0.0) / t.n_wl)


@dataclass(frozen=True)
class SpectralObjectiveSettings:
    """``prior``: the Wiener prior (None: :func:`reference_prior`); ``spectral_weight``: the mixed objective's
    weight of 100 x RMSE against mean dE00."""

    prior: SpectralPrior | None = None
    spectral_weight: float = DEFAULT_SPECTRAL_WEIGHT

    def __post_init__(self) -> None:
        if not (self.spectral_weight >= 0 and np.isfinite(self.spectral_weight)):
            raise ValueError(f"spectral weight {self.spectral_weight}: expected a finite number >= 0")


class SpectralEvaluator(ExpectedErrorEvaluator):
    """The optimisers' objective as the expected captured spectral RMSE of the training target (``spectral``)
    or mean dE00 + weight x 100 x that RMSE (``mixed``); levels realised on the sphere's grid first. Reports
    keep the noise-free and expected dE00 figures and add the spectral ones (:meth:`spectral_stats`)."""

    def __init__(self, setup: SimulationSetup, capture: CaptureModel | None = None,
                 settings: SpectralObjectiveSettings = SpectralObjectiveSettings(), mixed: bool = False) -> None:
        super().__init__(setup, capture)
        self.settings = settings
        self.objective = "mixed" if mixed else "spectral"
        self.spectral = SpectralModel(setup, self.model, settings.prior)

    def cost_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        idx = np.ascontiguousarray(idx, dtype=np.int64)
        w = self.realise(w)
        check_kernel_batch(idx, w, self.n_leds)
        rmse = self.spectral.pooled_rmse(dense_weights(idx, self.emitted_indexed(idx, w), self.n_leds), "train")
        if self.objective == "mixed":
            return super().cost_indexed(idx, w) + self.settings.spectral_weight * 100.0 * rmse
        self.evaluations += w.shape[0]
        return rmse

    def spectral_stats(self, W: np.ndarray) -> dict:
        """Float64 expected captured spectral figures of one light set W (L, K): per target ("train", "test")
        the pooled RMSE (the objective's figure) and the per-patch RMSE's mean / median / p90 / max."""
        W = self.model.emitted(np.asarray(W, dtype=float)[None])
        return {which: {"rmse": float(self.spectral.pooled_rmse(W, which)[0]),
                        "per_patch": ErrorStats.of(self.spectral.patch_rmse(W, which)[0]).to_dict()}
                for which in ("train", "test")}

    def objective_value(self, W: np.ndarray) -> float:
        """The float64 figure this objective minimises for one light set W (L, K) (reports sort by it)."""
        rmse = float(self.spectral.pooled_rmse(self.model.emitted(np.asarray(W, dtype=float)[None]), "train")[0])
        if self.objective == "mixed":
            return self.expected_stats(W)[0].mean + self.settings.spectral_weight * 100.0 * rmse
        return rmse
