"""The camera model of eq 5.10: c_i = sum_lambda L_i(lambda) R(lambda) CSRF_c(lambda) (R -> T for film).

Reflective and transmissive modes share the equation; only the sample spectra differ (reflectance factor vs
transmittance). Values are relative (the fit is scale-free); the virtual camera scales them to digital numbers.
"""
from __future__ import annotations

import numpy as np

CHANNELS = ("R", "G", "B")


def channel_responses(lights: np.ndarray, samples: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """Eq 5.10 for N lights: lights (n_lights, n_wl), samples (n, n_wl), camera (n_wl, 3) -> (n, 3 * n_lights).

    Columns are ordered light-major: R1, G1, B1, R2, G2, B2, ...
    """
    lights = np.atleast_2d(np.asarray(lights, dtype=float))
    per_light = np.einsum("lw,nw,wc->nlc", lights, np.atleast_2d(samples), camera)
    return per_light.reshape(per_light.shape[0], -1)


def led_responses(leds: np.ndarray, samples: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """Response of each camera channel to each LED alone at full level: (n_leds, n, 3).

    By superposition (thesis 3.1.2) a light with levels w gives sum_k w_k * led_responses[k].
    """
    return np.einsum("kw,nw,wc->knc", leds, np.atleast_2d(samples), camera)


def with_flare(responses: np.ndarray, flare: float) -> np.ndarray:
    """Per-LED responses (n_leds, n, 3) of a target's patches with veiling glare: each patch gets ``flare`` times
    the frame's mean response, the frame's mean taken as the target's mean patch (linear in the levels, so it
    holds for every light by superposition). ``flare`` 0: the same array.

    The virtual lab's worlds add glare the same way, from the frame's actual mean (drivers/virtual/camera.py); the
    stand fit (simulation/stand_fit.py) estimates ``flare`` from calibration captures.
    """
    if not flare:
        return responses
    return responses + flare * responses.mean(axis=1, keepdims=True)


def channel_names(n_lights: int) -> list[str]:
    return [f"{c}{i + 1}" for i in range(n_lights) for c in CHANNELS]


def effective_sensitivities(lights: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """Eq 5.15: the N-light system's channel sensitivities L_i(lambda) * CSRF_c(lambda), shape (n_wl, 3 * n_lights)."""
    lights = np.atleast_2d(lights)
    return (lights[:, :, None] * camera[None]).transpose(1, 0, 2).reshape(camera.shape[0], -1)


def flat_fielded_sensitivities(lights: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """The sensitivities of flat-fielded values (eq 7.1: a patch's value over the open gate's, channel by
    channel): eq 5.15 with each channel divided by its response to a perfect white, (n_wl, 3 * n_lights).

    A channel the open gate leaves dark (a light switched off) gets a zero column."""
    S = effective_sensitivities(np.asarray(lights, dtype=float), np.asarray(camera, dtype=float))
    gate = S.sum(axis=0)
    return np.divide(S, gate, out=np.zeros_like(S), where=gate > 0)
