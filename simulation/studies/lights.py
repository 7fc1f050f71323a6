"""The light sets the default-choosing studies (parsimony, HDR merge) judge their options with.

The defaults serve the copy stand, so they are judged under the lights it uses: the mode's packaged presets
(``resources/presets/<mode>_exhaustive.json`` and ``<mode>_pso.json``, made by ``make resources`` with the
expected-captured objective). With a user's own measured data (camera, LEDs or targets), those presets do not
apply; then the full-intensity exhaustive optimum and a PSO optimum of that setup stand in.
"""
from __future__ import annotations

import logging

import numpy as np

from dualrgb import resources
from dualrgb.simulation.presets import load_preset
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.search import exhaustive, light_pairs
from dualrgb.simulation.studies.common import SetupSpec, evaluator_for

log = logging.getLogger(__name__)

PRESET_FILES = {"exhaustive": "{mode}_exhaustive.json", "pso": "{mode}_pso.json"}


def study_lights(spec: SetupSpec, pso_settings: PsoSettings = PsoSettings(particles=100, iterations=10),
                 light_sets: int | None = None) -> tuple[dict[str, np.ndarray], str]:
    """{'exhaustive': (L, K), 'pso': (L, K)} and where they come from ('packaged presets' or 'optima')."""
    ev = evaluator_for(spec)
    custom = any((spec.camera_csv, spec.leds_csv, spec.train_csv, spec.test_csv))
    if not custom:
        out = {}
        for key, name in PRESET_FILES.items():
            preset = load_preset(resources.path("presets", name.format(mode=spec.mode)))
            out[key] = np.stack([s.weights(ev.n_leds) for s in preset.sources])
        return out, "packaged presets"
    groups = light_pairs()[:light_sets] if light_sets else light_pairs()
    return ({"exhaustive": exhaustive(ev, groups).best.weights(ev.n_leds),
             "pso": pso(ev, groups, pso_settings, seed=0).best.weights(ev.n_leds)},
            "noise-free optima of this setup")
