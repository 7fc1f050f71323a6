"""The stand model fitted to a calibration's captures: a few physical parameters, regularised, with uncertainties.

A calibration captures the open gate (flats), the training and the test target under every light. Their
dark-subtracted patch means, per second and at the frame's centre (flat-fielded values times the open gate's
level there, so vignetting is out), are what the model must predict (:class:`StandObservations`). The model
(:class:`simulation.stand_model.StandModel`) predicts them with the optimiser's own camera model, eq 5.10
(simulation/camera_model.py), on LED spectra perturbed by :func:`simulation.led_shapes.shaped_led_spectra`:

    white_lc   = k g_c (1 + f) sum_lambda E_l(lambda) S_c(lambda)
    patch_jlc  = k g_c sum_lambda E_l(lambda) R_j(lambda) S_c(lambda) + f / (1 + f) F_lc

with E_l = sum_i e_i(w_li) o_i LED_i(lambda; shift_i) the light's spectrum (e_i: what LED i emits at its level
w_li as set, relative to full output - the sphere's one level model, :meth:`simulation.sphere.SphereProperties.emitted`:
its measured level -> output curve from a stand folder, else proportional), S_c the camera's curve (optionally shifted
and stretched about its peak), g_c the channel's gain, f the veiling flare and F_lc the captured frame's mean
(the flare adds f times the frame's true mean, which the capture shows times 1 + f). ``k`` converts relative
units to DN per second as the virtual lab and the expected-captured objective do: the unperturbed model's open gate
under the reference light (1, 6, 8) gives ``CameraNoise.reference_dn`` at 1/60 s (times the ISO / aperture factor).

Parameters (:data:`PARAMETERS`): per LED on in any light, its output scale and peak shift; per channel its gain;
the flare; with ``camera_shape`` (default: when the camera is not measured) each channel curve's shift and width.
Each has a Gaussian prior centred on the starting model (nominal, or measured) with a stated width
(:class:`Priors`) and physical bounds; a parameter that ends on a bound is reported in one line. The fit uses the
training target and the flats only; the test target checks it.

Least squares (scipy ``least_squares``, trust region reflective) on relative residuals
``(model - data) / sqrt(noise^2 + (model_error data)^2)`` plus the prior terms. Uncertainties from the Jacobian
at the optimum: ``cov = (J_d^T J_d / s^2 + J_p^T J_p)^-1`` with ``s^2`` the data's reduced chi-square (at least
1), i.e. the usual ``(J^T J)^-1 sigma^2`` with the data's scatter taken from the fit itself and the priors as stated.

Identifiability (a fit's R^2 does not certify its parameters: several trade off against each other). For each
parameter the posterior against the prior sd (``sd_ratio``: below :data:`DETERMINED_RATIO` the captures determine
it, at or above :data:`PRIOR_RATIO` = 1/sqrt 2 the captures carry less than half of what is known about it, so it is
determined mainly by its prior) and how far it moved in prior sd (``moved_sd``); every pair of parameters whose
posterior correlation reaches :data:`CORRELATION_LIMIT` in magnitude; and the combinations of parameters the
captures leave to the priors (``weak_directions``: eigenvectors of the posterior covariance in prior-sd units whose
sd stays at or above :data:`PRIOR_RATIO` of the prior's - e.g. every LED output up and every channel gain down
together, which changes no prediction). One warning line per parameter that moved more than :data:`MOVED_LIMIT`
prior sd or is determined mainly by its prior.

References
----------
Thesis chapter 7 (Fig 7.4, Table 7.2: captured digital numbers against the simulation), eq 5.10, 4.3 (LED peaks and
output); Nocedal & Wright, *Numerical Optimization* (2006), ch. 10 (nonlinear least squares, Gauss-Newton
covariance).
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dualrgb.simulation.camera_model import CHANNELS, led_responses
from dualrgb.simulation.capture_model import CameraNoise, CaptureModel
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid
from dualrgb.simulation.stand_model import StandModel, StandParameters

log = logging.getLogger(__name__)

REFERENCE_LEDS = (1, 6, 8)          # Table 7.1's reference light (the virtual camera's scale)


@dataclass(frozen=True)
class Priors:
    """Prior widths (one standard deviation) around the starting model, and the model's relative error floor."""

    led_output_sd: float = 0.15          # LED binning and ageing: tens of % (the aged-leds world: 0.85-1)
    led_shift_sd_nm: float = 5.0         # binning +-5 nm; warm-up drift a few nm (thesis 4.3.2)
    gain_sd: float = 0.5                 # the camera's absolute scale is not known before the fit
    camera_shift_sd_nm: float = 5.0      # another body's curves: peaks a few nm apart
    camera_width_sd: float = 0.1
    flare_sd: float = 0.02               # lens and stand glare: fractions of a percent to a few %
    model_error: float = 0.003           # relative sd a patch mean may miss by beyond its noise

    def to_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


