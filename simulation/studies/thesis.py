"""The thesis' tables reproduced with the project's own code paths (``dualrgb study thesis``).

For each simulation and capture table of the thesis (Tables 5.1, 6.1, 6.2, 7.1, 7.2, 8.1, 8.2, 9.1, 9.2; the
values transcribed in ``resources/thesis_tables.json``), the figure the project computes in the matching mode
(Chapters 5-8: photographic film = transmissive; Chapter 9: reflective), on the thesis' grid (410-780 nm at
10 nm, thesis 4.5) and with the thesis' methods:

* Tables 5.1 / 9.1: the full-intensity exhaustive search over the 630 binned pairs (simulation.search);
* Tables 6.1 / 6.2 / 9.2: the 3-channel baseline under D65, that search's best, the thesis PSO (Algorithm 1:
  200 particles, 10 iterations, C0 0.95, C1 = C2 = 2) and the (mu + lambda) GA (Algorithm 2), noise-free cost;
* Table 7.1: the exposure the capture model gives each of the thesis' own lights (simulation.studies.noise;
  its radiometric scale is calibrated on the table's first row);
* Table 7.2: the project's own optima captured: predicted (the expected captured error, simulation
  .expected_error, of the virtual lab's capture) and captured (the virtual lab through DNGs and the processing
  when a ``capture`` is given, else the pixel-level capture simulation of simulation.studies.noise);
* Tables 8.1 / 8.2: the HDR bracket the model gives the thesis' lights (open-gate exposure and 100x, as the
  parsimony and HDR studies) and the ND 2.0 chart captured as an HDR bracket (pixel-level simulation) with eq 8.9
  and with the mode's default merge.

Each comparison row carries one line saying why the figures differ (data set, synthetic film, thesis
inconsistency, capture against simulation) or that they agree within the thesis' rounding. Output and docs
table: :mod:`.thesis_report`.
"""
from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dualrgb import resources
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.datasets import SimulationSetup, default_setup
from dualrgb.simulation.ga import GaSettings
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.hdr_estimators import HDR_THESIS, default_method
from dualrgb.simulation.pso import PsoSettings
from dualrgb.simulation.runner import RunResult, run
from dualrgb.simulation.search import Candidate
from dualrgb.simulation.studies.noise import NoiseModel

log = logging.getLogger(__name__)

TABLES_FORMAT = "dualrgb-thesis-tables/1"
THESIS_GRID = SpectralGrid(410.0, 780.0, 10.0)          # thesis 4.5
ND_TRANSMITTANCE = 0.01                                 # ND 2.0 over half the chart (thesis 8.3)
HDR_SPAN = 100.0                                        # the bracket the parsimony and HDR studies use
Capture = Callable[[SimulationSetup, np.ndarray, np.ndarray], dict]


@dataclass(frozen=True)
class ThesisConfig:
    """``full``: the thesis' budgets (the committed reference run); ``small``: a few seconds of CPU for tests."""

    pso: PsoSettings = PsoSettings()                     # thesis 6.2.4
    ga: GaSettings = GaSettings()
    seed: int = 0
    repeats: int = 6                                     # simulated captures per condition (Monte Carlo)
    budget: str = "full"

    @classmethod
    def small(cls) -> ThesisConfig:
        return cls(pso=PsoSettings(particles=20, iterations=3), ga=GaSettings(mu=8, lam=40, generations=3),
                   repeats=2, budget="small")


def load_thesis_tables() -> dict:
    """The transcribed thesis values (resources/thesis_tables.json)."""
    path = resources.path("thesis_tables.json")
    data = json.loads(path.read_text(encoding="utf-8"))
    if data.get("format") != TABLES_FORMAT:
        raise ValueError(f"{path}: format {data.get('format')!r}, expected {TABLES_FORMAT!r}")
    return data


def weights_of(sources: list[tuple[list[int], list[float]]], n_leds: int = 10) -> np.ndarray:
    """(L, K) weights of lights given as (LEDs, levels), LEDs 1-based as in the thesis."""
    W = np.zeros((len(sources), n_leds))
    for i, (leds, levels) in enumerate(sources):
        W[i, np.asarray(leds) - 1] = levels
    return W


def table_lights(entry: dict) -> np.ndarray:
    """The (L, K) weights of a thesis table entry with source1/2 and levels1/2."""
    return weights_of([(entry["source1"], entry.get("levels1", [1.0] * 3)),
                       (entry["source2"], entry.get("levels2", [1.0] * 3))])


