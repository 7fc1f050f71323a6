"""The names and sizes a user chooses from (target modes, search methods, the sphere's LEDs), importable without
numpy or colour-science so the CLI can offer them before anything heavy loads; simulation.datasets,
simulation.runner and simulation.lightsource use these."""
from __future__ import annotations

MODES = ("reflective", "transmissive")                     # reflective targets or film (transmissive), thesis 5.2
METHODS = ("halving", "exhaustive", "pso", "ga", "three-channel")   # simulation.runner.run; first = default
COLOUR_OBJECTIVES = ("expected-captured", "noise-free", "robust", "expected-per-pixel")   # mean dE00; first = default
SPECTRAL_OBJECTIVES = ("spectral", "mixed")                        # expected spectral RMSE, dE00 + weight x RMSE
OBJECTIVES = COLOUR_OBJECTIVES + SPECTRAL_OBJECTIVES               # simulation.runner.make_evaluator
DEFAULT_SPECTRAL_WEIGHT = 0.1    # mixed: mean dE00 + weight x 100 x RMSE (1 % RMSE costs as much as 0.1 dE00)
N_SPHERE_LEDS = 10                                        # the sphere's LEDs, 1-based in LightSource (thesis Table 4.2)
# the calibration's capture protocol: frames averaged into each master dark (thesis 8.2.1: 10) and each open-gate
# white; simulation.capture_model's virtual-lab capture (so every preset's expected captured error) and the copy-stand
# workflow's defaults (app.workflow.stand.defaults: the GUI, the CLI, the demo) read them here
CALIBRATION_DARK_FRAMES = 10
CALIBRATION_FLAT_FRAMES = 3