# StandParameters field -> (prior width attribute of Priors, lower bound, upper bound, label)
PARAMETERS: dict[str, tuple[str, float, float, str]] = {
    "led_output_scale": ("led_output_sd", 0.0, 2.0, "LED {n} output"),
    "led_peak_shift_nm": ("led_shift_sd_nm", -20.0, 20.0, "LED {n} peak shift (nm)"),
    "channel_gain": ("gain_sd", 0.1, 10.0, "gain {c}"),
    "camera_shift_nm": ("camera_shift_sd_nm", -20.0, 20.0, "camera {c} shift (nm)"),
    "camera_width_scale": ("camera_width_sd", 0.5, 2.0, "camera {c} width"),
    "flare": ("flare_sd", -0.02, 0.2, "flare"),      # a little below 0 absorbs a dark offset; glare itself is >= 0
}
CAMERA_SHAPE = ("camera_shift_nm", "camera_width_scale")


@dataclass
class StandObservations:
    """A calibration's captures, reduced (module docstring): DN per second above black at the frame's centre.

    ``levels`` (L, n_leds) each light's LED levels as emitted; ``white`` (L, 3) the open gate; ``train`` (n, L, 3)
    the training patches; ``train_frame`` (L, 3) the training frame's mean; ``train_sd`` (n, L, 3) the standard
    error of each patch mean (optional); the same for the test target (optional); the targets' spectra on
    ``grid``; ``dn_scale`` the ISO / aperture factor against ISO 50, f/8."""

    levels: np.ndarray
    white: np.ndarray
    train: np.ndarray
    train_spectra: np.ndarray
    train_frame: np.ndarray
    train_sd: np.ndarray | None = None
    test: np.ndarray | None = None
    test_spectra: np.ndarray | None = None
    test_frame: np.ndarray | None = None
    grid: SpectralGrid = DEFAULT_GRID
    dn_scale: float = 1.0

    def __post_init__(self) -> None:
        L = np.asarray(self.levels).shape[0]
        n = np.asarray(self.train).shape[0]
        checks = {"white": (self.white, (L, 3)), "train": (self.train, (n, L, 3)),
                  "train_frame": (self.train_frame, (L, 3)),
                  "train_spectra": (self.train_spectra, (n, len(self.grid)))}
        for name, (arr, shape) in checks.items():
            if np.asarray(arr).shape != shape:
                raise ValueError(f"stand observations: {name} has shape {np.asarray(arr).shape}, expected {shape}")
        if not np.all(np.asarray(self.white) > 0):
            raise ValueError("stand observations: the open gate is dark in a channel (no flat signal to fit)")


@dataclass
class FittedParameter:
    key: str                 # "<StandParameters field>[<index>]" or "flare"
    label: str
    value: float
    sd: float
    prior: float
    prior_sd: float
    bounds: tuple[float, float]
    at_bound: str = ""       # "lower" / "upper" when the fit ended on a bound

    @property
    def sd_ratio(self) -> float:
        """Posterior over prior standard deviation (module docstring: identifiability)."""
        return self.sd / self.prior_sd

    @property
    def moved_sd(self) -> float:
        """How far the fit moved it from the starting model, in prior standard deviations (signed)."""
        return (self.value - self.prior) / self.prior_sd

    @property
    def determined_by(self) -> str:
        """'captures', 'partly' or 'prior' (module docstring: identifiability)."""
        r = self.sd_ratio
        return "captures" if r < DETERMINED_RATIO else "prior" if r >= PRIOR_RATIO else "partly"

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "label": self.label, "value": self.value, "sd": self.sd, "prior": self.prior,
                "prior_sd": self.prior_sd, "bounds": list(self.bounds), "at_bound": self.at_bound or None,
                "sd_ratio": self.sd_ratio, "moved_sd": self.moved_sd, "determined_by": self.determined_by}


