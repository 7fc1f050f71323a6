"""``dualrgb study thesis``: a small run (seconds) against the committed full run, an independent colour-science
check of the committed figures, and the docs page's generated table.

Tolerances (stated here, not tuned to pass): the exhaustive search, the 3-channel baseline, the thesis' lights'
exposures and the predicted errors of fixed lights are deterministic, so the small run must reproduce the full
run to 1e-6; a short PSO / GA (20 particles x 3 iterations; GA mu 8, lambda 40, 3 generations) may stop above the
thesis budget's optimum but not below it (0.002 slack for the float32 search cost) and within 0.2 dE00 of it; the
ND 2.0 HDR captures are a Monte Carlo (2 repeats here, 6 in the full run, same seeds) and must agree within four
combined standard errors. Table 7.2's captured column is the virtual lab in the full run and the pixel-level
simulation in the small one: different capture chains, not compared here (the stability study compares them).
"""
import json

import colour
import numpy as np
import pytest

from dualrgb import resources
from dualrgb.simulation.studies.thesis import ThesisConfig, load_thesis_tables, reproduce
from dualrgb.simulation.studies.thesis_report import (
    DOC_PAGE,
    README_END,
    README_START,
    build_rows,
    markdown,
    replace_between_markers,
)

DETERMINISTIC = 1e-6


@pytest.fixture(scope="module")
def committed():
    data = json.loads(resources.path("thesis_reproduction.json").read_text(encoding="utf-8"))
    assert data["format"] == "dualrgb-thesis-reproduction/1" and data["config"]["budget"] == "full"
    return data


@pytest.fixture(scope="module")
def small():
    return reproduce(ThesisConfig.small())


@pytest.mark.parametrize("mode", ["transmissive", "reflective"])
def test_small_run_reproduces_the_deterministic_figures(small, committed, mode):
    s, c = small["figures"][mode], committed["figures"][mode]
    assert s["three_channel"] == c["three_channel"]
    assert s["thesis_pair_rank"] == c["thesis_pair_rank"]
    for a, b in zip(s["exhaustive_top"], c["exhaustive_top"], strict=True):
        assert a["sources"] == b["sources"]
        assert a["train"] == pytest.approx(b["train"], abs=DETERMINISTIC)
        assert a["test"] == pytest.approx(b["test"], abs=DETERMINISTIC)


def test_small_run_reproduces_exposures_and_predictions_of_fixed_lights(small, committed):
    s, c = small["figures"]["transmissive"], committed["figures"]["transmissive"]
    for a, b in zip(s["exposures"]["7.1"], c["exposures"]["7.1"], strict=True):
        assert a["model_s"] == pytest.approx(b["model_s"], rel=DETERMINISTIC)
    for key in ("8.1", "8.2"):
        for light, v in c["exposures"][key].items():
            assert s["exposures"][key][light]["model_s"] == pytest.approx(v["model_s"], rel=DETERMINISTIC)
    for cond in ("three_channel", "full_intensity"):            # same lights in both runs: the same prediction
        assert s["captures"][cond]["predicted"] == pytest.approx(c["captures"][cond]["predicted"], abs=DETERMINISTIC)


@pytest.mark.parametrize("mode,method", [("transmissive", "pso"), ("transmissive", "ga"), ("reflective", "pso")])
def test_short_optimisers_stop_at_or_above_the_full_budget_optimum(small, committed, mode, method):
    short, full = small["figures"][mode][method]["train"], committed["figures"][mode][method]["train"]
    assert full - 0.002 <= short <= full + 0.2


def test_hdr_monte_carlo_agrees_within_its_standard_errors(small, committed):
    s, c = small["figures"]["transmissive"]["hdr"], committed["figures"]["transmissive"]["hdr"]
    for lights in ("full_intensity", "pso"):
        for merge in c["merges"]:
            if lights == "pso" and small["figures"]["transmissive"]["pso"]["sources"] != \
                    committed["figures"]["transmissive"]["pso"]["sources"]:
                continue                                      # a short PSO may stop on other lights
            a, b = s[lights][merge], c[lights][merge]
            for k in ("train", "test"):
                assert abs(a[k] - b[k]) <= 4 * np.hypot(a[f"{k}_se"], b[f"{k}_se"])


def _de00_by_hand(mode: str, sources: list[list[int]]) -> tuple[float, float]:
    """Independent of the project's simulation: colour-science's CMFs, D65 and CIEDE2000, numpy's lstsq, the
    packaged CSVs read with numpy, linear interpolation to 410-780 nm at 10 nm (thesis 4.5), eq 4.2 and 5.10."""
    wl = np.arange(410.0, 781.0, 10.0)

    def table(*parts):
        lines = [ln for ln in resources.path(*parts).read_text().splitlines() if ln and not ln.startswith("#")]
        data = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
        return np.stack([np.interp(wl, data[:, 0], data[:, i]) for i in range(1, data.shape[1])], axis=1)

    shape = colour.SpectralShape(410, 780, 10)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape).values
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape).values
    leds, cam = table("leds", "sphere10_relative.csv"), table("cameras", "nikon_5100_npl.csv")
    files = {"transmissive": ("film_train_it87_288.csv", "film_test_cc24.csv"),
             "reflective": ("reflective_train_rawtoaces190.csv", "reflective_test_babelcolor_cc24.csv")}[mode]
    k = 100.0 / (d65 @ cmfs[:, 1])
    white = k * d65 @ cmfs
    out = {}
    for role, f in zip(("train", "test"), files, strict=True):
        T = table("targets", f)                                       # (wl, patches)
        light = [leds[:, np.asarray(s) - 1].sum(axis=1) for s in sources]
        out[role] = (np.concatenate([(T.T * li) @ cam for li in light], axis=1), k * (T.T * d65) @ cmfs)
    A = np.linalg.lstsq(out["train"][0], out["train"][1], rcond=None)[0]
    wxy = colour.XYZ_to_xy(white / white[1])

    def de(role):
        V, xyz = out[role]
        lab = [colour.XYZ_to_Lab(x / white[1], wxy) for x in (xyz, V @ A)]
        return float(colour.delta_E(lab[0], lab[1], method="CIE 2000").mean())

    return de("train"), de("test")


@pytest.mark.parametrize("mode", ["transmissive", "reflective"])
def test_committed_exhaustive_optimum_matches_an_independent_computation(committed, mode):
    best = committed["figures"][mode]["exhaustive_top"][0]
    train, test = _de00_by_hand(mode, best["sources"])
    assert best["train"] == pytest.approx(train, abs=1e-3) and best["test"] == pytest.approx(test, abs=1e-3)


def test_the_docs_show_the_table_generated_from_the_committed_run(committed):
    tables = load_thesis_tables()["tables"]
    table = markdown(build_rows(tables, committed["figures"]), committed, tables)
    page = resources.path().parent / DOC_PAGE
    if not page.is_file():
        pytest.skip(f"{DOC_PAGE} is not beside the package (installed wheel)")
    text = page.read_text(encoding="utf-8")
    assert replace_between_markers(text, table, DOC_PAGE) == text, \
        f"{DOC_PAGE}'s thesis table is not the one `dualrgb study thesis --doc {DOC_PAGE}` writes from the " \
        "committed run"
    assert text.count(README_START) == 1 and text.count(README_END) == 1
