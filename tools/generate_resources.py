"""Rebuild every CSV under resources/ (run ``python -m tools.generate_resources`` or
``make resources``; deterministic).

* LEDs: thesis Table 4.2 peaks and relative peak values, each shaped with colour-science's ``sd_single_led``
  (Ohno 2005) at half spectral width 25 nm, 380-780 nm at 1 nm; the absolute table derived from it
  (tools/derive_leds.py).
* Camera: colour-science's 'Nikon 5100 (NPL)' sensitivities, a stand-in for the D610 (thesis 4.2).
* Reflective targets: rawtoaces v1 training set (190 reflectances) and BabelColor Average ColorChecker (24,
  measured 380-730 nm); the ColorChecker measured by Ohta (1997) to 780 nm, a second test reference for the
  spectral figures beyond 730 nm (colour-science's 'ColorChecker N Ohta', the same data as ISO 17321-1).
* Film targets: a three-dye Beer-Lambert film model, T = 10^-(base + c*Dc + m*Dm + y*Dy) with Gaussian dye
  densities; an IT8.7/1-like 288-patch training film (264 Sobol-sampled dye mixes + 24 neutral steps) and
  the ColorChecker 24 reproduced on film (dye amounts fitted per patch to the chart's D65 Lab).
"""
from __future__ import annotations

import logging

import colour
import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from dualrgb.resources import path
from dualrgb.simulation.film_model import DYES, FILM_BASE_DENSITY, film_transmittance
from dualrgb.simulation.spectral_io import write_spectral_csv
from tools.derive_leds import derive

log = logging.getLogger(__name__)

LED_PEAKS_NM = (416, 448, 467, 491, 520, 545, 572, 597, 626, 680)
LED_RELATIVE_PEAKS = (0.88, 1.00, 0.663, 0.183, 0.198, 0.014, 0.003, 0.165, 0.300, 0.565)
# thesis Table 4.2's absolute column (W sr^-1 m^-2) is not used: its ratios differ from the relative column by up
# to 3.8 % (LED 7); the absolute table is the relative one x LED 2's absolute peak (tools/derive_leds.py)
LED_HALF_SPECTRAL_WIDTH = 25.0
FILM_SHAPE = colour.SpectralShape(380, 780, 5)
SCRIPT = "tools/generate_resources.py (python -m tools.generate_resources)"


def _led_csvs() -> None:
    shape = colour.SpectralShape(380, 780, 1)
    wl = shape.wavelengths
    base = np.stack([colour.sd_single_led(p, shape=shape, half_spectral_width=LED_HALF_SPECTRAL_WIDTH).values
                     for p in LED_PEAKS_NM], axis=1)
    base /= base.max(axis=0)
    names = [f"LED{i}" for i in range(1, 11)]
    common = {
        "peaks_nm": " ".join(str(p) for p in LED_PEAKS_NM),
        "model": f"colour.sd_single_led (Ohno 2005), half_spectral_width={LED_HALF_SPECTRAL_WIDTH:g} nm",
        "source": "thesis Table 4.2 (peak wavelengths and peak values of the 10-LED integrating sphere)",
        "generated_by": SCRIPT,
    }
    write_spectral_csv(path("leds", "sphere10_relative.csv"), wl, base * np.array(LED_RELATIVE_PEAKS), names,
                       {"title": "10-LED sphere spectra, relative", "units": "relative radiance (LED 2 peak = 1)",
                        **common})
    derive(path("leds", "sphere10_relative.csv"), path("leds", "sphere10_absolute.csv"))   # one source (issue 40)


def _camera_csv() -> None:
    msds = colour.characterisation.MSDS_CAMERA_SENSITIVITIES["Nikon 5100 (NPL)"]
    write_spectral_csv(path("cameras", "nikon_5100_npl.csv"), msds.wavelengths, msds.values, ["red", "green", "blue"],
                       {"title": "Camera spectral sensitivity (stand-in for the Nikon D610)",
                        "units": "relative sensitivity (peak-normalised)",
                        "source": "colour-science MSDS_CAMERA_SENSITIVITIES['Nikon 5100 (NPL)'] (NPL measurements)",
                        "generated_by": SCRIPT})


