"""Spectral estimation: the dual-RGB channels -> a reflectance (or transmittance) factor per wavelength.

Every method fits one *linear* map, an (n_wavelengths, n_channels) matrix, from training data, and the estimate
is that map followed by a clip to the physical range [0, 1] (:class:`SpectralEstimator`). A linear map is what
a per-pixel cube needs: 24 MP images are estimated in row bands as one matrix product and a clip.

Methods (the dispatch table :data:`SPECTRAL_METHODS`, colour-science style):

* ``wiener``: the Wiener (linear minimum mean-square error) estimate for values c = S^T r + n,
  M = K S (S^T K S + N)^-1, with S the system's sensitivities (the lights' spectra times the camera's CSRF,
  eq 5.15, divided by the open gate: :func:`simulation.camera_model.flat_fielded_sensitivities`), N the noise
  covariance of the values (diagonal: the capture model's or the measured noise) and K the prior second-moment
  matrix of the spectra (:class:`SpectralPrior`): a mix of the training spectra's second moment and a
  first-order Markov smoothness prior, K_ij = rho^(|lambda_i - lambda_j| / 10 nm). The second moment (not the
  centred covariance) keeps the map linear (no offset).
* ``matrix-r``: Zhao & Berns' matrix R method: the fundamental metamer of the colorimetric estimate (XYZ from
  the colour matrix, colorimetrically exact under the reference illuminant: the estimate's XYZ is the matrix's)
  plus the metameric black of a spectral estimate (Wiener when the sensitivities are known, else ``pinv``),
  M = A (A^T A)^-1 M_xyz^T + (I - A (A^T A)^-1 A^T) M_spectral, A = the reference illuminant x CMFs (eq 4.2).
* ``pinv``: least squares from the training values to the training spectra (Moore-Penrose; with ``ridge``
  > 0 a ridge regression, the ridge relative to the mean diagonal of C^T C), the "training-based" estimate.

``offset=True`` (``wiener`` and ``pinv``) makes the map affine, ``spectra = values M^T + b``: the fit is made on
the training data centred on their means (the Wiener prior is then the covariance, not the second moment) and
``b = mean spectrum - mean values M^T``. Where the system sees nothing (below ~410 nm and above ~690 nm for the
Nikon CSRF) a linear map can only scale the spectrum with the visible signal; a film's transmittance there is its
base's, nearly constant whatever the dyes, which only an offset carries. Cross-validation on the training target
chooses between the two (simulation.spectral_selection).

References
----------
Pratt & Mancill (1976), Spectral estimation techniques for the spectral calibration of a color image scanner,
Applied Optics 15(1) (the Wiener estimate); Haneishi et al. (2000), System design for accurately estimating the
spectral reflectance of art paintings, Applied Optics 39(35) (the Wiener estimate with a first-order Markov
prior and the system noise); Zhao & Berns (2007), Image-based spectral reflectance reconstruction using the
matrix R method, Color Research & Application 32(5); Cohen & Kappauf (1982), Metameric color stimuli,
fundamental metamers, and Wyszecki's metameric blacks, American Journal of Psychology 95(4).
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np

log = logging.getLogger(__name__)

FORMAT = "dualrgb-spectral-estimator/1"
PHYSICAL_RANGE = (0.0, 1.0)             # reflectance or transmittance factor of a non-fluorescent original
MARKOV_STEP_NM = 10.0                   # the smoothness prior's rho is the correlation of samples 10 nm apart
JITTER = 1e-10                          # relative to the mean diagonal: keeps a dark channel's system solvable
QUANTITIES = {"reflective": "reflectance factor", "transmissive": "transmittance factor"}     # what a mode measures


def quantity_of(mode: str) -> str:
    """What ``mode`` measures (:data:`QUANTITIES`; anything else: reflectance)."""
    return QUANTITIES.get(mode, QUANTITIES["reflective"])


class SpectralEstimationError(ValueError):
    """Training data or a stored estimator that cannot define a spectral estimate (one line)."""


@dataclass(frozen=True)
class SpectralPrior:
    """The prior second moment of the spectra: ``training_weight`` x the training spectra's second moment +
    (1 - ``training_weight``) x a Markov smoothness prior with correlation ``smoothness`` at 10 nm (scaled to
    the training spectra's mean square)."""

    smoothness: float = 0.98
    training_weight: float = 0.75

    def __post_init__(self) -> None:
        if not (0.0 <= self.smoothness < 1.0 and 0.0 <= self.training_weight <= 1.0):
            raise SpectralEstimationError(f"spectral prior: smoothness {self.smoothness} must be in [0, 1) and "
                                          f"training weight {self.training_weight} in [0, 1]")

    def matrix(self, spectra: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
        """K (n_wl, n_wl) for the training ``spectra`` (n, n_wl) on ``wavelengths``."""
        spectra = np.asarray(spectra, dtype=float)
        trained = spectra.T @ spectra / len(spectra)
        wl = np.asarray(wavelengths, dtype=float)
        smooth = self.smoothness ** (np.abs(np.subtract.outer(wl, wl)) / MARKOV_STEP_NM)
        scale = float(np.trace(trained)) / len(wl) or 1.0
        return self.training_weight * trained + (1.0 - self.training_weight) * scale * smooth

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class SpectralTraining:
    """What a fit may use: training ``values`` (n, C) and ``spectra`` (n, n_wl) on ``wavelengths``, and where
    known the system's ``sensitivities`` (n_wl, C: values ~ spectra @ sensitivities), the ``noise_var`` (C,) of
    the values the estimator will be applied to, the ``colour_weights`` (n_wl, 3: XYZ = spectra @ them, the
    reference illuminant x CMFs of eq 4.2) and the ``xyz_matrix`` (C, 3) the colour is delivered with (None:
    least squares on these values)."""

    values: np.ndarray
    spectra: np.ndarray
    wavelengths: np.ndarray
    channels: list[str] = field(default_factory=list)
    sensitivities: np.ndarray | None = None
    noise_var: np.ndarray | None = None
    colour_weights: np.ndarray | None = None
    xyz_matrix: np.ndarray | None = None
    quantity: str = QUANTITIES["reflective"]

    def __post_init__(self) -> None:
        self.values = np.asarray(self.values, dtype=float)
        self.spectra = np.asarray(self.spectra, dtype=float)
        self.wavelengths = np.asarray(self.wavelengths, dtype=float)
        n, c = self.values.shape if self.values.ndim == 2 else (0, 0)
        if self.values.ndim != 2 or self.spectra.shape != (n, len(self.wavelengths)):
            raise SpectralEstimationError(f"spectral training: values {self.values.shape} and spectra "
                                          f"{self.spectra.shape} do not describe the same {len(self.wavelengths)}"
                                          "-sample patches")
        if not (np.isfinite(self.values).all() and np.isfinite(self.spectra).all()):
            raise SpectralEstimationError("spectral training: values or spectra contain NaN or infinity")
        if n < 2:
            raise SpectralEstimationError(f"spectral training: {n} patches; at least 2 are needed")
        if not self.channels:
            self.channels = [f"ch{i + 1}" for i in range(c)]
        if self.sensitivities is not None and np.shape(self.sensitivities) != (len(self.wavelengths), c):
            raise SpectralEstimationError(f"spectral training: sensitivities {np.shape(self.sensitivities)}, "
                                          f"expected ({len(self.wavelengths)}, {c})")

    @property
    def xyz(self) -> np.ndarray:
        return self.spectra @ self._weights()

    def _weights(self) -> np.ndarray:
        if self.colour_weights is None:
            raise SpectralEstimationError("matrix-r needs the colour weights (reference illuminant x CMFs)")
        return np.asarray(self.colour_weights, dtype=float)

    def subset(self, rows: np.ndarray) -> SpectralTraining:
        """The same training restricted to ``rows`` (cross-validation folds); the colour matrix is refitted."""
        return replace(self, values=self.values[rows], spectra=self.spectra[rows], xyz_matrix=None)


@dataclass
class SpectralEstimator:
    """A fitted estimate: ``spectra = clip(values @ matrix.T, *bounds)``, ``matrix`` (n_wl, n_channels).

    ``offset`` (n_wl,) makes it affine (module docstring; None: linear). The per-pixel cube applies it in row
    bands (:meth:`apply` with ``out``); ``to_dict`` / ``from_dict`` store it in a calibration profile (JSON)."""

    matrix: np.ndarray
    wavelengths: np.ndarray
    channels: list[str]
    method: str
    settings: dict = field(default_factory=dict)
    bounds: tuple[float, float] = PHYSICAL_RANGE
    quantity: str = QUANTITIES["reflective"]
    offset: np.ndarray | None = None

    @property
    def n_channels(self) -> int:
        return int(self.matrix.shape[1])

    @property
    def n_wavelengths(self) -> int:
        return int(self.matrix.shape[0])

    def apply(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Spectra (..., n_wl) of ``values`` (..., n_channels): one matrix product (+ the offset) and a clip
        to ``bounds``.

        float32 values give float32 spectra (the cube streams float32 row bands), anything else float64; NaN
        values (pixels without a usable flat field) give NaN spectra. ``out``: a preallocated result array."""
        values = np.asarray(values)
        if values.shape[-1] != self.n_channels:
            raise SpectralEstimationError(f"spectral estimator ({self.method}) expects {self.n_channels} channels "
                                          f"({', '.join(self.channels)}), got {values.shape[-1]}")
        dtype = np.float32 if values.dtype == np.float32 else np.float64
        est = np.matmul(values.astype(dtype, copy=False), self.matrix.T.astype(dtype), out=out)
        if self.offset is not None:
            est += self.offset.astype(dtype)
        return np.clip(est, self.bounds[0], self.bounds[1], out=est)

    def to_dict(self) -> dict:
        return {"format": FORMAT, "method": self.method, "quantity": self.quantity,
                "wavelengths_nm": [float(v) for v in self.wavelengths], "channels": list(self.channels),
                "bounds": [float(b) for b in self.bounds], "settings": self.settings,
                "matrix": [[float(v) for v in row] for row in self.matrix],
                **({"offset": [float(v) for v in self.offset]} if self.offset is not None else {})}

    @classmethod
    def from_dict(cls, data: dict, source: str = "spectral estimator") -> SpectralEstimator:
        """The estimator stored by :meth:`to_dict`; anything else is a one-line :class:`SpectralEstimationError`."""
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            found = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise SpectralEstimationError(f"{source}: format {found!r}, expected {FORMAT!r}")
        try:
            matrix = np.asarray(data["matrix"], dtype=float)
            wavelengths = np.asarray(data["wavelengths_nm"], dtype=float)
            channels = [str(c) for c in data["channels"]]
            lo, hi = (float(b) for b in data.get("bounds", PHYSICAL_RANGE))
            offset = None if data.get("offset") is None else np.asarray(data["offset"], dtype=float)
        except (KeyError, TypeError, ValueError) as exc:
            raise SpectralEstimationError(f"{source}: damaged ({type(exc).__name__}: {exc})") from None
        if matrix.shape != (len(wavelengths), len(channels)) or not np.isfinite(matrix).all() or not lo < hi:
            raise SpectralEstimationError(f"{source}: matrix {matrix.shape} does not fit {len(wavelengths)} "
                                          f"wavelengths x {len(channels)} channels (or is not finite)")
        if offset is not None and (offset.shape != (len(wavelengths),) or not np.isfinite(offset).all()):
            raise SpectralEstimationError(f"{source}: offset {offset.shape} does not fit {len(wavelengths)} "
                                          "wavelengths (or is not finite)")
        return cls(matrix, wavelengths, channels, str(data.get("method", "")), dict(data.get("settings") or {}),
                   (lo, hi), str(data.get("quantity", QUANTITIES["reflective"])), offset)


def _estimator(training: SpectralTraining, matrix: np.ndarray, method: str, settings: dict,
               offset: np.ndarray | None = None) -> SpectralEstimator:
    return SpectralEstimator(matrix, training.wavelengths.copy(), list(training.channels), method, settings,
                             PHYSICAL_RANGE, training.quantity, offset)


def wiener_matrix(sensitivities: np.ndarray, prior: np.ndarray, noise_var: np.ndarray | None) -> np.ndarray:
    """M = K S (S^T K S + N)^-1 (n_wl, C) for S (n_wl, C), K (n_wl, n_wl) and N = diag(noise_var).

    A channel the system does not see (a zero column of S, no noise) gets a zero column instead of a singular
    system (a tiny jitter on every diagonal, and 1 on that channel's)."""
    S = np.asarray(sensitivities, dtype=float)
    KS = prior @ S
    P = S.T @ KS
    if noise_var is not None:
        P = P + np.diag(np.asarray(noise_var, dtype=float))
    d = np.diag(P).copy()
    P[np.diag_indices_from(P)] += JITTER * (float(d[d > 0].mean()) if (d > 0).any() else 1.0) + (d <= 0)
    return np.linalg.solve(P, KS.T).T


def pinv_matrix(values: np.ndarray, spectra: np.ndarray, ridge: float = 0.0) -> np.ndarray:
    """Least squares values -> spectra: M (n_wl, C) minimising |values M^T - spectra|^2 (+ ridge)."""
    C = np.asarray(values, dtype=float)
    if ridge <= 0:
        return np.linalg.lstsq(C, spectra, rcond=None)[0].T      # minimum norm: a zero channel gets a zero column
    G = C.T @ C
    G[np.diag_indices_from(G)] += ridge * float(np.trace(G)) / len(G)
    return np.linalg.solve(G, C.T @ spectra).T


def fit_wiener(training: SpectralTraining, prior: SpectralPrior = SpectralPrior(),
               noise_var: np.ndarray | None = None, offset: bool = False) -> SpectralEstimator:
    """The Wiener estimate (module docstring) with ``prior`` and the noise ``noise_var`` (default: the
    training's ``noise_var``, else none); ``offset``: the affine estimate about the training mean (the prior
    built from the centred spectra: their covariance)."""
    if training.sensitivities is None:
        raise SpectralEstimationError("wiener needs the system's sensitivities (the lights' spectra x the camera's "
                                      "CSRF); without them use matrix-r or pinv")
    noise = training.noise_var if noise_var is None else noise_var
    S = np.asarray(training.sensitivities, dtype=float)
    mean = training.spectra.mean(axis=0) if offset else np.zeros(len(training.wavelengths))
    M = wiener_matrix(S, prior.matrix(training.spectra - mean, training.wavelengths), noise)
    settings = {"prior": prior.to_dict(), "noise_var": None if noise is None else [float(v) for v in noise],
                **({"offset": True} if offset else {})}
    return _estimator(training, M, "wiener", settings, mean - (mean @ S) @ M.T if offset else None)


def fit_pinv(training: SpectralTraining, ridge: float = 0.0, offset: bool = False) -> SpectralEstimator:
    """Least squares from the training values to the training spectra (``ridge`` > 0: ridge regression);
    ``offset``: with an intercept (fitted on the centred data, so the ridge does not shrink it)."""
    if not offset:
        return _estimator(training, pinv_matrix(training.values, training.spectra, ridge), "pinv", {"ridge": ridge})
    mv, ms = training.values.mean(axis=0), training.spectra.mean(axis=0)
    M = pinv_matrix(training.values - mv, training.spectra - ms, ridge)
    return _estimator(training, M, "pinv", {"ridge": ridge, "offset": True}, ms - mv @ M.T)


def fit_matrix_r(training: SpectralTraining, prior: SpectralPrior = SpectralPrior(),
                 ridge: float = 0.0) -> SpectralEstimator:
    """Zhao & Berns' matrix R: the fundamental metamer of the colour matrix's XYZ plus the metameric black of
    the Wiener estimate (``prior``; ``pinv`` with ``ridge`` when the sensitivities are unknown)."""
    A = training._weights()
    M_xyz = training.xyz_matrix
    if M_xyz is None:
        M_xyz = np.linalg.lstsq(training.values, training.xyz, rcond=None)[0]
    fundamental = A @ np.linalg.solve(A.T @ A, np.asarray(M_xyz, dtype=float).T)      # (n_wl, C)
    R = A @ np.linalg.solve(A.T @ A, A.T)                                              # Cohen's matrix R
    part: dict
    if training.sensitivities is not None:
        spectral, part = fit_wiener(training, prior), {"spectral_part": "wiener", "prior": prior.to_dict()}
    else:
        spectral, part = fit_pinv(training, ridge), {"spectral_part": "pinv", "ridge": ridge}
    M = fundamental + (np.eye(len(A)) - R) @ spectral.matrix
    return _estimator(training, M, "matrix-r", {**part, "noise_var": spectral.settings.get("noise_var")})


Fit = Callable[..., SpectralEstimator]
SPECTRAL_METHODS: dict[str, Fit] = {"wiener": fit_wiener, "matrix-r": fit_matrix_r, "pinv": fit_pinv}


def fit_spectral(training: SpectralTraining, method: str = "wiener", **settings) -> SpectralEstimator:
    """Fit ``method`` (a key of :data:`SPECTRAL_METHODS`) with its ``settings`` on ``training``."""
    if method not in SPECTRAL_METHODS:
        raise SpectralEstimationError(f"spectral method {method!r}: expected one of {', '.join(SPECTRAL_METHODS)}")
    return SPECTRAL_METHODS[method](training, **settings)