def candidate_dict(c: Candidate) -> dict:
    """Pair, levels and float64 noise-free errors of a reported candidate."""
    return {"sources": [list(s.leds) for s in c.sources], "levels": [list(s.levels) for s in c.sources],
            "train": c.train_errors.mean, "test": c.test_errors.mean,
            "train_median": c.train_errors.median, "test_median": c.test_errors.median}


@dataclass
class ModeRuns:
    setup: SimulationSetup
    exhaustive: RunResult
    pso: RunResult
    ga: RunResult | None
    seconds: dict = field(default_factory=dict)

    def rank_of(self, pair: list[list[int]]) -> int:
        """1-based rank of a light pair in the exhaustive search (the search's own float32 cost order)."""
        want = {tuple(pair[0]), tuple(pair[1])}
        for i, c in enumerate(self.exhaustive.outcome.candidates if self.exhaustive.outcome else []):
            if {tuple(s.leds) for s in c.sources} == want:
                return i + 1
        raise ValueError(f"light pair {pair} is not among the binned pairs")


def mode_runs(mode: str, cfg: ThesisConfig, with_ga: bool) -> ModeRuns:
    """The exhaustive search, the thesis PSO and (``with_ga``) the GA on ``mode``'s packaged data, noise-free."""
    setup = default_setup(mode, THESIS_GRID)
    seconds = {}
    out = {}
    for method in ("exhaustive", "pso", *(("ga",) if with_ga else ())):
        t0 = time.perf_counter()
        out[method] = run(setup, method, seed=cfg.seed, top=3, objective="noise-free", pso_settings=cfg.pso,
                          ga_settings=cfg.ga)
        seconds[method] = time.perf_counter() - t0
    return ModeRuns(setup, out["exhaustive"], out["pso"], out.get("ga"), seconds)


def search_figures(runs: ModeRuns, tables: dict, full_table: str) -> dict:
    """Tables 5.1 / 9.1 (and the search half of 6.1 / 9.2): the project's exhaustive top 3, its PSO and GA
    optima, the 3-channel baseline, and the rank of the thesis' best full-intensity pair."""
    ex = runs.exhaustive.outcome
    assert ex is not None and runs.pso.outcome is not None
    thesis_best = tables[full_table]["rows"][0]
    return {"three_channel": runs.exhaustive.three_channel,
            "exhaustive_top": [candidate_dict(c) for c in ex.candidates[:3]],
            "thesis_pair_rank": runs.rank_of([thesis_best["source1"], thesis_best["source2"]]),
            "pso": candidate_dict(runs.pso.outcome.best),
            **({"ga": candidate_dict(runs.ga.outcome.best)} if runs.ga and runs.ga.outcome else {}),
            "light_sets": len(ex.candidates), "seconds": runs.seconds}


def exposures_figures(setup: SimulationSetup, tables: dict) -> dict:
    """Tables 7.1, 8.1, 8.2: the capture model's open-gate exposure of each of the thesis' lights and the 100x
    bracket of the HDR studies, beside the thesis' times."""
    model = NoiseModel(setup, CaptureModel.virtual_lab(setup.mode).camera)
    t71 = [{"light": r["light"], "thesis_s": r["exposure_s"],
            "model_s": float(model.exposures(weights_of([(r["leds"], r["levels"])]))[0])}
           for r in tables["7.1"]["rows"]]
    hdr = {}
    for key in ("8.1", "8.2"):
        t = model.exposures(table_lights(tables[key]["lights"]))
        hdr[key] = {f"light {i + 1}": {"thesis_s": tables[key]["exposures_s"][f"light {i + 1}"],
                                       "model_s": [float(t[i]), float(t[i] * HDR_SPAN)]} for i in range(2)}
    return {"7.1": t71, **hdr}


