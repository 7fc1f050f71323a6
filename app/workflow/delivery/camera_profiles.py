"""The ICC profile of a camera-RGB master (one light's flat-fielded camera R, G, B): what it says and how it is made.

Choice: a linear input profile built from the calibration, rather than data marked as device data. TIFF has no
way to say "device RGB, not colorimetric" that baseline validators accept (SLUB's checkit_tiff baseline requires an
ICC profile in every RGB TIFF), and a file without one is shown by every colour-managed viewer as sRGB: linear
camera data displayed as gamma-encoded, dark and wrong. A profile that tells the truth about the encoding (linear,
65535 = 2x the flat field's white) and gives the best colorimetric reading one light's three channels allow is the
honest choice: a viewer then shows the image with about the right tones and colours, and the profile's
description says it is an approximation and where the calibrated colours are (the XYZ and RGB masters, made from
every light's channels with the calibration's matrix).

How the 3x3 is fitted (why not from the chart's captures: the calibration profile keeps no patch values): the
calibration's lights (their LED levels, the packaged LED spectra) and the camera model (eq 5.10 with the nominal
sensitivities) give each light's flat-fielded channels (eq 7.1) for the mode's training reflectances; the
calibration's own matrix turns all lights' channels into the XYZ the masters hold; light n's 3x3 is the least-
squares map from its three channels to that XYZ. So it is "what the calibration would deliver, from this light
alone", on typical surfaces. Its fit residual is said in the description (mean dE00 on those surfaces).
"""
from __future__ import annotations

import logging
from functools import lru_cache

import numpy as np

from dualrgb.app.processing.encode import LINEAR_ONE
from dualrgb.app.processing.outputs import camera_icc

log = logging.getLogger(__name__)


@lru_cache(maxsize=8)
def _setup(mode: str):
    from dualrgb.simulation.datasets import default_setup

    return default_setup(mode)


def light_matrices(profile) -> list[tuple[np.ndarray, float]]:
    """Per light of ``profile`` (in its channel order): the (3, 3) matrix (row c: channel c's XYZ at 1.0 on the
    calibration's scale) and its mean dE00 on the training surfaces against the calibration's XYZ."""
    from dualrgb.simulation.camera_model import flat_fielded_sensitivities
    from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab

    setup = _setup(profile.mode)
    lights = np.stack([nl.light.spectrum(setup.leds) for nl in profile.lights])
    values = setup.train.spectra @ flat_fielded_sensitivities(lights, setup.camera)      # (n, 3 L)
    A = np.asarray(profile.matrix.matrix, dtype=float)
    if A.shape[0] != values.shape[1]:
        raise ValueError(f"calibration {profile.id}: a matrix of {A.shape[0]} channels for {len(profile.lights)} "
                         "lights")
    xyz = values @ A
    white = np.asarray(profile.white_xyz, dtype=float)
    out = []
    for n in range(len(profile.lights)):
        v = values[:, 3 * n: 3 * n + 3]
        m, *_ = np.linalg.lstsq(v, xyz, rcond=None)
        de = delta_e_2000(xyz_to_lab(np.clip(v @ m, 0, None), white), xyz_to_lab(xyz, white))
        out.append((m, float(np.mean(de))))
    return out


def camera_rgb_icc(profile, light: int, light_name: str) -> bytes:
    """The ICC profile embedded in light ``light``'s camera-RGB master (module docstring); a calibration the
    model cannot be fitted for (lights it does not describe) gets the profile of its white balance alone: a
    diagonal map of the flat field's white to the reference white, said in the description."""
    try:
        m, de = light_matrices(profile)[light]
        what = f"3x3 fit to calibration {profile.id}, mean dE00 {de:.1f} on typical surfaces"
    except (ValueError, KeyError, IndexError, np.linalg.LinAlgError) as exc:
        log.warning("camera-RGB profile of %s: %s; white balance only", light_name, exc)
        m = np.diag(np.asarray(profile.white_xyz, dtype=float))
        what = "white balance only (no colour fit)"
    text = f"camera RGB under {light_name}, linear, 2x headroom: approximate ({what}); calibrated colours: XYZ master"
    return camera_icc(m, profile.white_xyz, LINEAR_ONE, text.encode("ascii", "replace").decode("ascii"))