@dataclass
class Prediction:
    """What a model predicts for the observations: white (L, 3), train (n, L, 3), test (m, L, 3) or None."""

    white: np.ndarray
    train: np.ndarray
    test: np.ndarray | None


@dataclass
class StandFit:
    """The fitted model (``model``), where it started (``start``: nominal, or with measurements), the parameters,
    warnings and both models' predictions with their R^2 per channel (``r2["start" | "fitted"][target]``: 1 - SS_res
    / SS_tot against the captured values, no line refitted; channel order R1, G1, B1, R2, ...)."""

    model: StandModel
    start: StandModel
    parameters: list[FittedParameter]
    warnings: list[str]
    chi2_scale: float
    evaluations: int
    start_prediction: Prediction
    fitted: Prediction
    r2: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    priors: Priors = field(default_factory=Priors)
    correlations: list[dict[str, Any]] = field(default_factory=list)    # {"a", "b": labels, "r"}, |r| descending
    weak_directions: list[dict[str, Any]] = field(default_factory=list)  # {"sd_ratio", "combination": [[label, w]]}

    def min_r2(self, which: str = "fitted", target: str = "train") -> float:
        values = self.r2.get(which, {}).get(target) or [float("nan")]
        return float(min(values))

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model.to_dict(), "start": self.start.to_dict(),
                "parameters": [p.to_dict() for p in self.parameters], "warnings": list(self.warnings),
                "chi2_scale": self.chi2_scale, "evaluations": self.evaluations, "priors": self.priors.to_dict(),
                "r2": self.r2, "correlations": self.correlations, "weak_directions": self.weak_directions,
                "identifiability": {"determined_ratio": DETERMINED_RATIO, "prior_ratio": PRIOR_RATIO,
                                    "moved_limit": MOVED_LIMIT, "correlation_limit": CORRELATION_LIMIT}}


# ---- the forward model ----------------------------------------------------------------------------------------
def dn_per_unit_s(model: StandModel, grid: SpectralGrid = DEFAULT_GRID, camera: CameraNoise | None = None) -> float:
    """DN per second per relative unit: the unperturbed model's open gate under the reference light (1, 6, 8)
    reaches ``camera.reference_dn`` above black in its brightest channel at ``camera.reference_exposure_s``."""
    cam = camera or CameraNoise()
    levels = np.zeros(model.led_table()[1].shape[0])
    levels[np.asarray(REFERENCE_LEDS) - 1] = 1.0
    gate = levels @ led_responses(model.leds(grid, unperturbed=True), np.ones((1, len(grid))),
                                  model.camera(grid, unperturbed=True))[:, 0]
    return (cam.reference_dn - cam.black_level) / (cam.reference_exposure_s * float(gate.max()))


def predict(model: StandModel, obs: StandObservations, k: float | None = None) -> Prediction:
    """The DN per second ``model`` predicts for the observations (module docstring); ``k``: dn_per_unit_s."""
    grid = obs.grid
    k = obs.dn_scale * (dn_per_unit_s(model, grid) if k is None else k)
    leds, cam, f = model.leds(grid), model.camera(grid), model.params.flare
    levels = model.emitted(np.asarray(obs.levels, dtype=float))        # what the LEDs emitted at the levels set
    white = k * (1.0 + f) * (levels @ led_responses(leds, np.ones((1, len(grid))), cam)[:, 0])

    def patches(spectra: np.ndarray, frame: np.ndarray) -> np.ndarray:
        P = np.einsum("lk,knc->nlc", levels, led_responses(leds, spectra, cam))
        return k * P + f / (1.0 + f) * np.asarray(frame, dtype=float)[None]
    test = None
    if obs.test_spectra is not None and obs.test_frame is not None:
        test = patches(obs.test_spectra, obs.test_frame)
    return Prediction(white, patches(obs.train_spectra, obs.train_frame), test)


