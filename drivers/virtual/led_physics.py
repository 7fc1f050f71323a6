"""How the sphere's LEDs behave as they stay on (thesis 4.3.2, Fig. 4.10): peak-wavelength drift, LED 10's fade,
and the sphere's heating; the emulator (drivers/virtual/sphere_emulator.py) evaluates them on its own clock.

Drift depends on continuous on-time only, not on the level (the thesis measured at full level): none during the
first 10 s, then growing towards a per-LED maximum reached after about an hour (LED 4 ~7 nm, LED 7 none, the
others a few nm). LED 10 fades after ~40 min on and does not recover (it "died" in the thesis run).
"""
from __future__ import annotations

import math

import numpy as np

# Thesis 4.3.2 / Fig. 4.10: maximum peak shift after ~1 h (LED 4 7 nm, LED 7 none, others a few nm).
MAX_SHIFT_NM = np.array([2.0, 3.0, 3.0, 7.0, 4.0, 3.0, 0.0, 3.0, 4.0, 5.0])
DRIFT_ONSET_S = 10.0          # no shift at all during the first 10 s on
DRIFT_TAU_S = 900.0           # 1 - exp(-(3600 - 10) / 900) = 0.98 of the maximum after an hour
FADE_LED = 10                 # LED 10 malfunctioned towards the end of the hour (thesis 4.3.2)
FADE_START_S = 2400.0         # its output starts to fall after 40 min continuously on ...
FADE_TAU_S = 600.0            # ... to exp(-2) = 14 % after an hour; the loss is permanent
AMBIENT_C = 24.0
HEAT_C_PER_LED = 1.2          # steady-state rise per LED at full level
THERMAL_TAU_S = 240.0
OVER_TEMPERATURE_C = 45.0


def peak_shift_nm(on_time_s: np.ndarray | float, max_shift_nm: np.ndarray | float = MAX_SHIFT_NM) -> np.ndarray:
    """Peak-wavelength drift (nm, towards longer wavelengths) after ``on_time_s`` seconds continuously on."""
    t = np.maximum(np.asarray(on_time_s, dtype=float) - DRIFT_ONSET_S, 0.0)
    return np.asarray(max_shift_nm, dtype=float) * -np.expm1(-t / DRIFT_TAU_S)


def fade_factor(on_time_s: float) -> float:
    """LED 10's relative output after ``on_time_s`` seconds continuously on (1 before FADE_START_S)."""
    return 1.0 if on_time_s <= FADE_START_S else math.exp(-(on_time_s - FADE_START_S) / FADE_TAU_S)
