"""Rebuild resources/presets/*.json from the simulation (``python -m tools.make_presets``; deterministic).

For each mode: the exhaustive full-intensity best pair (thesis chapter 5 / 9.1.2) and the default optimiser's
best pair (successive halving over the thesis PSO, chapter 6 / 9.1.3, seed 0; file ``<mode>_pso.json``), both
chosen by the default objective, the expected captured error of the virtual lab's capture (issue 14); each
preset carries the noise-free and the expected captured figures. Plus the D65-like sphere mix used for the
3-channel baseline (thesis 1.4). Every level is realised on the sphere's grid (simulation.sphere): 0 or at
least the minimum stable level, in PWM steps.
"""
from __future__ import annotations

import logging

from dualrgb.resources import path
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.datasets import MODES, default_setup
from dualrgb.simulation.presets import Preset, save_preset
from dualrgb.simulation.runner import DEFAULT_METHOD, run
from dualrgb.simulation.sphere import realisable_d65_mix

log = logging.getLogger(__name__)


def main() -> None:
    logging.basicConfig(level=logging.INFO)
    out = path("presets")
    for mode in MODES:
        setup = default_setup(mode)
        for method, label, stem in (("exhaustive", "dual-RGB", "exhaustive"),
                                    (DEFAULT_METHOD, "dual-RGB-PSO", "pso")):
            result = run(setup, method, seed=0, top=1)
            preset = result.preset(name=f"{label} {mode}")
            save_preset(preset, out / f"{mode}_{stem}.json")
            log.info("%s %s: %s", mode, method, " + ".join(s.label() for s in preset.sources))
    setup = default_setup("reflective")
    mix, duv = realisable_d65_mix(setup.leds, setup.illuminant, setup.cmfs, CaptureModel().sphere)
    save_preset(Preset(name="3-channel D65 mix", sources=(mix,), method="nnls-d65",
                       model={"duv_to_d65": round(duv, 5), "grid": setup.grid.label()}),
                out / "three_channel_d65.json")
    log.info("D65 mix: %s (du'v' %.4f)", mix.label(), duv)


if __name__ == "__main__":
    main()
