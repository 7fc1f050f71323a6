"""An LED table moved, stretched and scaled: the one function that perturbs LED spectra.

The virtual lab's worlds render their LEDs with it (drivers/virtual/sphere_light.py) and the stand model fitted to
a calibration (simulation/stand_fit.py) predicts with it, so a fitted peak shift or output scale means exactly
what a world's does: ``S'(lambda) = o * S(p + (lambda - p - s) / w)`` for an LED of peak ``p`` (its table's
maximum), shift ``s`` (nm, + = redder), width scale ``w`` (FWHM x w, peak height kept) and output scale ``o``.
"""
from __future__ import annotations

import logging

import numpy as np
from numpy.typing import ArrayLike

log = logging.getLogger(__name__)


def table_peaks(wavelengths: ArrayLike, spectra: ArrayLike) -> np.ndarray:
    """(n_leds,) each LED's peak wavelength: the table's wavelength of its maximum."""
    return np.asarray(wavelengths, dtype=float)[np.argmax(np.asarray(spectra), axis=1)]


def shaped_led_spectra(wavelengths: ArrayLike, spectra: ArrayLike, shift_nm: ArrayLike | None = None,
                       width_scale: ArrayLike | None = None, output_scale: ArrayLike | None = None,
                       peaks_nm: ArrayLike | None = None) -> np.ndarray:
    """Each LED of a table moved by ``shift_nm``, stretched about its peak by ``width_scale`` and scaled by
    ``output_scale`` (module docstring), on the table's own wavelengths.

    Parameters
    ----------
    wavelengths : (n_wl,) the table's wavelengths in nm (e.g. 1 nm steps, resources/leds/sphere10_relative.csv).
    spectra : (n_leds, n_wl) relative or absolute spectral radiance of each LED at full output.
    shift_nm, width_scale, output_scale : (n_leds,) or None (no shift, width 1, output 1).
    peaks_nm : (n_leds,) the peaks the widths stretch about (default :func:`table_peaks`).

    Returns
    -------
    (n_leds, n_wl) new array; outside the table's range a moved spectrum is 0 (linear interpolation). An LED with
    no shift and width 1 is its table row exactly (times its output scale), so an unperturbed table is returned
    bit for bit.

    References
    ----------
    Thesis 4.3.2 (LED peaks move as the junction warms; Fig 4.10) and Table 4.2 (the nominal peaks).
    """
    wl = np.asarray(wavelengths, dtype=float)
    native = np.asarray(spectra, dtype=float)
    n = native.shape[0]
    shifts = np.zeros(n) if shift_nm is None else np.asarray(shift_nm, dtype=float)
    widths = np.ones(n) if width_scale is None else np.asarray(width_scale, dtype=float)
    peaks = table_peaks(wl, native) if peaks_nm is None else np.asarray(peaks_nm, dtype=float)
    out = np.empty_like(native)
    for k in range(n):
        if widths[k] != 1.0:      # S(p + (wl - p - s) / w): sample positions p + s + (wl - p) w carry S(wl)
            p = peaks[k]
            out[k] = np.interp(wl, p + shifts[k] + (wl - p) * widths[k], native[k], left=0.0, right=0.0)
        elif shifts[k]:           # S(wl - s): the whole spectrum moves; zero outside the table's range
            out[k] = np.interp(wl, wl + shifts[k], native[k], left=0.0, right=0.0)
        else:
            out[k] = native[k]
    if output_scale is not None:
        scale = np.asarray(output_scale, dtype=float)
        for j in np.flatnonzero(scale != 1.0):
            out[j] *= scale[j]
    return out
