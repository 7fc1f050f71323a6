"""The CLI's copy-stand options in the window (issue 30): the rendering light (``--render-illuminant``), the
deliverables' sampling (``capture`` / ``process --ppi``), the calibration's sampling (``calibrate --ppi``,
``--target-width-mm``) and the resolution (``--resolution full|half``).

Each is a widget whose value is remembered in the GUI's settings (``dualrgb.ini``, key under ``options/``) and is
handed to the workflow through the same fields of app.workflow.stand.copystand.StandSettings (and the same arguments of
app.workflow.delivery.redelivery.redeliver) that the CLI fills from its options: nothing here interprets them.
"""
from __future__ import annotations

import logging
from typing import Any

from PySide6.QtWidgets import QComboBox, QDoubleSpinBox, QFormLayout, QLineEdit, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.processing.masters import RESOLUTION_CHOICES
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT
from dualrgb.simulation.other_lights import light_keys
from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

RENDER_KEY = "options/render_illuminant"
PPI_KEY = "options/ppi"                          # the deliverables' (capture / process --ppi); 0: the calibration's
CAL_PPI_KEY = "options/calibration_ppi"          # calibrate --ppi; 0: from the target's width or its grid
TARGET_WIDTH_KEY = "options/target_width_mm"     # calibrate --target-width-mm; 0: not given
CAMERA_CSV_KEY = "options/camera_csv"            # calibrate --camera-csv (Tools: Measure the camera); '': nominal
STAND_DIR_KEY = "options/stand_dir"              # calibrate --stand-dir (Tools: Measure the LEDs); '': nominal
RESOLUTION_KEY = "originals/resolution"          # the Originals panel's "Deliver at" (already remembered there)
MAX_PPI = 20000.0
MAX_TARGET_MM = 5000.0


def render_combo(ctx: AppContext) -> QComboBox:
    """The rendering light: simulation.other_lights' keys (D65, D50, A, FL11, LED), remembered."""
    combo = QComboBox()
    for key, name in light_keys().items():
        combo.addItem(key if key == name else f"{key} ({name})", key)
    combo.setCurrentIndex(max(0, combo.findData(ctx.get(RENDER_KEY, DEFAULT_RENDER_ILLUMINANT, str))))
    combo.setToolTip("The light the spectral cube's rendering is seen under: <id>_under_<LIGHT>_prophoto_16bit.tif "
                     "at half resolution, named in the sidecar for the cube made on demand at full resolution. The "
                     "colorimetric masters are D50/D65 as always.")
    combo.currentIndexChanged.connect(lambda _i: ctx.set(RENDER_KEY, combo.currentData()))
    return combo


def resolution_combo(ctx: AppContext) -> QComboBox:
    """Full / half resolution (``--resolution``), the same remembered choice as the Originals panel's."""
    combo = QComboBox()
    for key, label in RESOLUTION_CHOICES.items():
        combo.addItem(label, key)
    combo.setCurrentIndex(max(0, combo.findData(ctx.get(RESOLUTION_KEY, "full", str))))
    combo.setToolTip("Full: the sensor's pixels; half: one pixel per 2x2 Bayer cell (no interpolation).")
    combo.currentIndexChanged.connect(lambda _i: ctx.set(RESOLUTION_KEY, combo.currentData()))
    return combo


def number_spin(ctx: AppContext, key: str, top: float, suffix: str, zero_text: str, tip: str) -> QDoubleSpinBox:
    """A remembered positive number; 0 shows ``zero_text`` and means "not given" (the CLI's option left out)."""
    spin = QDoubleSpinBox()
    spin.setRange(0.0, top)
    spin.setDecimals(1)
    spin.setSuffix(suffix)
    spin.setSpecialValueText(zero_text)
    spin.setValue(min(max(ctx.get(key, 0.0, float), 0.0), top))
    spin.setToolTip(tip)
    spin.valueChanged.connect(lambda v: ctx.set(key, float(v)))
    return spin


def path_edit(ctx: AppContext, key: str, placeholder: str, tip: str) -> QLineEdit:
    """A remembered file or folder path ('' : not given)."""
    edit = QLineEdit(ctx.get(key, "", str))
    edit.setPlaceholderText(placeholder)
    edit.setToolTip(tip)
    edit.setClearButtonEnabled(True)
    edit.textChanged.connect(lambda t: ctx.set(key, t.strip()))
    return edit