def _reflective_csvs() -> None:
    train = colour.characterisation.read_training_data_rawtoaces_v1()
    # the source holds rounding residues down to -7e-18: clip them to 0 so the file passes strict validation
    assert train.values.min() > -1e-9
    write_spectral_csv(path("targets", "reflective_train_rawtoaces190.csv"), train.wavelengths,
                       np.clip(train.values, 0.0, None),
                       [str(n) for n in train.labels],
                       {"title": "Reflective training target (190 samples)",
                        "units": "reflectance factor (0..1; a few fluorescent samples reach 1.44)",
                        "source": "colour-science read_training_data_rawtoaces_v1() (rawtoaces training data; "
                                  "residues < 1e-9 clipped to 0)",
                        "generated_by": SCRIPT})
    cc = colour.SDS_COLOURCHECKERS["BabelColor Average"]
    names = list(cc)
    wl = next(iter(cc.values())).wavelengths
    vals = np.stack([cc[n].values for n in names], axis=1)
    write_spectral_csv(path("targets", "reflective_test_babelcolor_cc24.csv"), wl, vals, names,
                       {"title": "Reflective test target ColorChecker Classic 24", "units": "reflectance factor 0..1",
                        "source": "colour-science SDS_COLOURCHECKERS['BabelColor Average']", "layout": "4x6",
                        "generated_by": SCRIPT})
    _ohta_csv()


def _ohta_csv() -> None:
    cc = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    names = list(cc)
    wl = next(iter(cc.values())).wavelengths
    vals = np.stack([cc[n].values for n in names], axis=1)
    write_spectral_csv(path("targets", "reflective_test_ohta_cc24.csv"), wl, vals, names,
                       {"title": "Reflective test target ColorChecker Classic 24 (Ohta)",
                        "units": "reflectance factor 0..1",
                        "source": "colour-science SDS_COLOURCHECKERS['ColorChecker N Ohta'] (Ohta N., The basis of "
                                  "color reproduction engineering, 1997; the same data as ISO 17321-1), 380-780 nm",
                        "layout": "4x6", "generated_by": SCRIPT})


def _lab_d65(values: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
    shape = colour.SpectralShape(wavelengths[0], wavelengths[-1], wavelengths[1] - wavelengths[0])
    msds = colour.MultiSpectralDistributions(values, wavelengths)
    xyz = colour.msds_to_XYZ(msds, colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape),
                             colour.SDS_ILLUMINANTS["D65"].copy().align(shape), method="Integration") / 100
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return colour.XYZ_to_Lab(xyz, white)


def _film_csvs() -> None:
    wl = FILM_SHAPE.wavelengths
    sampler = qmc.Sobol(d=3, scramble=True, seed=87)
    amounts = sampler.random(264) * 2.2
    greys = np.linspace(0.0, 2.6, 24)
    amounts = np.vstack([amounts, np.stack([greys, greys * 0.93, greys * 0.88], axis=1)])
    t_train = film_transmittance(amounts, wl)
    names = [f"IT8-{i + 1:03d}" for i in range(264)] + [f"GS{i:02d}" for i in range(24)]
    write_spectral_csv(path("targets", "film_train_it87_288.csv"), wl, t_train, names,
                       {"title": "IT8.7/1-like film training target (288 patches)", "units": "transmittance 0..1",
                        "source": "three-dye Beer-Lambert film model (synthetic, stands in for a measured IT8.7/1)",
                        "model": f"T=10^-({FILM_BASE_DENSITY}+c*Dc+m*Dm+y*Dy); dyes {DYES} (peak nm, sigma nm)",
                        "layout": "12x22 + 24 grey scale", "generated_by": SCRIPT})

    cc = colour.SDS_COLOURCHECKERS["BabelColor Average"]
    cc_names = list(cc)
    cc_vals = np.stack([cc[n].copy().align(FILM_SHAPE).values for n in cc_names], axis=1)
    target_lab = _lab_d65(cc_vals, wl)

    def lab_error(amounts: np.ndarray, lab: np.ndarray) -> np.ndarray:
        return _lab_d65(film_transmittance(amounts[None, :], wl), wl)[0] - lab

    fitted = [least_squares(lab_error, x0=np.array([0.5, 0.5, 0.5]), bounds=(0.0, 4.0), args=(lab,)).x
              for lab in target_lab]
    t_test = film_transmittance(np.array(fitted), wl)
    write_spectral_csv(path("targets", "film_test_cc24.csv"), wl, t_test, cc_names,
                       {"title": "ColorChecker 24 reproduced on film", "units": "transmittance 0..1",
                        "source": "three-dye Beer-Lambert film model with dye amounts fitted to BabelColor Average "
                                  "CC24 D65 Lab (scipy least_squares, amounts 0..4)",
                        "layout": "4x6", "generated_by": SCRIPT})


def main() -> None:
    logging.basicConfig(level=logging.INFO)
    _led_csvs()
    _camera_csv()
    _reflective_csvs()
    _film_csvs()
    log.info("resources written under %s", path())


if __name__ == "__main__":
    main()
