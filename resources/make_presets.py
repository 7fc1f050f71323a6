"""Rebuild resources/presets/*.json from the simulation (``python -m resources.make_presets``; deterministic).

For each mode: the exhaustive full-intensity best pair (thesis chapter 5 / 9.1.2) and the PSO best pair
(chapter 6 / 9.1.3, seed 0), plus the D65-like sphere mix used for the 3-channel baseline (thesis 1.4).
"""
from __future__ import annotations

import logging

from resources import path
from simulation.datasets import MODES, default_setup
from simulation.presets import Preset, d65_mix, save_preset
from simulation.runner import run

log = logging.getLogger(__name__)


def main() -> None:
    logging.basicConfig(level=logging.INFO)
    out = path("presets")
    for mode in MODES:
        setup = default_setup(mode)
        for method, label in (("exhaustive", "dual-RGB"), ("pso", "dual-RGB-PSO")):
            result = run(setup, method, seed=0, top=1)
            preset = result.preset(name=f"{label} {mode}")
            save_preset(preset, out / f"{mode}_{method}.json")
            log.info("%s %s: %s", mode, method, " + ".join(s.label() for s in preset.sources))
    setup = default_setup("reflective")
    mix, duv = d65_mix(setup.leds, setup.illuminant, setup.cmfs)
    save_preset(Preset(name="3-channel D65 mix", sources=(mix,), method="nnls-d65",
                       model={"duv_to_d65": round(duv, 5), "grid": setup.grid.label()}),
                out / "three_channel_d65.json")
    log.info("D65 mix: %s (du'v' %.4f)", mix.label(), duv)


if __name__ == "__main__":
    main()