def r2_per_channel(predicted: np.ndarray, captured: np.ndarray) -> list[float]:
    """1 - SS_res / SS_tot per channel (columns of the (n, L, 3) arrays flattened light-major): how much of the
    captured values' spread the prediction explains, with no line refitted (a gain or an offset error counts)."""
    p = np.asarray(predicted, dtype=float).reshape(len(predicted), -1)
    y = np.asarray(captured, dtype=float).reshape(len(captured), -1)
    ss_tot = ((y - y.mean(axis=0)) ** 2).sum(axis=0)
    ss_res = ((y - p) ** 2).sum(axis=0)
    return [float(v) for v in 1.0 - ss_res / np.where(ss_tot > 0, ss_tot, np.nan)]


# ---- the parameter vector -----------------------------------------------------------------------------------
@dataclass
class _Vector:
    """Which parameters are free (``keys``: (field, index or None)), their priors and bounds."""

    keys: list[tuple[str, int | None]]
    prior: np.ndarray
    prior_sd: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    labels: list[str]

    def params(self, base: StandParameters, x: np.ndarray) -> StandParameters:
        changes: dict[str, Any] = {}
        for (name, i), v in zip(self.keys, x, strict=True):
            if i is None:
                changes[name] = float(v)
            else:
                cur = list(changes.get(name, getattr(base, name)))
                cur[i] = float(v)
                changes[name] = tuple(cur)
        return dataclasses.replace(base, **changes)


def _vector(start: StandParameters, used_leds: np.ndarray, priors: Priors, camera_shape: bool) -> _Vector:
    keys: list[tuple[str, int | None]] = []
    labels: list[str] = []
    for name in PARAMETERS:
        if name in CAMERA_SHAPE and not camera_shape:
            continue
        label = PARAMETERS[name][3]
        if name.startswith("led_"):
            idx: list[int | None] = [int(i) for i in used_leds]
        elif name == "flare":
            idx = [None]
        else:
            idx = [0, 1, 2]
        for i in idx:
            keys.append((name, i))
            labels.append(label.format(n=(i or 0) + 1, c=CHANNELS[(i or 0) % len(CHANNELS)]))
    prior = np.array([getattr(start, n) if i is None else getattr(start, n)[i] for n, i in keys], dtype=float)
    spec = [PARAMETERS[n] for n, _ in keys]
    lo, hi = np.array([s[1] for s in spec]), np.array([s[2] for s in spec])
    return _Vector(keys, prior, np.array([getattr(priors, s[0]) for s in spec]), lo, hi, labels)


DARK_FLOOR = 0.01           # a patch's relative error is taken on at least this fraction of the open gate
DETERMINED_RATIO = 0.5      # posterior sd below half the prior's: the captures determine the parameter
PRIOR_RATIO = 2 ** -0.5     # posterior variance at least half the prior's: determined mainly by its prior
MOVED_LIMIT = 3.0           # moved more than this many prior sd from the starting model: warned
CORRELATION_LIMIT = 0.9     # |posterior correlation| reported from here


def _data_sigma(obs: StandObservations, priors: Priors) -> tuple[np.ndarray, np.ndarray]:
    """Residual scales of the open gate (L, 3) and the training patches (n, L, 3) (module docstring)."""
    white = np.asarray(obs.white, dtype=float)
    level = np.maximum(np.abs(np.asarray(obs.train, dtype=float)), DARK_FLOOR * white[None])
    noise = 0.0 if obs.train_sd is None else np.asarray(obs.train_sd, dtype=float)
    return priors.model_error * white, np.sqrt(noise ** 2 + (priors.model_error * level) ** 2)


def _bound_warnings(vec: _Vector, x: np.ndarray) -> tuple[list[str], list[str]]:
    """Per parameter '', 'lower' or 'upper' (ended on that bound), and one line for each that did."""
    where, lines = [], []
    for label, v, lo, hi in zip(vec.labels, x, vec.lo, vec.hi, strict=True):
        tol = 1e-6 * (hi - lo)
        side = "lower" if v <= lo + tol else "upper" if v >= hi - tol else ""
        where.append(side)
        if side:
            lines.append(f"stand fit: {label} = {v:.4g} is at its {side} bound {lo if side == 'lower' else hi:g}: "
                         "the model cannot follow the captures there (a measured curve may be needed)")
    return where, lines