def capture_lights(runs: ModeRuns) -> dict[str, np.ndarray]:
    """The project's counterparts of the thesis' captured conditions: the sphere's D65 mix (3-channel), the
    exhaustive best and the PSO best, realised on the sphere's level grid (as the virtual lab sets them)."""
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
    from dualrgb.simulation.sphere import realisable_d65_mix

    s = runs.setup
    ev = ExpectedErrorEvaluator(s, CaptureModel.virtual_lab(s.mode))
    mix, _ = realisable_d65_mix(s.leds, s.illuminant, s.cmfs, ev.capture.sphere)
    assert runs.exhaustive.outcome is not None and runs.pso.outcome is not None
    lights = {"three_channel": mix.weights(s.leds.shape[0])[None],
              "full_intensity": runs.exhaustive.outcome.best.weights(s.leds.shape[0]),
              "pso": runs.pso.outcome.best.weights(s.leds.shape[0])}
    return {k: ev.realise(W) for k, W in lights.items()}


def capture_figures(runs: ModeRuns, cfg: ThesisConfig, capture: Capture | None) -> dict:
    """Table 7.2: per condition, predicted (expected captured, mean and median) and captured (virtual lab if
    ``capture`` else the pixel-level simulation; mean with its standard error over repeats)."""
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator

    s = runs.setup
    ev = ExpectedErrorEvaluator(s, CaptureModel.virtual_lab(s.mode))
    model = NoiseModel(s, ev.capture.camera)
    out: dict[str, Any] = {"captured_by": "virtual lab (DNGs through the processing; mean ± standard error over "
                                          "its captures)" if capture else
                           f"pixel-level capture simulation (simulation.studies.noise, {cfg.repeats} captures)"}
    for name, W in capture_lights(runs).items():
        tr, te = ev.expected_stats(W)
        got = capture(s, W, model.exposures(W)) if capture else model.captured_errors(W, cfg.repeats)
        n = max(int(got.get("repeats", 1)), 1)
        out[name] = {"leds": [[int(i) + 1 for i in np.nonzero(w)[0]] for w in W],
                     "levels": [w[w > 0].tolist() for w in W],
                     "predicted": {"mean_train": tr.mean, "median_train": tr.median, "mean_test": te.mean,
                                   "median_test": te.median},
                     "captured": {"mean_train": got["train"], "mean_test": got["test"],
                                  "mean_train_se": got["train_sd"] / np.sqrt(max(n - 1, 1)),
                                  "mean_test_se": got["test_sd"] / np.sqrt(max(n - 1, 1)), "repeats": n}}
    return out


def hdr_figures(runs: ModeRuns, cfg: ThesisConfig) -> dict:
    """Section 8.3: the ND 2.0 chart captured as a 1x + 100x bracket (pixel-level simulation), merged with eq 8.9
    and with the mode's default merge, for the project's full-intensity and PSO optima."""
    s = runs.setup
    model = NoiseModel(s, CaptureModel.virtual_lab(s.mode).camera)
    half = {k: np.where(np.arange(len(t)) < len(t) // 2, ND_TRANSMITTANCE, 1.0)
            for k, t in (("train", s.train), ("test", s.test))}
    lights = capture_lights(runs)
    merges = list(dict.fromkeys((HDR_THESIS, default_method(s.mode))))
    out: dict[str, Any] = {"merges": merges}
    for name in ("full_intensity", "pso"):
        out[name] = {}
        for m in merges:
            got = model.captured_errors(lights[name], cfg.repeats, factors=(1.0, HDR_SPAN), nd=half, hdr_method=m)
            out[name][m] = {k: got[k] for k in ("train", "test", "train_se", "test_se", "repeats")}
    return out


def reproduce(cfg: ThesisConfig = ThesisConfig(), *, capture: Capture | None = None,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> dict:
    """Every figure the comparison needs, per mode (see the module docstring); JSON-ready."""
    t0 = time.perf_counter()
    tables = load_thesis_tables()["tables"]
    figures: dict[str, Any] = {}
    for i, (mode, full_table) in enumerate((("transmissive", "5.1"), ("reflective", "9.1"))):
        check(cancel)
        runs = mode_runs(mode, cfg, with_ga=mode == "transmissive")
        figures[mode] = search_figures(runs, tables, full_table)
        report(progress, 0.3 + 0.3 * i, f"thesis: {mode} searches")
        if mode == "transmissive":
            check(cancel)
            figures[mode]["exposures"] = exposures_figures(runs.setup, tables)
            figures[mode]["captures"] = capture_figures(runs, cfg, capture)
            figures[mode]["hdr"] = hdr_figures(runs, cfg)
            report(progress, 0.5, "thesis: captures")
    return {"config": asdict(cfg), "grid": THESIS_GRID.label(), "figures": figures,
            "elapsed_s": round(time.perf_counter() - t0, 2)}
