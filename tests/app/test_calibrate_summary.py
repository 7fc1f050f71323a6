"""The calibration's closing line (issue 40): the per-pixel dE00 on the test chart beside the patch means."""
from types import SimpleNamespace

from dualrgb.app.commands.calibrate_summary import summary_lines


def _profile(statistics):
    return SimpleNamespace(id="cal-x", statistics=statistics, matrix=SimpleNamespace(method="least-squares"))


def test_the_first_line_gives_the_per_pixel_error_beside_the_patch_means():
    stats = {"best": "least-squares", "methods": {"least-squares": {"train": {"mean": 0.511}, "test": {"mean": 0.326}}},
             "per_pixel_de00": {"train": {"mean": 0.854, "p90": 1.35}, "test": {"mean": 0.897, "p90": 1.647}}}
    first = summary_lines(_profile(stats))[0]
    assert first == ("calibration cal-x: test chart mean dE00 0.33 (training chart 0.51), per pixel test 0.90 / p90 "
                     "1.65, least-squares matrix")


def test_a_profile_without_per_pixel_figures_keeps_the_patch_means_only():
    stats = {"best": "least-squares", "methods": {"least-squares": {"train": {"mean": 0.5}, "test": {"mean": 0.3}}}}
    assert summary_lines(_profile(stats))[0] == ("calibration cal-x: test chart mean dE00 0.30 (training chart 0.50), "
                                                 "least-squares matrix")