def given(spin: QDoubleSpinBox) -> float | None:
    """The spin's value, or None where it shows its "not given" text (0)."""
    return float(spin.value()) if spin.value() > 0 else None


def rows(parent: QWidget, *pairs: tuple[str, QWidget]) -> None:
    """``parent``'s layout: a form of (label, widget) rows without margins (they sit inside another form)."""
    form = QFormLayout(parent)
    form.setContentsMargins(0, 0, 0, 0)
    for label, widget in pairs:
        form.addRow(label, widget)


class DeliveryOptions(QWidget):
    """Rows of the Originals form: the rendering light and the deliverables' ppi (``dualrgb capture``)."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.render_light = render_combo(ctx)
        self.ppi = number_spin(ctx, PPI_KEY, MAX_PPI, "\u00a0ppi", "the calibration's",
                               "Sampling written into the deliverables; leave at the "
                               "calibration's (from its test target) unless the stand's scale is known otherwise.")
        rows(self, ("Rendering light", self.render_light), ("Sampling", self.ppi))

    def stand_fields(self) -> dict[str, Any]:
        """The StandSettings fields these set, as ``dualrgb capture`` fills them."""
        return {"render_illuminant": str(self.render_light.currentData()), "ppi": given(self.ppi)}


class CalibrationSampling(QWidget):
    """Rows of the calibration box: ``calibrate --ppi``, ``--target-width-mm`` and the measured curves the stand
    fit starts from (``--camera-csv``, ``--stand-dir``; the Tools panel's measurements offer theirs)."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.camera_csv = path_edit(ctx, CAMERA_CSV_KEY, "nominal camera curves",
                                    "Empty: the nominal camera curves. A camera CSV (Tools > Measure the camera): the "
                                    "stand model fitted to the captures starts from the camera's measured "
                                    "sensitivities.")
        self.stand_dir = path_edit(ctx, STAND_DIR_KEY, "nominal LEDs",
                                   "Empty: the nominal LEDs. A stand folder (Tools > Measure the LEDs): the LEDs' "
                                   "measured spectra and level curves are "
                                   "the stand model's starting curves; an LED set below the measured minimum "
                                   "stable level is warned about.")
        self.target_width = number_spin(ctx, TARGET_WIDTH_KEY, MAX_TARGET_MM, "\u00a0mm", "not measured",
                                        "The test target's width, outer corners of its corner patches: the"
                                        " calibration's ppi follows from it.")
        self.ppi = number_spin(ctx, CAL_PPI_KEY, MAX_PPI, "\u00a0ppi", "from the target",
                               "The sensor's sampling at the object plane; it overrides "
                               "the target's width.")
        rows(self, ("Test target width", self.target_width), ("Sampling", self.ppi),
             ("Measured camera", self.camera_csv), ("Measured LEDs", self.stand_dir))

    def showEvent(self, event: Any) -> None:
        """What the Tools panel chose to use meanwhile (saved in the settings) shows when the box does."""
        for edit, key in ((self.camera_csv, CAMERA_CSV_KEY), (self.stand_dir, STAND_DIR_KEY)):
            edit.setText(self.ctx.get(key, "", str))
        super().showEvent(event)

    def measured(self, lights: Any = ()) -> StandModel | None:
        """The stand model the fit starts from (None: nominal), read and checked now (ValueError naming the
        file); LEDs of ``lights`` set below the stand folder's minimum stable level are logged as warnings."""
        from dualrgb.app.workflow.calibration.stand_reoptimise import measured_start

        camera, stand = self.camera_csv.text().strip(), self.stand_dir.text().strip()
        if stand:
            from dualrgb.app.workflow.calibration.led_stand import load_stand, unstable_levels

            for line in unstable_levels(lights, load_stand(stand)):
                log.warning("%s", line)
        return measured_start(camera or None, stand or None)

    def stand_fields(self) -> dict[str, Any]:
        """The StandSettings fields these set, as ``dualrgb calibrate`` fills them (the measured curves: see
        :meth:`measured`)."""
        return {"ppi": given(self.ppi), "target_width_mm": given(self.target_width)}
