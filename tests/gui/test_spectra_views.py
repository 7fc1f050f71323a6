"""The GUI's spectra (issue 21), offscreen: a click on a patch of the Results view shows its estimated and
reference spectra; the Originals' Delivered tab shows a delivered cube under a chosen light (re-rendered in the
compute pool when the light changes) and a clicked pixel's spectrum read from the delivered cube."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, Qt
from spectral_profiles import estimator, spectral_profile, stack

from dualrgb.app.gui.results_plots import CELL, PatchSpectra, TargetPlots, TargetView
from dualrgb.app.workflow.delivery.delivered_view import open_delivered
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver
from tests.gui.conftest import HANG_GUARD_MS, wait_idle

WL = np.arange(410.0, 790.0, 10.0)


def click_image(qtbot, widget, item, x: float, y: float) -> None:
    """A real left click on image coordinates (x, y) of a pyqtgraph image widget."""
    pos = widget.mapFromScene(item.mapToScene(QPointF(x, y)))
    qtbot.mouseClick(widget.viewport(), Qt.LeftButton, pos=pos)


def target_view(n: int = 6) -> TargetView:
    rng = np.random.default_rng(1)
    ref = rng.uniform(0.05, 0.9, (n, len(WL)))
    est = ref + rng.normal(0, 0.02, ref.shape)
    rmse = np.sqrt(np.mean((est - ref) ** 2, axis=1))
    lab = rng.uniform(0, 50, (n, 3))
    return TargetView("test", [f"patch {k}" for k in range(n)], rng.uniform(0, 2, n), lab, lab + 1,
                      rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, (n, 3)), (2, 3),
                      PatchSpectra(WL, ref, est, rmse, "wiener", "reflectance factor"))


def test_a_clicked_patch_shows_its_estimated_and_reference_spectra(qtbot):
    plots = TargetPlots()
    qtbot.addWidget(plots)
    plots.resize(900, 900)
    plots.show()
    view = target_view()
    plots.show_view(view)
    assert plots.patch == int(np.argmax(view.errors))                    # the worst patch first
    qtbot.waitExposed(plots)
    click_image(qtbot, plots.mosaic_widget, plots.mosaic_item, 2 * CELL + CELL / 2, 1 * CELL + CELL / 2)
    qtbot.waitUntil(lambda: plots.patch == 5, timeout=HANG_GUARD_MS)               # row 1, column 2 of a 2 x 3 target
    (label_r, ref, _, dashed_r), (label_e, est, _, dashed_e) = plots.spectra.curves
    assert np.array_equal(ref, view.spectra.reference[5]) and np.array_equal(est, view.spectra.estimate[5])
    assert not dashed_r and dashed_e and label_e == "estimate" and "wiener" in plots.spectra.title.text()
    assert f"spectral RMSE {view.spectra.rmse[5]:.4f}" in plots.spectra.title.text()
    click_image(qtbot, plots.heat_widget, plots.heat_item, 0.5, 0.5)    # the heat map: one unit per patch
    qtbot.waitUntil(lambda: plots.patch == 0, timeout=HANG_GUARD_MS)


def test_without_spectra_the_view_says_so(qtbot):
    plots = TargetPlots()
    qtbot.addWidget(plots)
    view = target_view()
    view.spectra = None
    plots.show_view(view)
    assert plots.spectra.curves == [] and "no spectral estimate" in plots.spectra.title.text()


def test_the_delivered_view_renders_under_a_light_and_shows_a_pixel(qtbot, make_window, tmp_path):
    prof = spectral_profile(tmp_path)
    s = stack(40, 60)
    d = deliver(s, prof, Original("ACC-3"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord())
    w = make_window()
    dv = w.originals.delivered
    dv.show_delivery(d.sidecar)
    qtbot.waitUntil(lambda: dv.view is not None, timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w)
    d65 = dv.image.image.copy()
    assert d65.shape == (40, 60, 3) and d65.dtype == np.uint8
    assert np.array_equal(d65, open_delivered(d.sidecar).render("D65"))    # the workflow's rendering
    dv.illuminant.setCurrentIndex(dv.illuminant.findData("A"))
    qtbot.waitUntil(lambda: dv.shown_light == "A", timeout=HANG_GUARD_MS)
    assert np.array_equal(dv.image.image, open_delivered(d.sidecar).render("A"))
    qtbot.waitExposed(dv)
    click_image(qtbot, dv.image_widget, dv.image, 7.5, 3.5)
    qtbot.waitUntil(lambda: dv.pixel == (3, 7), timeout=HANG_GUARD_MS)
    (_, values, _, _), = dv.spectrum.curves
    ref = estimator().apply(s.data[3, 7].astype(np.float64))
    assert np.allclose(values, ref, atol=1e-4) and "x 7, y 3" in dv.spectrum.title.text()
