"""The 24 MP delivery's stage split, two-core floor and overhead as `make bench` writes and prints them
(bench/delivery_stages.py, issue 41): the arithmetic, checked on made-up stage costs."""
from __future__ import annotations

import pytest

from bench.delivery_stages import floor_summary, summary_lines

STAGES = {"decode_last_frame": 0.05, "merge_flat": 0.2, "demosaic": 0.04, "tiff_writing": 0.06, "sha256": 0.5,
          "sidecar_and_folder": 0.01, "colour_encodings_linear": 0.3, "colour_encodings_root-polynomial-2": 0.5}
DECODE = {"seconds": 0.34, "cpu_s": 0.4}
FULL = {"seconds": 0.65, "cpu_s": 1.3, "load_1min": [0.2, 0.3]}


def test_the_floor_is_the_last_decode_plus_half_of_the_rest():
    d = floor_summary(DECODE, STAGES, FULL, "linear")
    rest = 0.2 + 0.04 + 0.06 + 0.5 + 0.01 + 0.3
    assert d["floor_s"] == pytest.approx(0.05 + rest / 2, abs=1e-3)
    assert d["floor_vs_decode"] == pytest.approx((0.05 + rest / 2) / 0.34, abs=1e-3)
    assert d["stage_sum_cpu_s"] == pytest.approx(0.05 + rest, abs=1e-3)
    assert d["groups_cpu_s"] == {"decode": 0.05, "pixel_work": 0.24, "encode": 0.3, "hashing": 0.5, "io": 0.07}
    assert sum(d["groups_cpu_s"].values()) == pytest.approx(d["stage_sum_cpu_s"], abs=1e-3)
    assert d["overhead_cpu_s"] == pytest.approx(1.3 - (0.05 + rest), abs=1e-3)
    assert d["cpu_projection"]["two_core_s"] == pytest.approx(0.05 + (1.3 - 0.05) / 2, abs=1e-3)
    assert d["cpu_projection"]["vs_decode_cpu"] == pytest.approx((0.05 + 1.25 / 2) / 0.4, abs=1e-3)
    assert d["met"] == {"vs_decode": True, "cpu_vs_stage_sum": True}


def test_each_model_brings_its_own_encodings_and_a_miss_is_said():
    d = floor_summary(DECODE, STAGES, {**FULL, "seconds": 0.9, "cpu_s": 2.0}, "root-polynomial-2")
    assert d["stages_cpu_s"]["colour_encodings"] == 0.5 and d["groups_cpu_s"]["encode"] == 0.5
    assert d["met"] == {"vs_decode": False, "cpu_vs_stage_sum": False}


def test_make_bench_prints_the_split_the_floor_and_the_overhead():
    result = {"frame": "6080x4028", "decode_s": 0.34, "cpu_decode_s": 0.4, "load_average_1min": [0.1, 0.4],
              "delivery": floor_summary(DECODE, STAGES, FULL, "linear")}
    text = "\n".join(summary_lines(result))
    for said in ("sha256 0.500", "hashing 0.500", "pixel_work 0.240", "two-core floor", "= 0.605 s",
                 "overhead 0.140 CPU-s", "gap 0.045 s"):
        assert said in text
