"""The spectral estimate of a characterised capture: fitted on the captured training target, judged on the test
target, reported beside the colour figures.

``characterise_spectra`` builds the training data (captured patch means, the training target's reference
spectra, per-pixel noise from the patches' spread, the colour matrix the capture delivers and, when the lights
are known, the system's sensitivities from the simulation's model), chooses the method and its settings by
cross-validation on the training target alone (simulation.spectral_selection) and evaluates the chosen
estimator on both targets (simulation.spectral_metrics: RMSE, GFC, CIEDE2000 under D65, A, D50, FL11 and a
warm-white LED).

The sensitivities come from the model (the lights' LED spectra x the camera's CSRF, eq 5.15, over the open
gate); each channel's gain is fitted to the captured training values (least squares through the origin), so
the model's overall scale per channel (exposure, the flat field's white) never has to be exact. The noise is
the median over the training patches of the per-pixel variance: the estimator is the one the per-pixel cube
applies, so it is regularised for single pixels, not for patch means.
"""
from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb.app.processing.figure_files import FigureJob
from dualrgb.common.progress import CancelToken
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.spectral_estimation import SpectralEstimator, SpectralTraining, quantity_of
from dualrgb.simulation.spectral_selection import SpectralSelection

log = logging.getLogger(__name__)

FIGURE_PATCHES = 6          # patches drawn in the spectra figure (spread over the test target)


@dataclass
class SpectralCharacterisation:
    """The chosen estimator, how it was chosen, and its figures on the training and test targets."""

    selection: SpectralSelection
    wavelengths: np.ndarray
    train: dict
    test: dict | None = None
    estimates: dict[str, np.ndarray] = field(default_factory=dict)     # target -> (n, n_wl) estimated spectra
    references: dict[str, np.ndarray] = field(default_factory=dict)
    sensitivities_gain: list[float] | None = None

    @property
    def estimator(self) -> SpectralEstimator:
        return self.selection.estimator

    def to_dict(self) -> dict:
        """What a calibration profile and a report store: the estimator, the choice, both targets' figures."""
        return {"estimator": self.estimator.to_dict(), "selection": self.selection.to_dict(), "train": self.train,
                "test": self.test, "model_gain": self.sensitivities_gain}

    def summary(self) -> dict:
        """The headline figures (the test target's when there is one): RMSE mean / p90, GFC mean, mean dE00 per
        light."""
        f = self.test or self.train
        return {"method": self.selection.chosen.label(), "target": "test" if self.test else "train",
                "rmse_mean": round(f["rmse"]["mean"], 5), "rmse_p90": round(f["rmse"]["p90"], 5),
                "gfc_mean": round(f["gfc"]["mean"], 5),
                "de00_mean": {k: round(v["mean"], 4) for k, v in f["de00"].items()}}


def model_sensitivities(mode: str, lights: Sequence[LightSource]) -> np.ndarray:
    """The flat-fielded values' sensitivities (n_wl, 3 L) of ``lights`` in the packaged model of ``mode``."""
    from dualrgb.simulation.camera_model import flat_fielded_sensitivities
    from dualrgb.simulation.datasets import default_setup

    setup = default_setup(mode)
    return flat_fielded_sensitivities(np.stack([light.spectrum(setup.leds) for light in lights]), setup.camera)