def _fitted(vec: _Vector, x: np.ndarray, cov: np.ndarray, where: list[str]) -> list[FittedParameter]:
    """The fitted parameters with their standard uncertainties (the covariance's diagonal) and bound sides."""
    sds = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return [FittedParameter(f"{n}[{i}]" if i is not None else n, lab, float(v), float(s), float(p), float(w),
                            (float(lo), float(hi)), side)
            for (n, i), lab, v, s, p, w, lo, hi, side in zip(vec.keys, vec.labels, x, sds, vec.prior, vec.prior_sd,
                                                             vec.lo, vec.hi, where, strict=True)]


def _identifiability(parameters: list[FittedParameter], cov: np.ndarray) -> tuple[list[dict[str, Any]], list[str]]:
    """The correlated pairs (|r| >= CORRELATION_LIMIT, largest first) and one warning line per parameter that moved
    more than MOVED_LIMIT prior sd or is determined mainly by its prior (module docstring)."""
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.where(np.outer(sd, sd) > 0, np.outer(sd, sd), np.inf)
    i, j = np.triu_indices(len(sd), 1)
    strong = np.flatnonzero(np.abs(corr[i, j]) >= CORRELATION_LIMIT)
    pairs = sorted(({"a": parameters[i[k]].label, "b": parameters[j[k]].label, "r": float(corr[i[k], j[k]])}
                    for k in strong), key=lambda d: -abs(d["r"]))
    lines = []
    for p in parameters:
        if abs(p.moved_sd) > MOVED_LIMIT:
            lines.append(f"stand fit: {p.label} = {p.value:.4g} moved {p.moved_sd:+.1f} prior sd from {p.prior:.4g} "
                         f"(prior sd {p.prior_sd:g}): the starting model is far off there, or another parameter's "
                         "error is absorbed by it")
        if p.determined_by == "prior":
            lines.append(f"stand fit: {p.label} is determined mainly by its prior (posterior sd {p.sd:.3g} = "
                         f"{p.sd_ratio:.2f} of the prior's {p.prior_sd:g}): these captures say little about it")
    return pairs, lines


def _weak_directions(parameters: list[FittedParameter], cov: np.ndarray) -> list[dict[str, Any]]:
    """The parameter combinations the captures leave to the priors (module docstring), weakest first: each its
    posterior sd over the prior's along it and its largest components (unit vector in prior-sd units, |w| >= 0.1)."""
    prior_sd = np.array([p.prior_sd for p in parameters])
    values, vectors = np.linalg.eigh(cov / np.outer(prior_sd, prior_sd))
    out = []
    for k in np.argsort(values)[::-1]:
        ratio = float(np.sqrt(max(values[k], 0.0)))
        if ratio < PRIOR_RATIO:
            break
        v = vectors[:, k] * np.sign(vectors[np.argmax(np.abs(vectors[:, k])), k])
        top = [[parameters[i].label, round(float(v[i]), 3)] for i in np.argsort(-np.abs(v)) if abs(v[i]) >= 0.1]
        out.append({"sd_ratio": ratio, "combination": top})
    return out


def _covariance(jac: np.ndarray, n_data: int, residuals: np.ndarray, prior_sd: np.ndarray) -> tuple[np.ndarray,
                                                                                                        float]:
    """Parameter covariance (J_d^T J_d / s^2 + diag(1 / prior_sd^2))^-1 and s^2 (module docstring)."""
    Jd = np.asarray(jac, dtype=float)[:n_data]
    dof = max(n_data - len(prior_sd), 1)
    s2 = max(1.0, float(np.sum(residuals[:n_data] ** 2)) / dof)
    info = Jd.T @ Jd / s2 + np.diag(1.0 / prior_sd ** 2)
    return np.linalg.pinv(info), s2


def _log_notes(bounds: list[str], identifiability: list[str]) -> None:
    """A parameter on its bound is a warning (the stand is not what the model allows); what the captures say little
    about is the fit's statistics (INFO: ``calibration show``, ``-v``), nothing for the operator to do."""
    for line in bounds:
        log.warning("%s", line)
    for line in identifiability:
        log.info("%s", line)


