"""The two packaged LED tables describe one sphere (issue 40): the absolute table is the relative one (the source of
every simulated figure) times LED 2's absolute peak, as tools/derive_leds.py writes it; the light dose and the
virtual spectroradiometer (which scales the relative table by LED 2's ratio) therefore agree LED by LED."""
from __future__ import annotations

import numpy as np

from dualrgb import resources
from dualrgb.simulation.spectral_io import read_spectral_csv
from tools.derive_leds import LED2_ABSOLUTE_PEAK, derive


def test_the_absolute_table_is_the_relative_one_times_led_2s_peak_at_every_led():
    rel = read_spectral_csv(resources.path("leds", "sphere10_relative.csv"))
    absolute = read_spectral_csv(resources.path("leds", "sphere10_absolute.csv"))
    assert np.array_equal(rel.wavelengths, absolute.wavelengths) and rel.columns == absolute.columns
    ratio = absolute.values.max(axis=0) / rel.values.max(axis=0)               # per LED: one constant for all
    assert np.allclose(ratio, LED2_ABSOLUTE_PEAK, rtol=1e-7)
    big = rel.values > 1e-6 * rel.values.max()
    assert np.allclose(absolute.values[big], rel.values[big] * LED2_ABSOLUTE_PEAK, rtol=1e-7)
    assert "derived_from" in absolute.meta and "sphere10_relative.csv" in absolute.meta["derived_from"]


def test_the_packaged_absolute_table_is_what_the_tool_writes(tmp_path):
    out = tmp_path / "absolute.csv"
    derive(resources.path("leds", "sphere10_relative.csv"), out)
    assert out.read_bytes() == resources.path("leds", "sphere10_absolute.csv").read_bytes()


def test_light_dose_and_the_spectroradiometers_unit_are_the_same_sphere():
    from dualrgb.core.session.light_dose import lux_per_led
    from dualrgb.drivers.virtual.sphere_light import radiance_per_relative_unit

    assert np.isclose(radiance_per_relative_unit(), LED2_ABSOLUTE_PEAK, rtol=1e-7)
    rel = read_spectral_csv(resources.path("leds", "sphere10_relative.csv"))
    import colour

    shape = colour.SpectralShape(rel.wavelengths[0], rel.wavelengths[-1], 1)
    ybar = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape).values[:, 1]
    lux = 683.0 * np.pi * (rel.values * radiance_per_relative_unit() * ybar[:, None]).sum(axis=0)
    assert np.allclose(lux_per_led(), lux, rtol=1e-6)