def fitted_gain(sensitivities: np.ndarray, spectra: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per channel, the gain g minimising |values_c - g (spectra @ S)_c|^2 (1 where the model predicts 0)."""
    predicted = spectra @ sensitivities
    num = np.einsum("nc,nc->c", values, predicted)
    den = np.einsum("nc,nc->c", predicted, predicted)
    return np.divide(num, den, out=np.ones_like(num), where=den > 0)


@dataclass
class SpectralInputs:
    """The patch data of one capture for :func:`characterise_spectra` (``*_std``: per-pixel spread)."""

    mode: str
    channels: list[str]
    train_values: np.ndarray
    train_spectra: np.ndarray
    train_std: np.ndarray | None = None
    test_values: np.ndarray | None = None
    test_spectra: np.ndarray | None = None
    xyz_matrix: np.ndarray | None = None
    lights: Sequence[LightSource] | None = None
    measured_ranges: dict[str, tuple[float, float] | None] = field(default_factory=dict)   # "train" / "test"


def training_data(inputs: SpectralInputs) -> tuple[SpectralTraining, np.ndarray | None]:
    """The :class:`SpectralTraining` of a capture and the model gain per channel (None without the lights)."""
    from dualrgb.simulation.datasets import default_setup

    setup = default_setup(inputs.mode)
    values = np.asarray(inputs.train_values, dtype=float)
    S = gain = None
    if inputs.lights:
        S = model_sensitivities(inputs.mode, inputs.lights)
        if S.shape[1] != values.shape[1]:
            raise ValueError(f"spectral estimate: {len(inputs.lights)} lights give {S.shape[1]} channels but the "
                             f"capture has {values.shape[1]} ({', '.join(inputs.channels)})")
        gain = fitted_gain(S, inputs.train_spectra, values)
        S = S * gain
    noise = None
    if inputs.train_std is not None and np.isfinite(inputs.train_std).all():
        noise = np.median(np.asarray(inputs.train_std, dtype=float) ** 2, axis=0)
    weights = setup.illuminant[:, None] * setup.cmfs * 100.0 / float(setup.illuminant @ setup.cmfs[:, 1])
    quantity = quantity_of(inputs.mode)
    return SpectralTraining(values, inputs.train_spectra, setup.grid.wavelengths, list(inputs.channels), S, noise,
                            weights, inputs.xyz_matrix, quantity), gain


def characterise_spectra(inputs: SpectralInputs, cancel: CancelToken | None = None) -> SpectralCharacterisation:
    """Fit, choose (cross-validation on the training target) and evaluate the spectral estimate of a capture."""
    from dualrgb.simulation.datasets import default_setup, measured_mask
    from dualrgb.simulation.spectral_metrics import seen_wavelengths, spectral_figures
    from dualrgb.simulation.spectral_selection import select_estimator

    training, gain = training_data(inputs)
    selection = select_estimator(training, cancel=cancel)
    setup = default_setup(inputs.mode)
    seen = seen_wavelengths(training.sensitivities) if training.sensitivities is not None else None
    targets = {"train": (training.values, training.spectra)}
    if inputs.test_values is not None and inputs.test_spectra is not None:
        targets["test"] = (np.asarray(inputs.test_values, dtype=float), np.asarray(inputs.test_spectra, dtype=float))
    estimates = {k: selection.estimator.apply(v) for k, (v, _) in targets.items()}
    figures = {k: spectral_figures(estimates[k], ref, setup.grid, setup.cmfs, seen,
                                   measured_mask(setup.grid.wavelengths, inputs.measured_ranges.get(k)))
               for k, (_, ref) in targets.items()}
    out = SpectralCharacterisation(selection, setup.grid.wavelengths, figures["train"], figures.get("test"),
                                   estimates, {k: ref for k, (_, ref) in targets.items()},
                                   None if gain is None else [round(float(g), 6) for g in gain])
    s = out.summary()
    log.info("spectral estimate %s: %s mean RMSE %.4f, p90 %.4f, GFC %.4f", s["method"], s["target"],
             s["rmse_mean"], s["rmse_p90"], s["gfc_mean"])
    return out


def spectra_figure(path: Path, sc: SpectralCharacterisation, names: Sequence[str], target: str = "test") -> Path:
    """Estimated (dashed) against reference (solid) spectra of a few patches spread over ``target``."""
    from dualrgb.app.processing.figure_files import new_figure, save_tight

    ref, est = sc.references[target], sc.estimates[target]
    picks = np.unique(np.linspace(0, len(ref) - 1, min(FIGURE_PATCHES, len(ref))).astype(int))
    fig = new_figure(7.5, 4.2)
    ax = fig.add_subplot(111)
    for i, k in enumerate(picks):
        colour = f"C{i}"
        ax.plot(sc.wavelengths, ref[k], color=colour, lw=1.6, label=str(names[k]) if k < len(names) else str(k))
        ax.plot(sc.wavelengths, est[k], color=colour, lw=1.2, ls="--")
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel(sc.estimator.quantity)
    ax.set_ylim(0, 1.05)
    s = sc.summary()
    ax.set_title(f"{target}: reference (solid) vs estimate (dashed), {s['method']}\nmean RMSE {s['rmse_mean']:.4f}, "
                 f"GFC {s['gfc_mean']:.4f}", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    return save_tight(fig, path)


def spectral_section(out_dir: Path, sc: SpectralCharacterisation, names: Mapping[str, Sequence[str]]
                     ) -> tuple[dict, list[FigureJob]]:
    """The report's "spectral" section and its figure (to draw: app.processing.figure_files.draw_figures)."""
    target = "test" if sc.test is not None else "train"
    path, patches = Path(out_dir) / f"spectra_{target}.png", names.get(target, [])
    job = FigureJob(f"estimated against reference spectra ({target})",
                    lambda: spectra_figure(path, sc, patches, target))
    return {**sc.to_dict(), "summary": sc.summary()}, [job]
