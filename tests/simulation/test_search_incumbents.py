"""Re-optimising never reports lights its own objective rates worse than the lights in use: the incumbents
(simulation.search.add_incumbents, run(..., incumbents=)) are costed by the search's objective and ranked among its
candidates; and a stand model's setup is on the mode's grid, the one the optimiser and the virtual lab use."""
from __future__ import annotations

import numpy as np

from dualrgb import resources
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.presets import load_preset
from dualrgb.simulation.runner import run
from dualrgb.simulation.search import add_incumbents, exhaustive, light_pairs
from dualrgb.simulation.stand_model import StandModel


def test_an_incumbent_better_than_the_search_ranks_first_and_keeps_its_cost():
    setup = default_setup("reflective")
    ev = Evaluator(setup)
    outcome = exhaustive(ev, light_pairs()[:5])                  # a poor search: 5 full-intensity pairs
    preset = load_preset(resources.path("presets", "reflective_pso.json"))
    found = outcome.best.train_cost
    add_incumbents(ev, outcome, [preset.sources, preset.sources[:1]])    # a one-light set is not comparable
    W = np.stack([s.weights(setup.leds.shape[0]) for s in preset.sources])[None]
    assert outcome.best.sources == preset.sources and outcome.best.train_cost < found
    assert outcome.best.train_cost == float(ev.cost(W)[0]) and len(outcome.candidates) == 6
    costs = [c.train_cost for c in outcome.candidates]
    assert costs == sorted(costs)


def test_run_keeps_the_incumbent_only_when_the_search_finds_nothing_better():
    setup = default_setup("reflective")
    preset = load_preset(resources.path("presets", "reflective_pso.json"))
    full = load_preset(resources.path("presets", "reflective_exhaustive.json"))
    kept = run(setup, "exhaustive", top=1, objective="noise-free", incumbents=[preset.sources])
    assert kept.preset().sources[0].leds == preset.sources[0].leds          # PSO levels beat every full-intensity set
    beaten = run(setup, "exhaustive", top=1, objective="noise-free",
                 incumbents=[(full.sources[0], full.sources[0])])             # a poor incumbent: the search's best
    assert beaten.preset().sources[0].leds == full.sources[0].leds and \
        beaten.preset().sources[1].leds != full.sources[0].leds


def test_a_stand_models_setup_is_on_the_modes_grid():
    for mode in ("reflective", "transmissive"):
        assert np.array_equal(StandModel().setup(mode).grid.wavelengths, default_grid(mode).wavelengths)
    assert StandModel().setup("transmissive").grid.start == 380.0
