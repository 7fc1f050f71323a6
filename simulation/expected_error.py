"""Expected captured error of a light set: the noise-free simulation plus what a capture adds, analytically.

The lab fits the characterisation on a *captured* training target and reports its mean CIEDE2000 on captures.
A capture differs from the simulation by (settings: :class:`simulation.capture_model.CaptureModel`):

* camera noise: each light's exposure puts the open gate's brightest channel at the sequence's target level;
  a patch's flat-fielded value v = S / F (eq 7.1) has variance
  sigma^2 = [v / (g F) + b / F^2 + v^2 (1 / (g F) + b / F^2) / n_flat] / n_px, with F the open gate's DN in that
  channel, g electrons per DN, b the per-pixel read + dark-current variance (master dark included), n_px the
  patch's pixel count (x 2 for G, x the trimmed mean's efficiency);
* the target reference's uncertainty (relative, as a gain on a patch's XYZ and per tristimulus value);
* the LEDs' peak drift between captures (first order in the shift, from the spectra's wavelength derivative);
* the sphere's levels (simulation.sphere, one model): a search's levels are realised (PWM steps, 0 or at least
  the minimum stable level) and a light already captured keeps its levels as set (``captured``); either way each
  LED then emits what its level curve says (measured on the stand, else proportional).

Propagation (first order, no Monte Carlo): noise in the regressors makes least squares behave like a ridge
fit, E[V^T V] = V0^T V0 + D with D = diag(sum_j sigma_j^2) (errors-in-variables attenuation; this is what keeps
a near-collinear light pair from "fitting" its noise), so the expected fit is A = (V0^T V0 + D)^-1 V0^T Y and
its noise-free prediction error b_j = V0_j A - Y_j gives m_j = dE00 (exact formula). Around it the training
prediction error of patch j has covariance
  S_j = sum_c sigma_jc^2 A_c A_c^T + Sigma_ref,j + sigma_d^2 sum_d e_j^(d) e_j^(d)T,
with e^(d) = (I - H) dV^(d) A the part of a drift direction d (one LED of one light) the fit cannot absorb (H:
the ridge fit's hat matrix). The fit's own absorption of the noise (a (1 - h_jj) factor, h_jj ~ 3L / n) is left
out: against the Monte Carlo it over-corrects slightly. CIEDE2000 is locally a quadratic form:
dE00^2 ~ dx^T Q_j dx with Q_j = J_j^T T_j J_j (J_j: XYZ -> Lab Jacobian, T_j: the dE00 metric at the reference
colour, by polarisation of the float64 formula). For a Gaussian x with E|x|^2 = m^2 + tr(QS) = E2 and
Var|x|^2 = 2 tr((QS)^2) + 4 b^T Q S Q b = V, E|x| ~ sqrt(E2) (1 - V / (8 E2^2)) (second order in the spread of
|x|^2; exact to < 1 % for a 3-D isotropic spread, 6 % for a 1-D one). A Monte Carlo over noisy captures agrees
within a few % (tests).

References: thesis chapters 5-7 (eqs 5.4, 7.1; Table 7.2 for the gap this closes); Fuller, *Measurement Error
Models* (1987), ch. 1-2 (attenuation of least squares by errors in the regressors); Sharma, Wu & Dalal (2005)
for CIEDE2000.
"""
from __future__ import annotations

import copy
import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from dualrgb.simulation.camera_model import led_responses, with_flare
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.datasets import SimulationSetup, Target, target_xyz
from dualrgb.simulation.fast_expected import mean_expected_de2000, prepare_expected
from dualrgb.simulation.matrix_fit import solve_normal_equations
from dualrgb.simulation.objective import ErrorStats, Evaluator, check_kernel_batch, kernel_threads
from dualrgb.simulation.pixel_error import PixelErrors, pixel_errors

log = logging.getLogger(__name__)

_DELTA = 6.0 / 29.0
PIXEL_SAMPLES = 512           # pixels drawn per patch for the per-pixel figures (p90 within ~0.02 dE00)


