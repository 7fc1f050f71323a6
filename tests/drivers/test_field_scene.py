"""The virtual camera's uniform-field hook (a monochromator's diffused output): the response integrates the field's
radiance against the sensitivities the camera renders with (hand computations), a swapped camera changes it, an
exposure freezes the light as it was, and the exposure log says whether the field emitted."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb import resources
from dualrgb.drivers.raw import load_raw
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.scene import FieldLight, Scene
from dualrgb.simulation.spectral_io import read_spectral_csv

DARK = StaticLight(np.zeros(10), light_on=False)


def camera(scene: Scene, **kw) -> VirtualCamera:
    cam = VirtualCamera(lambda: DARK, scene, **kw)
    cam.open()
    return cam


def field(wl, radiance) -> FieldLight:
    return FieldLight(lambda: (np.asarray(wl, float), np.asarray(radiance, float)))


def test_a_flat_field_on_the_grid_integrates_the_sensitivities():
    cam = camera(Scene.open_gate(64, 48))
    grid = cam.grid.wavelengths
    s = cam.camera_sensitivities
    response = cam.field_response(Scene.uniform_field(field(grid, np.full(len(grid), 2.0)), 64, 48))
    # trapezoid of a piecewise-linear curve on its own nodes, by hand: step * (sum - half the ends), / step
    assert response == pytest.approx(2.0 * (s.sum(axis=0) - (s[0] + s[-1]) / 2), rel=1e-12)


def test_a_narrow_line_sees_the_sensitivity_at_its_wavelength():
    table = read_spectral_csv(resources.path("cameras", "nikon_5100_npl.csv"))       # independently, the CSV
    cam = camera(Scene.open_gate(64, 48))
    for nm in (450.0, 530.0, 600.0):
        wl = np.array([nm - 0.5, nm, nm + 0.5])
        r = cam.field_response(Scene.uniform_field(field(wl, [0.0, 1.0, 0.0]), 64, 48))
        expected = [np.interp(nm, table.wavelengths, table.values[:, c]) for c in range(3)]
        assert r * cam.grid.step / 0.5 == pytest.approx(expected, rel=1e-6, abs=1e-9)


def test_the_camera_it_renders_with_is_swappable(tmp_path):
    table = read_spectral_csv(resources.path("cameras", "nikon_5100_npl.csv"))
    shifted = tmp_path / "shifted.csv"
    rows = "".join(f"{w:g},{','.join(f'{v:.9g}' for v in table.values[i])}\n" for i, w in
                   enumerate(table.wavelengths + 7.0))
    shifted.write_text("wavelength_nm,red,green,blue\n" + rows)
    wl = np.array([529.5, 530.0, 530.5])
    scene = Scene.uniform_field(field(wl, [0.0, 1.0, 0.0]), 64, 48)
    nominal, moved = camera(scene).field_response(scene), camera(scene, camera_csv=shifted).field_response(scene)
    assert moved * 20 == pytest.approx([np.interp(523.0, table.wavelengths, table.values[:, c]) for c in range(3)],
                                       rel=1e-3)
    assert not np.allclose(nominal, moved)


def test_an_exposure_freezes_the_light_and_is_logged_lit(tmp_path):
    state = {"on": True}
    wl = np.arange(540.0, 560.01, 0.25)
    light = FieldLight(lambda: (wl, np.clip(1 - np.abs(wl - 550) / 8, 0, None) * (0.05 if state["on"] else 0)))
    cam = camera(Scene.uniform_field(light, 64, 48, vignetting=0.0))
    exposure = cam.expose(0.25)
    state["on"] = False                                  # the shutter closes before the download
    raw = cam.fetch(exposure)
    dark = cam.fetch(cam.expose(0.25))
    assert [e.lit for e in cam.exposure_log] == [True, False]
    (tmp_path / "a.dng").write_bytes(raw.data)
    (tmp_path / "b.dng").write_bytes(dark.data)
    lit, unlit = load_raw(tmp_path / "a.dng"), load_raw(tmp_path / "b.dng")
    assert lit.plane("G1").mean() > unlit.plane("G1").mean() + 1000
    assert abs(np.median(unlit.plane("G1")) - 600) < 2            # median: the hot pixels aside


def test_a_field_scene_needs_its_light_and_has_no_class_spectra():
    with pytest.raises(ValueError, match="needs its FieldLight"):
        Scene(kind="field", width=64, height=48)
    with pytest.raises(ValueError, match="emits its own light"):
        Scene.uniform_field(field([500, 510], [1, 1]), 64, 48).class_spectra(38)
