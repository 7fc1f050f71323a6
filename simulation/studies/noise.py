"""Camera noise at the exposure each light needs, and the noise-aware objective.

Capture model (thesis 7 and 8; constants as the virtual lab's D610, drivers/virtual/camera.py):

* each light gets its own exposure, set so the brightest channel of the open gate reaches
  ``target_fraction`` (80 %) of the 11 000 DN linear limit (raw, black level 600 included);
* a patch's signal in that channel is then S = headroom * c / o_max (c: its response, o_max: the open gate's
  brightest channel response, headroom = 0.8 * 11 000 - 600 DN), the open gate's (flat) signal F likewise;
* per pixel: shot noise (S / gain DN^2 at ``electrons_per_dn`` e-/DN), read noise 2.5 DN, dark current shot
  noise (grows with the exposure time), the master dark (mean of ``dark_frames`` frames) subtracted,
  quantisation (1/12 DN^2); the value is flat-fielded (eq 7.1: (raw - dark) / (white - dark)) and averaged
  over ``pixels_per_patch`` pixels of the patch.

So the flat-fielded value of patch j, channel c is v = S / F with standard deviation
sqrt(var_S + v^2 var_F) / F / sqrt(pixels). Exposure *times* only matter through dark current; they come
from a radiometric scale calibrated like the virtual camera: the open gate under the full-intensity light
(1, 6, 8) reaches 10 500 DN at 1/60 s (thesis Table 7.1).

(The app's objective is the analytic :mod:`simulation.expected_error`; this Monte-Carlo one is the study's
check on it.) The noise-aware objective is the expected training dE00 of a capture: Monte-Carlo over ``draws`` fixed
standard-normal draws (common random numbers: every candidate sees the same draws, so the objective is a
smooth, deterministic function the optimisers can compare), the characterisation fitted on the *noisy*
training values and applied to them (as the thesis reports captured training errors). It is vectorised over
candidates and draws. :meth:`NoiseModel.simulate_capture` is the independent check: a pixel-level capture
(Poisson electrons, Gaussian read noise, rounding to integer DN, clipping at the linear limit, a simulated
master dark and white frame) with held-out seeds.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from dualrgb.simulation.camera_model import led_responses
from dualrgb.simulation.capture_model import CameraNoise
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.datasets import SimulationSetup, Target, target_xyz
from dualrgb.simulation.fast_de import mean_de2000_xyz
from dualrgb.simulation.hdr_estimators import HdrNoise, default_method, merge_exposures
from dualrgb.simulation.matrix_fit import solve_normal_equations

log = logging.getLogger(__name__)


@dataclass
class _PatchData:
    R: np.ndarray           # (K, n, 3) per-LED responses (raw units)
    xyz: np.ndarray
    lab: np.ndarray
    lab32: tuple[np.ndarray, np.ndarray, np.ndarray]


class NoiseModel:
    """Flat-fielded patch values of a light set with their noise, expected errors and simulated captures."""

    def __init__(self, setup: SimulationSetup, camera: CameraNoise = CameraNoise(),
                 train: Target | None = None, test: Target | None = None) -> None:
        self.setup = setup
        self.camera = camera
        self.white = target_xyz(setup, train or setup.train)[1]
        self.open = led_responses(setup.leds, np.ones((1, len(setup.grid))), setup.camera)[:, 0, :]   # (K, 3)
        self.n_leds = setup.leds.shape[0]
        self.data = {"train": self._patches(train or setup.train), "test": self._patches(test or setup.test)}
        ref = np.zeros(self.n_leds)
        ref[np.asarray(camera.reference_leds) - 1] = 1.0
        self.dn_per_unit_s = ((camera.reference_dn - camera.black_level)
                              / (camera.reference_exposure_s * float((ref @ self.open).max())))
        self._draws: dict = {}

    def _patches(self, target: Target) -> _PatchData:
        xyz = target_xyz(self.setup, target)[0]
        lab = xyz_to_lab(xyz, self.white)
        l32, a32, b32 = (np.ascontiguousarray(lab[:, i], dtype=np.float32) for i in range(3))
        return _PatchData(led_responses(self.setup.leds, target.spectra, self.setup.camera), xyz, lab, (l32, a32, b32))

    # ---- the capture of a light set -------------------------------------------------------------------
    def exposures(self, W: np.ndarray) -> np.ndarray:
        """Exposure time (s) each light needs: W (..., L, K) -> (..., L); inf for a dark light."""
        o_max = (np.asarray(W, dtype=float) @ self.open).max(axis=-1)
        with np.errstate(divide="ignore"):
            return self.camera.headroom / (self.dn_per_unit_s * o_max)

    def signals(self, W: np.ndarray, which: str = "train") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """DN above black of patches S (B, n, L, 3) and open gate F (B, L, 3), and exposures t (B, L)."""
        W = np.asarray(W, dtype=float)
        gate = W @ self.open                                                     # (B, L, 3)
        o_max = gate.max(axis=-1)                                                # (B, L)
        scale = np.divide(self.camera.headroom, o_max, out=np.zeros_like(o_max), where=o_max > 0)
        C = np.einsum("blk,knc->bnlc", W, self.data[which].R)
        S = C * scale[:, None, :, None]
        F = gate * scale[:, :, None]
        t = np.divide(self.camera.headroom, self.dn_per_unit_s * o_max, out=np.full_like(o_max, np.inf),
                      where=o_max > 0)
        return S, F, t

    def values(self, W: np.ndarray, which: str = "train") -> tuple[np.ndarray, np.ndarray]:
        """Flat-fielded values v and their standard deviation over the patch mean, both (B, n, 3L)."""
        cam = self.camera
        S, F, t = self.signals(W, which)
        dark_e = np.where(np.isfinite(t), t, 0.0) * cam.dark_current          # dark electrons per frame (B, L)
        dark = cam.read_noise**2 + dark_e / cam.electrons_per_dn**2          # DN^2 per frame
        base = dark * (1.0 + 1.0 / cam.dark_frames) + 1.0 / 12.0
        usable = F >= cam.min_flat_dn                                        # (B, L, 3)
        Fs = np.where(usable, F, 1.0)[:, None]
        v = np.where(usable[:, None], S / Fs, 0.0)
        var_s = S / cam.electrons_per_dn + base[:, None, :, None]
        var_f = (F[:, None] / cam.electrons_per_dn + base[:, None, :, None]) / cam.flat_frames
        std = np.where(usable[:, None], np.sqrt(var_s + v * v * var_f) / Fs, 0.0) / np.sqrt(cam.pixels_per_patch)
        B, n = v.shape[:2]
        return v.reshape(B, n, -1), std.reshape(B, n, -1)

    # ---- expected errors -------------------------------------------------------------------------------
    def draws(self, count: int, seed: int, n: int, channels: int, which: str) -> np.ndarray:
        key = (count, seed, n, channels, which)
        if key not in self._draws:
            self._draws[key] = np.random.default_rng([seed, n, channels, which == "test"]).standard_normal(
                (count, n, channels))
        return self._draws[key]

    def expected_errors(self, W: np.ndarray, draws: int = 16, seed: int = 0, *, test: bool = True,
                        exact: bool = False, chunk: int = 64) -> dict:
        """Expected mean dE00 of captures of each light set W (B, L, K): fit on the noisy training capture,
        errors of the training capture and (``test``) of an independent test capture. ``draws`` = 0 gives the
        noise-free errors through the same code. ``exact`` uses the float64 CIEDE2000 (else the fast kernel).
        Returns {"train": (B,), "test": (B,)} (means over draws) and per-draw arrays."""
        W = np.asarray(W, dtype=float)
        B = W.shape[0]
        out_tr = np.empty((B, max(draws, 1)))
        out_te = np.empty((B, max(draws, 1))) if test else None
        for lo in range(0, B, chunk):
            hi = min(B, lo + chunk)
            tr, te = self._expected_chunk(W[lo:hi], draws, seed, test, exact)
            out_tr[lo:hi] = tr
            if out_te is not None:
                out_te[lo:hi] = te
        res = {"train": out_tr.mean(axis=1), "train_draws": out_tr}
        if out_te is not None:
            res.update({"test": out_te.mean(axis=1), "test_draws": out_te})
        return res

    def _noisy(self, W: np.ndarray, which: str, draws: int, seed: int) -> np.ndarray:
        v, std = self.values(W, which)                                        # (b, n, ch)
        if draws == 0:
            return v[:, None]
        Z = self.draws(draws, seed, v.shape[1], v.shape[2], which)
        return v[:, None] + std[:, None] * Z[None]                            # (b, D, n, ch)

    def _mean_de(self, xyz_pred: np.ndarray, which: str, exact: bool) -> np.ndarray:
        """xyz_pred (P, n, 3) -> mean dE00 per row."""
        d = self.data[which]
        if exact:
            return delta_e_2000(d.lab, xyz_to_lab(xyz_pred, self.white)).mean(axis=-1)
        out = np.empty(xyz_pred.shape[0], dtype=np.float32)
        X, Y, Z = (np.ascontiguousarray(xyz_pred[..., i]) for i in range(3))
        mean_de2000_xyz(X, Y, Z, self.white, *d.lab32, out)
        return out.astype(float)

    def _expected_chunk(self, W: np.ndarray, draws: int, seed: int, test: bool, exact: bool):
        b = W.shape[0]
        Vtr = self._noisy(W, "train", draws, seed)                            # (b, D, n, ch)
        D, n, ch = Vtr.shape[1:]
        V = Vtr.reshape(b * D, n, ch)
        VT = V.transpose(0, 2, 1)
        A = solve_normal_equations(VT @ V, VT @ self.data["train"].xyz)                # (bD, ch, 3)
        tr = self._mean_de(V @ A, "train", exact).reshape(b, D)
        te = None
        if test:
            Vte = self._noisy(W, "test", draws, seed).reshape(b * D, -1, ch)
            te = self._mean_de(Vte @ A, "test", exact).reshape(b, D)
        return tr, te

    # ---- a pixel-level capture (held-out check) ----------------------------------------------------------
    def simulate_capture(self, W: np.ndarray, rng: np.random.Generator, which: str = "train", *,
                         factors: tuple[float, ...] = (1.0,), transmittance: np.ndarray | None = None,
                         hdr_method: str | None = None) -> np.ndarray:
        """Flat-fielded patch means (n, 3L) of one simulated capture of light set W (L, K), pixel by pixel.

        ``factors``: exposures relative to the open-gate exposure (several = an HDR bracket, merged as thesis
        8.2: master dark per exposure, then ``simulation.hdr_estimators.merge_exposures`` with ``hdr_method``
        (None: the parsimony study's default), frames at the linear limit unused); the white (open gate) frame
        is bracketed the same way. ``transmittance`` (n,): an ND filter over some patches (thesis 8.3).
        """
        cam = self.camera
        S, F, t = self.signals(np.asarray(W, dtype=float)[None], which)
        S, F, t = S[0], F[0], t[0]                                            # (n, L, 3), (L, 3), (L,)
        if transmittance is not None:
            S = S * np.asarray(transmittance, dtype=float)[:, None, None]
        n, L = S.shape[:2]
        shape = (n, L, 3, cam.pixels_per_patch)
        dark_e = (np.where(np.isfinite(t), t, 0.0) * cam.dark_current)[None, :, None, None]   # electrons
        method = hdr_method or default_method(self.setup.mode)
        noise = HdrNoise(cam.read_noise, cam.electrons_per_dn)

        def merged(signal_dn: np.ndarray) -> np.ndarray:
            x, usable = capture_bracket(cam, signal_dn, factors, rng, shape, dark_e)
            return merge_exposures(x, usable, factors, method, span=cam.max_code - cam.black_level, noise=noise)[0]

        raw = merged(S[..., None])
        white = np.mean([merged(F[None, :, :, None]) for _ in range(cam.flat_frames)], axis=0)
        usable = (F >= cam.min_flat_dn)[None, :, :, None]
        ratio = np.where(usable & (white > 0), raw / np.where(white > 0, white, 1.0), 0.0)
        return ratio.mean(axis=-1).reshape(n, L * 3)

    def captured_errors(self, W: np.ndarray, repeats: int = 10, seed: int = 12345, *,
                        factors: tuple[float, ...] = (1.0,), nd: dict[str, np.ndarray] | None = None,
                        models: tuple[str, ...] = (), hdr_method: str | None = None,
                        nd_in_truth: bool = True, folds: int = 0) -> dict:
        """Mean dE00 (float64) of ``repeats`` simulated captures of W (L, K): fit on the captured training
        target, errors of the captured training and test targets; seeds disjoint from the objective's.
        ``nd``: per target ('train', 'test') transmittance of an ND filter; ``models``: also fit these
        characterisation models (simulation.studies.models) and report their errors under 'models';
        ``hdr_method``: the HDR merge estimator (simulate_capture; None: the setup's mode's default);
        ``nd_in_truth`` False: the ground truth is the target without the filter (a uniformly dark original, judged
        after exposure normalisation: the fitted matrix absorbs the scale). ``folds`` > 0: also the
        ``folds``-fold cross-validated error on the captured *training* target ('train_cv', and 'cv' per model),
        the figure a default is chosen by (simulation.cross_validation); the test figures are only reported.
        Every figure comes with its standard deviation over the repeats ('*_sd') and the standard error of
        its mean ('*_se' = sd / sqrt(repeats))."""
        per: dict[str, list[float]] = {"train": [], "test": [], "train_cv": []}
        per_model: dict[str, dict[str, list[float]]] = {m: {"train": [], "test": [], "cv": []} for m in models}
        for r in range(repeats):
            rng = np.random.default_rng([seed, r])
            caps = {which: self.simulate_capture(W, rng, which, factors=factors,
                                                 transmittance=(nd or {}).get(which), hdr_method=hdr_method)
                    for which in ("train", "test")}
            truth = {which: self.data[which].xyz * (nd[which][:, None] if nd and nd_in_truth else 1.0)
                     for which in ("train", "test")}
            results = {m: self._fit_and_judge(m, caps, truth, folds) for m in dict.fromkeys(("linear", *models))}
            for k, v in zip(("train", "test", "train_cv"), ("train", "test", "cv"), strict=True):
                per[k].append(results["linear"][v])
            for m in models:
                for k in per_model[m]:
                    per_model[m][k].append(results[m][k])
        out: dict[str, Any] = {"repeats": repeats, **_summary(per, folds)}
        if models:
            out["models"] = {m: _summary(d, folds) for m, d in per_model.items()}
        return out

    def _fit_and_judge(self, model: str, caps: dict, truth: dict, folds: int) -> dict[str, float]:
        """One capture: the model fitted on the captured training target, mean dE00 of training and test, and
        (``folds``) the cross-validated mean on the training target. 'linear' is the least-squares matrix."""
        from dualrgb.simulation.cross_validation import cross_validated_errors
        from dualrgb.simulation.studies.models import fit_model, model_errors

        Vtr, Vte = caps["train"], caps["test"]
        fm = fit_model(model, Vtr, truth["train"], self.white)
        out = {"train": float(model_errors(fm, Vtr, truth["train"], self.white).mean()),
               "test": float(model_errors(fm, Vte, truth["test"], self.white).mean()), "cv": float("nan")}
        if folds:
            def score(keep: np.ndarray, held: np.ndarray) -> np.ndarray:
                f = fit_model(model, Vtr[keep], truth["train"][keep], self.white)
                return model_errors(f, Vtr[held], truth["train"][held], self.white)

            out["cv"] = float(cross_validated_errors(score, len(Vtr), folds).mean())
        return out


def _summary(per: dict[str, list[float]], folds: int) -> dict[str, float]:
    """Mean, standard deviation and standard error of the mean over repeats of each figure."""
    out: dict[str, float] = {}
    for k, v in per.items():
        if k in ("train_cv", "cv") and not folds:
            continue
        a = np.asarray(v, dtype=float)
        out[k] = float(a.mean())
        out[f"{k}_sd"] = float(a.std())
        out[f"{k}_se"] = float(a.std(ddof=1) / np.sqrt(a.size)) if a.size > 1 else float("nan")
    return out


def capture_bracket(cam: CameraNoise, signal_dn: np.ndarray, factors, rng: np.random.Generator, shape: tuple,
                    dark_e: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """One bracket of exposures, pixel by pixel: dark-subtracted signals x (K, *shape) and usable masks.

    Exposure f of ``factors``: Poisson electrons (``signal_dn`` * f DN of signal plus ``dark_e`` * f electrons of
    dark current), read noise, integer DN clipped at the linear limit (a value there is unusable); the master
    dark is the mean of ``cam.dark_frames`` such frames without signal, as processing subtracts it."""
    g = cam.electrons_per_dn

    def frame(sig: np.ndarray, f: float) -> np.ndarray:
        e = rng.poisson(np.broadcast_to(sig * f * g + np.asarray(dark_e) * f, shape))
        raw = np.round(cam.black_level + e / g + rng.normal(0.0, cam.read_noise, shape))
        return np.clip(raw, 0, min(cam.max_code, cam.linear_limit))

    xs, usable = [], []
    for f in factors:
        raw = frame(signal_dn, f)
        xs.append(raw - np.mean([frame(np.zeros(1), f) for _ in range(cam.dark_frames)], axis=0))
        usable.append(raw < cam.linear_limit)
    return np.stack(xs), np.stack(usable)


def dense(idx: np.ndarray, w: np.ndarray, n_leds: int) -> np.ndarray:
    """Indexed light sets (P, L, m) -> dense weights (P, L, K) (padding has weight 0)."""
    P, L, m = w.shape
    W = np.zeros((P, L, n_leds))
    np.add.at(W, (np.arange(P)[:, None, None], np.arange(L)[None, :, None], idx), w)
    return W


class NoiseAwareEvaluator:
    """The expected training dE00 under noise with the optimisers' interface (``cost_indexed``,
    ``evaluations``), so the core PSO runs on it unchanged."""

    def __init__(self, model: NoiseModel, draws: int = 16, seed: int = 0) -> None:
        self.model = model
        self.draws = draws
        self.seed = seed
        self.evaluations = 0
        self.n_leds = model.n_leds

    def cost_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        W = dense(np.asarray(idx), np.asarray(w, dtype=float), self.n_leds)
        self.evaluations += W.shape[0]
        return self.model.expected_errors(W, self.draws, self.seed, test=False)["train"]

    def cost(self, W: np.ndarray) -> np.ndarray:
        W = np.asarray(W, dtype=float)
        self.evaluations += W.shape[0]
        return self.model.expected_errors(W, self.draws, self.seed, test=False)["train"]


@lru_cache(maxsize=4)
def thesis_exposures_check(mode: str = "transmissive") -> list[dict]:
    """Exposures the model gives the four lights of thesis Table 7.1, beside the thesis's values."""
    from dualrgb.simulation.datasets import default_setup

    model = NoiseModel(default_setup(mode))
    rows = [((1, 6, 8), (1.0, 1.0, 1.0), 1 / 60), ((3, 5, 9), (1.0, 1.0, 1.0), 1 / 500),
            ((1, 6, 7), (0.07, 0.58, 1.0), 1 / 2), ((2, 4, 9), (0.12, 0.56, 1.0), 1 / 40)]
    out = []
    for leds, levels, thesis in rows:
        W = np.zeros((1, model.n_leds))
        W[0, np.asarray(leds) - 1] = levels
        out.append({"leds": list(leds), "levels": list(levels), "model_s": float(model.exposures(W)[0]),
                    "thesis_s": thesis})
    return out