def lab_jacobian(xyz: np.ndarray, white: np.ndarray) -> np.ndarray:
    """d(L*, a*, b*) / d(X, Y, Z) at each row of ``xyz`` (n, 3) -> (n, 3, 3) (CIE 15 formulas)."""
    t = np.asarray(xyz, dtype=float) / white
    df = np.where(t > _DELTA**3, np.cbrt(np.maximum(t, _DELTA**3)) ** -2 / 3.0, 1.0 / (3 * _DELTA**2)) / white
    J = np.zeros(t.shape[:-1] + (3, 3))
    J[..., 0, 1] = 116 * df[..., 1]
    J[..., 1, 0] = 500 * df[..., 0]
    J[..., 1, 1] = -500 * df[..., 1]
    J[..., 2, 1] = 200 * df[..., 1]
    J[..., 2, 2] = -200 * df[..., 2]
    return J


def de2000_metric(lab: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """T (n, 3, 3) with dE00(lab, lab + d)^2 = d^T T d + O(|d|^3), by polarisation of the float64 formula."""
    lab = np.asarray(lab, dtype=float)
    E = np.eye(3)
    T = np.empty(lab.shape[:-1] + (3, 3))
    for a in range(3):
        for b in range(a, 3):
            plus = delta_e_2000(lab, lab + eps * (E[a] + E[b])) ** 2
            minus = delta_e_2000(lab, lab + eps * (E[a] - E[b])) ** 2
            T[..., a, b] = T[..., b, a] = (plus - minus) / (4 * eps**2)
    return T


def expected_norm(m2: np.ndarray, s: np.ndarray, var: np.ndarray) -> np.ndarray:
    """E|x| for a Gaussian x with E|x|^2 = m2 + s and Var|x|^2 = var (second-order expansion of the sqrt)."""
    e2 = m2 + s
    safe = np.where(e2 > 0, e2, 1.0)
    return np.where(e2 > 0, np.sqrt(safe) * (1.0 - var / (8.0 * safe * safe)), 0.0)


@dataclass
class TargetTerms:
    """One target's precomputed patch data: per-LED responses and their drift derivative, reference XYZ/Lab,
    the dE00 metric in XYZ and the reference covariance."""

    R: np.ndarray           # (K, n, 3) per-LED responses
    dR: np.ndarray          # (K, n, 3) d R / d (peak shift, nm)
    xyz: np.ndarray         # (n, 3)
    lab: np.ndarray         # (n, 3)
    Q: np.ndarray           # (n, 3, 3) dE00^2 ~ dx^T Q dx in XYZ
    ref_cov: np.ndarray     # (n, 3, 3) covariance of the reference XYZ
    pixels: float           # effective pixels per patch (R and B; G gets green_pixels x)

    def __len__(self) -> int:
        return self.xyz.shape[0]


@dataclass
class Expected:
    """Per-patch expected captured dE00 (B, n) and, for the same fit, the mean-prediction dE00 (B, n)."""

    expected: np.ndarray
    mean_prediction: np.ndarray

    @property
    def mean(self) -> np.ndarray:
        return self.expected.mean(axis=-1)


class ExpectedErrorModel:
    """The expected captured error of light sets W (B, L, K) under ``capture`` (float64 reference path)."""

    def __init__(self, setup: SimulationSetup, capture: CaptureModel | None = None,
                 reference: SimulationSetup | None = None) -> None:
        self.setup = setup
        self.reference = reference or setup         # whose target spectra give the reference XYZ
        self.capture = capture or CaptureModel()
        cam = self.capture.camera
        self.white = target_xyz(setup, setup.train)[1]
        self.n_leds = setup.leds.shape[0]
        self.open = led_responses(setup.leds, np.ones((1, len(setup.grid))), setup.camera)[:, 0, :]   # (K, 3)
        ref = np.zeros(self.n_leds)
        ref[np.asarray(cam.reference_leds) - 1] = 1.0
        self.dn_per_unit_s = ((cam.reference_dn - cam.black_level)
                              / (cam.reference_exposure_s * float((ref @ self.open).max())))
        # d S(lambda - shift) / d shift = -S'(lambda): the LED spectra's wavelength derivative
        self.dleds = -np.gradient(setup.leds, setup.grid.wavelengths, axis=1)
        self.terms = {"train": self._terms(setup.train, self.reference.train, "train"),
                      "test": self._terms(setup.test, self.reference.test, "test")}

    def _terms(self, target: Target, reference: Target, which: str) -> TargetTerms:
        s, c = self.setup, self.capture
        xyz = target_xyz(s, reference)[0]                # eq 4.2 unless the setup asks for ASTM E308
        lab = xyz_to_lab(xyz, self.white)
        J = lab_jacobian(xyz, self.white)
        Q = np.einsum("nab,nbc,ncd->nad", J.transpose(0, 2, 1), de2000_metric(lab), J)
        ref_cov = (c.reference_gain_sd**2 * np.einsum("na,nb->nab", xyz, xyz)
                   + c.reference_sd**2 * np.einsum("na,ab->nab", xyz**2, np.eye(3)))
        R = with_flare(led_responses(s.leds, target.spectra, s.camera), s.flare)      # the flare's part too
        dR = with_flare(led_responses(self.dleds, target.spectra, s.camera), s.flare)
        return TargetTerms(R, dR, xyz, lab, Q, ref_cov, c.pixels(which) * c.trim_efficiency)

    # ---- the capture of a light set ----------------------------------------------------------------------
    def realise(self, W: np.ndarray) -> np.ndarray:
        """Levels a search may set for W (PWM grid, 0 or at least the minimum stable level)."""
        return self.capture.sphere.realise(W)

    def emitted(self, W: np.ndarray, captured: bool = False) -> np.ndarray:
        """What the LEDs emit (relative to full output) for light sets W (..., L, K) of levels: the sphere's level
        model (simulation.sphere) on W realised for a search, or on W as set for lights already ``captured``.
        Every other method of this model takes these outputs."""
        W = np.asarray(W, dtype=float)
        return self.capture.sphere.emitted(W if captured else self.realise(W))

    def exposures(self, W: np.ndarray) -> np.ndarray:
        """Exposure time (s) of each light: W (..., L, K) -> (..., L); inf for a dark light."""
        o_max = (np.asarray(W, dtype=float) @ self.open).max(axis=-1)
        with np.errstate(divide="ignore"):
            return self.capture.camera.headroom / (self.dn_per_unit_s * o_max)

    def flat_dn(self, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Open gate per light and channel (B, L, 3) in relative units and in DN above black."""
        gate = np.asarray(W, dtype=float) @ self.open
        o_max = gate.max(axis=-1, keepdims=True)
        F = np.divide(self.capture.camera.headroom * gate, o_max, out=np.zeros_like(gate), where=o_max > 0)
        return gate, F

    def values(self, W: np.ndarray, which: str) -> np.ndarray:
        """Noise-free flat-fielded patch values V0 (B, n, 3L) = camera values / open gate, channel by channel."""
        gate, _ = self.flat_dn(W)
        C = np.einsum("blk,knc->bnlc", W, self.terms[which].R)
        V = np.divide(C, gate[:, None], out=np.zeros_like(C), where=gate[:, None] > 0)
        return V.reshape(V.shape[0], V.shape[1], -1)

    def noise_coefficients(self, W: np.ndarray, which: str) -> np.ndarray:
        """(a0, a1, a2) per light set and channel (3, B, 3L): sigma^2 = a0 + a1 v + a2 v^2 of a patch mean."""
        _, F = self.flat_dn(W)
        a = self.coefficients(F, self.exposures(W), which)
        return a.reshape(3, F.shape[0], -1)

    def coefficients(self, F: np.ndarray, t: np.ndarray, which: str) -> np.ndarray:
        """(a0, a1, a2) (3, ..., L, 3) from the open gate's DN F (..., L, 3) and the exposures t (..., L)."""
        cam = self.capture.camera
        dark_e = np.where(np.isfinite(t), t, 0.0) * cam.dark_current
        base = (cam.read_noise**2 + dark_e / cam.electrons_per_dn**2) * (1.0 + 1.0 / cam.dark_frames) + 1.0 / 12
        px = self.terms[which].pixels * np.array([1.0, self.capture.green_pixels, 1.0])      # (3,) per channel
        Fs = np.where(F > 0, F, np.inf)                                                    # a dark channel: no data
        a1 = 1.0 / (cam.electrons_per_dn * Fs * px)
        a0 = base[..., None] / (Fs * Fs * px)
        return np.stack([a0, a1, (a1 + a0) / cam.flat_frames])

    def variances(self, V: np.ndarray, coef: np.ndarray) -> np.ndarray:
        return coef[0][:, None] + coef[1][:, None] * V + coef[2][:, None] * V * V

    # ---- the expected fit and its errors -----------------------------------------------------------------
    def fit(self, W: np.ndarray) -> dict:
        """The expected (attenuated) fit on the captured training target and what its errors need."""
        tr = self.terms["train"]
        V = self.values(W, "train")
        s2 = self.variances(V, self.noise_coefficients(W, "train"))
        p = V.shape[2]
        Pr = np.einsum("bnc,bnd->bcd", V, V)
        Pr[:, np.arange(p), np.arange(p)] += s2.sum(axis=1)
        rhs = np.concatenate([np.einsum("bnc,na->bca", V, tr.xyz), np.broadcast_to(np.eye(p), Pr.shape)], axis=2)
        sol = solve_normal_equations(Pr, rhs)
        return {"V": V, "s2": s2, "A": sol[:, :, :3], "Pinv": sol[:, :, 3:]}

    def _drift_directions(self, W: np.ndarray, which: str) -> np.ndarray:
        """dV/d(shift) for every (light, LED): (B, L, K, n, 3L), zero where the LED is off."""
        gate, _ = self.flat_dn(W)
        dC = np.einsum("blk,knc->blknc", W, self.terms[which].dR)
        dC = np.divide(dC, gate[:, :, None, None, :], out=np.zeros_like(dC), where=gate[:, :, None, None, :] > 0)
        B, L, K, n, _ = dC.shape
        out = np.zeros((B, L, K, n, L, 3))
        for li in range(L):
            out[:, li, :, :, li, :] = dC[:, li]
        return out.reshape(B, L, K, n, 3 * L)

    def _spread(self, Sigma: np.ndarray, b: np.ndarray, terms: TargetTerms) -> tuple[np.ndarray, np.ndarray]:
        """(tr(QS), Var|x|^2) per patch for the prediction error covariance ``Sigma`` and bias ``b``."""
        QS = np.einsum("nab,Bnbc->Bnac", terms.Q, Sigma)
        s = np.einsum("Bnaa->Bn", QS)
        var = 2 * np.einsum("Bnab,Bnba->Bn", QS, QS) + 4 * np.einsum("Bna,Bnab,nbc,Bnc->Bn", b, QS, terms.Q, b)
        return s, var

    def train_errors(self, W: np.ndarray, fit: dict | None = None, *, pixel: bool = False) -> Expected:
        """Expected captured training dE00 per patch (fit and errors on the same captured target); W (B, L, K)
        the LEDs' outputs (:meth:`emitted`); ``pixel``: of one pixel of each patch (the fit still on the patch
        means), as a delivered image is judged."""
        pred, m, Sigma = self.train_distribution(W, fit, pixel=pixel)
        tr = self.terms["train"]
        s, var = self._spread(Sigma, pred - tr.xyz, tr)
        return Expected(expected_norm(m * m, s, var), m)

    def train_distribution(self, W: np.ndarray, fit: dict | None = None, *, pixel: bool = False
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The captured training prediction per patch: its mean XYZ (B, n, 3), that mean's dE00 (B, n) and the
        covariance of its error (B, n, 3, 3), of a patch mean or (``pixel``) of one pixel."""
        W = np.asarray(W, dtype=float)
        f = fit or self.fit(W)
        tr = self.terms["train"]
        V, s2, A, Pinv = f["V"], f["s2"], f["A"], f["Pinv"]
        pred = np.einsum("bnc,bca->bna", V, A)
        m = delta_e_2000(tr.lab, xyz_to_lab(pred, self.white))
        one = tr.pixels if pixel else 1.0             # a pixel's variance: the patch mean's times its pixels
        Sigma = np.einsum("bnc,bca,bcd->bnad", s2 * one, A, A) + tr.ref_cov
        if self.capture.drift_sd_nm > 0:
            dV = self._drift_directions(W, "train")                                      # (B, L, K, n, p)
            dVA = np.einsum("blknc,bca->blkna", dV, A)
            U = np.einsum("bcd,bnd,blkna->blkca", Pinv, V, dVA)                          # (V^T V + D)^-1 V^T dV A
            e = dVA - np.einsum("bnc,blkca->blkna", V, U)
            Sigma = Sigma + self.capture.drift_sd_nm**2 * np.einsum("blkna,blknd->bnad", e, e)
        return pred, m, Sigma

    def test_errors(self, W: np.ndarray, fit: dict | None = None, *, pixel: bool = False) -> Expected:
        """Expected captured test dE00 per patch: the test target captured on its own, the fit from the
        captured training target (its noise and drift reach the test predictions through the matrix); W (B, L, K)
        the LEDs' outputs (:meth:`emitted`); ``pixel``: of one pixel of each test patch."""
        pred, m, Sigma = self.test_distribution(W, fit, pixel=pixel)
        te = self.terms["test"]
        s, var = self._spread(Sigma, pred - te.xyz, te)
        return Expected(expected_norm(m * m, s, var), m)

    def test_distribution(self, W: np.ndarray, fit: dict | None = None, *, pixel: bool = False
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`train_distribution`, for the test target (:meth:`test_errors`)."""
        W = np.asarray(W, dtype=float)
        f = fit or self.fit(W)
        tr, te = self.terms["train"], self.terms["test"]
        V, s2, A, Pinv = f["V"], f["s2"], f["A"], f["Pinv"]
        Vt = self.values(W, "test")
        s2t = self.variances(Vt, self.noise_coefficients(W, "test")) * (te.pixels if pixel else 1.0)
        pred = np.einsum("bnc,bca->bna", Vt, A)
        m = delta_e_2000(te.lab, xyz_to_lab(pred, self.white))
        g = np.einsum("bnc,bcd->bnd", Vt, Pinv)                                  # (B, n_test, p)
        hx = np.einsum("bjc,bkc->bjk", g, V)                                      # (B, n_test, n_train)
        res = tr.xyz[None] - np.einsum("bnc,bca->bna", V, A)                      # training residuals
        # the test capture's own noise; the training capture's noise through the matrix (u = g_c r_k - hx_k A_c)
        Sigma = np.einsum("bnc,bca,bcd->bnad", s2t, A, A) + te.ref_cov
        Sigma = Sigma + np.einsum("bjk,bkc,bca,bcd->bjad", hx * hx, s2, A, A)
        Sigma = Sigma + np.einsum("bjc,bkc,bka,bkd->bjad", g * g, s2, res, res)
        cross = np.einsum("bjc,bjk,bkc,bka,bcd->bjad", g, hx, s2, res, A)
        Sigma = Sigma - cross - cross.transpose(0, 1, 3, 2)
        Sigma = Sigma + np.einsum("bjk,kad->bjad", hx * hx, tr.ref_cov)
        if self.capture.drift_sd_nm > 0:
            dVA_t = np.einsum("blknc,bca->blkna", self._drift_directions(W, "test"), A)   # the test capture's
            dVA = np.einsum("blknc,bca->blkna", self._drift_directions(W, "train"), A)
            U = np.einsum("bcd,bnd,blkna->blkca", Pinv, V, dVA)                          # the fit's
            f_ = np.einsum("bnc,blkca->blkna", Vt, U)
            Sigma = Sigma + self.capture.drift_sd_nm**2 * (np.einsum("blkna,blknd->bnad", dVA_t, dVA_t)
                                                          + np.einsum("blkna,blknd->bnad", f_, f_))
        return pred, m, Sigma

    def pixel_errors(self, W: np.ndarray, captured: bool = False, samples: int = PIXEL_SAMPLES,
                     seed: int = 0) -> dict[str, PixelErrors]:
        """Per-pixel dE00 of one light set W (L, K) of levels (as :meth:`expected`) on both targets: per patch the
        mean and 90th percentile over ``samples`` pixels drawn from the one-pixel prediction's Gaussian
        (:meth:`train_distribution`) through the exact CIEDE2000 (simulation.pixel_error)."""
        We = self.emitted(np.asarray(W, dtype=float)[None], captured)
        f = self.fit(We)
        rng = np.random.default_rng(seed)
        out = {}
        for which, dist in (("train", self.train_distribution), ("test", self.test_distribution)):
            pred, _, Sigma = dist(We, f, pixel=True)
            out[which] = sampled_pixel_errors(pred[0], Sigma[0], self.terms[which].xyz, self.white, rng, samples)
        return out

    def expected(self, W: np.ndarray, captured: bool = False) -> dict[str, np.ndarray]:
        """Mean expected captured dE00 of light sets W (B, L, K) of levels (realised for a search, as set when
        ``captured``: :meth:`emitted`): {"train": (B,), "test": (B,)}."""
        W = self.emitted(W, captured)
        f = self.fit(W)
        return {"train": self.train_errors(W, f).mean, "test": self.test_errors(W, f).mean}


def sampled_pixel_errors(pred: np.ndarray, Sigma: np.ndarray, xyz: np.ndarray, white: np.ndarray,
                         rng: np.random.Generator, samples: int = PIXEL_SAMPLES) -> PixelErrors:
    """Per patch, ``samples`` draws of N(pred, Sigma) (n, 3), (n, 3, 3) as the pixels of the patch whose reference
    is ``xyz``: their dE00's mean and 90th percentile (simulation.pixel_error.pixel_errors)."""
    # a symmetric square root (eigen): Sigma is positive semi-definite, possibly singular (no Cholesky)
    vals, vecs = np.linalg.eigh(Sigma)
    root = np.einsum("nab,nb,ncb->nac", vecs, np.sqrt(np.clip(vals, 0.0, None)), vecs)
    draws = pred[:, None, :] + np.einsum("nab,nkb->nka", root, rng.standard_normal((len(pred), samples, 3)))
    return pixel_errors(lambda x: x, list(draws), xyz, white)


def dense_weights(idx: np.ndarray, w: np.ndarray, n_leds: int) -> np.ndarray:
    """Indexed light sets (P, L, m) -> dense weights (P, L, K) (padding has weight 0)."""
    P, L, m = w.shape
    W = np.zeros((P, L, n_leds))
    np.add.at(W, (np.arange(P)[:, None, None], np.arange(L)[None, :, None], idx), w)
    return W


def _sym6(X: np.ndarray) -> np.ndarray:
    """(n, 3, 3) symmetric -> (6, n) float32 rows 00, 01, 02, 11, 12, 22 (the kernel's layout)."""
    i, j = np.triu_indices(3)
    return np.ascontiguousarray(X[:, i, j].T, dtype=np.float32)


class ExpectedErrorEvaluator(Evaluator):
    """The optimisers' objective (``cost_indexed``) as the expected captured training dE00, batched.

    Levels are realised on the sphere's grid first (:meth:`realise`), so a search never relies on a level the
    sphere cannot hold, and each LED emits what the sphere's level model says (:meth:`emitted_indexed`);
    :meth:`for_captured` scores lights already captured at their levels as set (a re-optimisation's
    incumbents). The float32 kernel (:mod:`simulation.fast_expected`) covers noise and reference uncertainty;
    with LED drift (``drift_sd_nm`` > 0) the float64 model is used (its projection of every drift direction costs
    ~20x more). Reports (:meth:`stats`) stay the noise-free float64 figures; the expected ones come from
    :meth:`expected_stats`.
    """

    objective = "expected-captured"

    def __init__(self, setup: SimulationSetup, capture: CaptureModel | None = None,
                 reference: SimulationSetup | None = None, *, per_pixel: bool = False) -> None:
        super().__init__(setup, reference)
        self.model = ExpectedErrorModel(setup, capture, reference)
        self.capture = self.model.capture
        tr = self.model.terms["train"]
        self.per_pixel = per_pixel
        if per_pixel:
            self.objective = "expected-per-pixel"
        self._spread_scale = float(tr.pixels) if per_pixel else 1.0    # a pixel's noise: the patch mean's x pixels
        self._open = self.model.open / self.scale                            # same units as the responses
        self._rsum = self.train.R.sum(axis=1)                                # (K, 3)
        self._gdiag = np.ascontiguousarray(np.einsum("acbc->abc", self._G))   # (K, K, 3): sum_j R_a,c R_b,c
        self._xyz32 = np.ascontiguousarray(tr.xyz.T, dtype=np.float32)
        self._q6 = _sym6(tr.Q)
        self._r6 = _sym6(tr.ref_cov)
        self._px = tr.pixels * np.array([1.0, self.capture.green_pixels, 1.0])

    def realise(self, w: np.ndarray) -> np.ndarray:
        """Levels a search may set (simulation.sphere.SphereProperties.realise)."""
        return self.capture.sphere.realise(w)

    def emitted_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The LEDs' outputs for an indexed batch (idx, w) (P, L, m) of levels (realised, then the level model)."""
        return self.capture.sphere.emitted(self.realise(w), idx)

    def for_captured(self) -> ExpectedErrorEvaluator:
        """This evaluator for lights already captured: their levels as the sphere set them, none forbidden (the
        same precomputed terms, shared; only the sphere's rule differs)."""
        twin = copy.copy(self)
        twin.capture = dataclasses.replace(self.capture, sphere=self.capture.sphere.as_captured())
        twin.model = copy.copy(self.model)
        twin.model.capture = twin.capture
        return twin

    def warm_up_kernels(self) -> float:
        """Compile or load this objective's kernels on a 4-particle batch (not counted); returns the seconds."""
        import time

        t0 = time.perf_counter()
        idx = np.zeros((4, 2, 3), dtype=np.int64)
        idx[:, 1] = 1
        self._fast(idx, np.ones((4, 2, 3)))
        return time.perf_counter() - t0

    def cost_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        idx = np.ascontiguousarray(idx, dtype=np.int64)
        w = self.emitted_indexed(idx, w)
        check_kernel_batch(idx, w, self.n_leds)          # prepare_expected indexes the LED tables blindly
        self.evaluations += w.shape[0]
        if self.capture.drift_sd_nm > 0:
            W = dense_weights(idx, w, self.n_leds)
            return np.concatenate([self.model.train_errors(W[lo:lo + 64], pixel=self.per_pixel).mean
                                   for lo in range(0, len(W), 64)])
        with kernel_threads(len(w)):
            return self._fast(idx, w)

    def _fast(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        P, L, m = w.shape
        cam = self.capture.camera
        D = np.empty((P, 3 * L))
        coef = np.empty((3, 3 * L, P))
        Cm = np.zeros((3 * L, 3 * self.n_leds, P))
        noise = np.array([cam.read_noise, cam.electrons_per_dn, cam.dark_current, cam.dark_frames, cam.flat_frames],
                         dtype=float)
        prepare_expected(idx, w, self._open, self._rsum, self._gdiag, float(len(self.train)), cam.headroom,
                         self.model.dn_per_unit_s * self.scale, noise, self._px, D, coef, Cm)
        M, A = self.fit_indexed(idx, w, extra=D)
        out = np.empty(P, dtype=np.float32)
        L1, a1, b1 = self.train._lab32
        mean_expected_de2000(M, Cm, np.ascontiguousarray(A.transpose(1, 2, 0)), coef, self._RT, self.train.white,
                             L1, a1, b1, self._xyz32, self._q6, self._r6, self._spread_scale, out)
        return out.astype(np.float64)

    def stats(self, W: np.ndarray) -> tuple[ErrorStats, ErrorStats]:
        """Float64 noise-free statistics (train, test) of one light set W (L, K) of levels, on what the LEDs emit."""
        return super().stats(self.model.emitted(np.asarray(W, dtype=float)))

    def pixel_stats(self, W: np.ndarray) -> dict:
        """Per-pixel dE00 of one light set W (L, K) of levels: {"train", "test"} (ExpectedErrorModel.pixel_errors,
        a Monte Carlo over one-pixel predictions: mean and p90) and "expected_train_mean" (the per-pixel objective's
        float64 figure)."""
        W = np.asarray(W, dtype=float)
        px = self.model.pixel_errors(W)
        We = self.model.emitted(W[None])
        return {"train": px["train"].to_dict(), "test": px["test"].to_dict(),
                "expected_train_mean": float(self.model.train_errors(We, pixel=True).mean[0])}

    def expected_stats(self, W: np.ndarray) -> tuple[ErrorStats, ErrorStats]:
        """Float64 expected captured per-patch statistics (train, test) of one light set W (L, K)."""
        W = self.model.emitted(np.asarray(W, dtype=float)[None])
        f = self.model.fit(W)
        return (ErrorStats.of(self.model.train_errors(W, f).expected[0]),
                ErrorStats.of(self.model.test_errors(W, f).expected[0]))