def fit_stand(obs: StandObservations, start: StandModel | None = None, priors: Priors | None = None,
              camera_shape: bool | None = None) -> StandFit:
    """Fit the stand model to a calibration's captures (module docstring).

    Parameters
    ----------
    obs : the captures, reduced (:class:`StandObservations`).
    start : the model to start from and centre the priors on (default: nominal; measurements go here).
    priors : prior widths and the model's relative error floor (default :class:`Priors`).
    camera_shape : also fit each camera curve's shift and width (default: when ``start`` has no measured camera).

    Returns
    -------
    :class:`StandFit`: the fitted model, parameters with uncertainties and what determines them (identifiability,
    module docstring), one warning per parameter that ended on a bound, moved more than 3 prior sd or is determined
    mainly by its prior, and R^2 of the start and fitted models on the training and (given) test targets.

    References
    ----------
    Thesis chapter 7 (Fig 7.4), eq 5.10; Nocedal & Wright (2006), ch. 10.
    """
    from scipy.optimize import least_squares

    start = start or StandModel()
    priors = priors or Priors()
    camera_shape = (not start.camera_measured) if camera_shape is None else camera_shape
    used = np.flatnonzero(np.asarray(obs.levels, dtype=float).max(axis=0) > 0)
    vec = _vector(start.params, used, priors, camera_shape)
    k = dn_per_unit_s(start, obs.grid)
    train_only = dataclasses.replace(obs, test_spectra=None, test_frame=None)
    sw, sd = _data_sigma(obs, priors)
    n_data = sw.size + sd.size

    def residuals(x: np.ndarray) -> np.ndarray:
        pred = predict(start.with_params(vec.params(start.params, x)), train_only, k)
        return np.concatenate([((pred.white - obs.white) / sw).ravel(), ((pred.train - obs.train) / sd).ravel(),
                               (x - vec.prior) / vec.prior_sd])
    x0 = np.clip(vec.prior, vec.lo, vec.hi)
    res = least_squares(residuals, x0, bounds=(vec.lo, vec.hi), x_scale=vec.prior_sd, method="trf")
    cov, s2 = _covariance(np.asarray(res.jac, dtype=float), n_data, res.fun, vec.prior_sd)
    where, warnings = _bound_warnings(vec, res.x)
    parameters = _fitted(vec, res.x, cov, where)
    correlations, lines = _identifiability(parameters, cov)
    _log_notes(warnings, lines)
    warnings += lines
    model = start.with_params(vec.params(start.params, res.x))
    fit = _finish(obs, start, model, parameters, warnings, s2, int(res.nfev), priors, k)
    fit.correlations, fit.weak_directions = correlations, _weak_directions(parameters, cov)
    return fit


def _finish(obs: StandObservations, start: StandModel, model: StandModel, parameters: list[FittedParameter],
            warnings: list[str], s2: float, nfev: int, priors: Priors, k: float) -> StandFit:
    nominal, fitted = predict(start, obs, k), predict(model, obs, k)
    r2: dict[str, dict[str, list[float]]] = {}
    for name, pred in (("start", nominal), ("fitted", fitted)):
        r2[name] = {"train": r2_per_channel(pred.train, obs.train)}
        if pred.test is not None and obs.test is not None:
            r2[name]["test"] = r2_per_channel(pred.test, obs.test)
    fit = StandFit(model, start, parameters, warnings, s2, nfev, nominal, fitted, r2, priors)
    log.info("stand fit: %d parameters, %d evaluations, min R^2 train %.5f (start %.5f)", len(parameters), nfev,
             fit.min_r2("fitted"), fit.min_r2("start"))
    return fit


def expected_de00(model: StandModel, mode: str, levels: np.ndarray, capture: CaptureModel | None = None
                  ) -> dict[str, float]:
    """Mean expected captured CIEDE2000 (least-squares matrix; simulation.expected_error) of the light set
    ``levels`` (L, n_leds) on the training and test targets, as ``model`` predicts it under ``capture``: the
    levels as the sphere set them (a light captured, or to be captured as it is: nothing is rounded off below
    the minimum stable level), each LED emitting what the model's level curve says."""
    from dualrgb.simulation.expected_error import ExpectedErrorModel

    setup = model.setup(mode)
    out = ExpectedErrorModel(setup, model.capture(capture or CaptureModel.virtual_lab(mode))).expected(
        np.asarray(levels, dtype=float)[None], captured=True)
    return {k: float(v[0]) for k, v in out.items()}
