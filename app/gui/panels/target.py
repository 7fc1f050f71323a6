"""Target: the captured colour target with a draggable 4-corner patch grid (rows x cols), the sampled part of
every patch outlined; automatic ColorChecker detection when app.processing.patches can do it."""
from __future__ import annotations

import logging

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF, Qt
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.viewmodel import display_rgb
from dualrgb.app.gui.widgets import image_widget, side_by_side
from dualrgb.app.processing.patches import PatchGrid, detect_cc24
from dualrgb.app.processing.report import layout_for
from dualrgb.app.workflow.calibration.session_processing import subject_entries
from dualrgb.core.vocabulary import Subject, SubjectKind

log = logging.getLogger(__name__)

def target_first(key: str) -> tuple[int, int, str]:
    """Sort order of the shown subjects: the test target, the training target, then originals."""
    subject = Subject.parse(key)
    if subject.kind is SubjectKind.TARGET:
        return (0, 0 if subject.name == "test" else 1, key)
    return (1, 0, key)


class TargetPanel(QWidget):
    title = "Target"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        self.ws = ctx.workspace
        self.subjects: dict[str, dict[str, list]] = {}
        self.image: np.ndarray | None = None          # linear superpixel RGB of the shown frame
        self.grid: PatchGrid | None = None
        self.roi: pg.PolyLineROI | None = None
        self.info = QLabel("Drag the four corner handles onto the outer corners of the corner patches "
                           "(top-left patch first, clockwise).")
        self.info.setWordWrap(True)
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(self._frame_box())
        ll.addWidget(self._grid_box())
        ll.addWidget(self.info)
        ll.addStretch(1)
        side_by_side(self, left, self._picture())
        self.lab.sessionChanged.connect(self.reload)
        ctx.bus.sessionUpdated.connect(self.reload)
        self.reload()

    # ------------------------------------------------------------------ builders
    def _frame_box(self) -> QGroupBox:
        box = QGroupBox("Frame")
        form = QFormLayout(box)
        self.subject = QComboBox()
        self.subject.setToolTip("Which captured target (or original) to show and place the grid on.")
        self.subject.currentIndexChanged.connect(self._subject_chosen)
        self.light = QComboBox()
        self.light.setToolTip("Which light's frame to show (the grid is the same for all).")
        self.light.currentIndexChanged.connect(lambda _i: self.load_frame())
        self.reload_button = QPushButton("Reload from session")
        self.reload_button.setToolTip("List the targets captured in the session again.")
        self.reload_button.clicked.connect(self.reload)
        form.addRow("Target", self.subject)
        form.addRow("Light", self.light)
        form.addRow(self.reload_button)
        return box

    def _grid_box(self) -> QGroupBox:
        box = QGroupBox("Patch grid")
        gf = QFormLayout(box)
        self.rows = QSpinBox()
        self.rows.setRange(1, 50)
        self.rows.setToolTip("Patch rows of the target.")
        self.cols = QSpinBox()
        self.cols.setRange(1, 50)
        self.cols.setToolTip("Patch columns of the target.")
        self.fraction = QDoubleSpinBox()
        self.fraction.setRange(0.1, 1.0)
        self.fraction.setSingleStep(0.05)
        self.fraction.setValue(0.5)
        self.fraction.setToolTip("Part of each patch that is measured (the middle), away from edges and gaps.")
        for w in (self.rows, self.cols):
            w.valueChanged.connect(lambda _v: self.update_grid())
        self.fraction.valueChanged.connect(lambda _v: self.update_grid())
        self.reset_button = QPushButton("Reset corners")
        self.reset_button.setToolTip("Put the four corners back to their starting place.")
        self.reset_button.clicked.connect(lambda: self.set_corners(self.default_corners()))
        self.detect_button = QPushButton("Detect ColorChecker")
        self.detect_button.setToolTip("Find a 24-patch ColorChecker automatically (needs the optional "
                                      "colour-checker-detection package).")
        self.detect_button.clicked.connect(self.detect)
        self.place_button = QPushButton("Use this grid")
        self.place_button.setToolTip("Sample this target with the grid as shown. A grid is used only once you "
                                     "place it (drag a corner, change rows or columns, or this button); a "
                                     "target without one is found in its frames when it is processed.")
        self.place_button.clicked.connect(lambda: self.update_grid(place=True))
        gf.addRow("Rows", self.rows)
        gf.addRow("Columns", self.cols)
        gf.addRow("Sampled part", self.fraction)
        row = QHBoxLayout()
        row.addWidget(self.reset_button)
        row.addWidget(self.detect_button)
        row.addWidget(self.place_button)
        gf.addRow(row)
        return box

    def _picture(self) -> QWidget:
        self.view, self.image_item, self.viewbox = image_widget(
            "The target as captured (raw, one light, brightened). Yellow: the grid; green: what is measured.")
        self.cells = pg.PlotDataItem(pen=pg.mkPen("#00e676", width=1), connect="finite")
        self.outline = pg.PlotDataItem(pen=pg.mkPen("#ffd600", width=1, style=Qt.PenStyle.DashLine), connect="finite")
        self.labels: list[pg.TextItem] = []
        self.viewbox.addItem(self.outline)
        self.viewbox.addItem(self.cells)
        return self.view

    # ------------------------------------------------------------------ subjects
    def reload(self) -> None:
        session = self.lab.session
        if session is None:
            self.subject.clear()
            self.info.setText("No session yet: capture a target in Calibrate & capture.")
            return
        self.ctx.runner.submit(lambda: subject_entries(session), pool="compute", name="list targets",
                               on_result=self._fill_subjects,
                               on_error=lambda exc: self.ctx.errors.report("List the targets", exc))

    def _fill_subjects(self, subjects: dict[str, dict[str, list]]) -> None:
        current = self.key()
        self.subjects = subjects
        self.subject.blockSignals(True)
        self.subject.clear()
        for key in sorted(subjects, key=target_first):
            self.subject.addItem(Subject.parse(key).label, key)      # people read labels, the data is the key
        if current in subjects:
            self.select_subject(current)
        elif subjects:                                   # the test target first: never an original with a grid
            self.subject.setCurrentIndex(0)
        self.subject.blockSignals(False)
        if subjects:
            self._subject_chosen()
        else:
            self.info.setText("No target captured in this session yet (Calibrate & capture → Dual-RGB capture).")

    def key(self) -> str:
        """The chosen subject's key ('target:test'); '' when none."""
        return self.subject.currentData() or ""

    def select_subject(self, key: str) -> None:
        i = self.subject.findData(key)
        if i < 0:
            raise ValueError(f"{key!r} is not captured in this session")
        self.subject.setCurrentIndex(i)

    def _subject_chosen(self, *_args) -> None:
        key = self.key()
        lights = self.subjects.get(key, {})
        self.light.blockSignals(True)
        self.light.clear()
        self.light.addItems(list(lights))
        self.light.blockSignals(False)
        self.load_frame()

    def tag(self) -> str:
        """'train' / 'test' for a colour target, else '' (an original)."""
        key = self.key()
        if not key:
            return "test"
        subject = Subject.parse(key)
        return subject.name if subject.kind is SubjectKind.TARGET else ""

    def reference_layout(self, n_default: int = 24) -> tuple[int, int]:
        vl = self.lab.virtual_lab
        chart = self.ws.charts.get(self.tag())          # the stand's own chart (the calibration box's Charts)
        if chart is not None:
            return tuple(chart.layout)
        if vl is not None and self.tag() in ("train", "test"):
            return vl.scene_for(self.tag()).layout
        from dualrgb.simulation.datasets import default_setup
        if self.tag() in ("train", "test"):
            target = getattr(default_setup(self.lab.mode), self.tag())    # no virtual lab: the chosen mode
            return layout_for(len(target), target.layout)
        return layout_for(n_default)

    def reference_geometry(self):
        """Where the chart's patches lie on it (simulation.chart_geometry), when it is a chart the lab draws in its
        real geometry (a ColorChecker Classic, Digital SG, IT8.7); None for the generic grid or no target."""
        from dualrgb.simulation.chart_geometry import geometry_of

        tag, vl = self.tag(), self.lab.virtual_lab
        if tag not in ("train", "test"):
            return None
        chart = self.ws.charts.get(tag)
        if chart is not None:
            geometry = geometry_of(chart)
        elif vl is not None:
            geometry = vl.scene_for(tag).geometry
        else:
            from dualrgb.app.workflow.calibration.targets import chart_of
            geometry = geometry_of(chart_of(self.lab.mode, tag))
        return None if geometry is None or geometry.name == "grid" else geometry

    # ------------------------------------------------------------------ frame
    def load_frame(self) -> None:
        key, light = self.key(), self.light.currentText()
        entries = self.subjects.get(key, {}).get(light, [])
        if not entries:
            return
        session = self.lab.session
        if session is None:
            return
        entry = sorted(entries, key=lambda e: e.exposure_s or 0.0)[0]
        path = session.file_path(entry)

        def work() -> np.ndarray:
            from dualrgb.drivers.raw import load_raw, superpixel
            return superpixel(load_raw(path))

        self.ctx.runner.submit(work, pool="compute", name="load target frame", on_result=self.show_image,
                               on_error=lambda exc: self.ctx.errors.report("Load the target frame", exc))

    def show_image(self, linear: np.ndarray) -> None:
        self.image = linear
        self.image_item.setImage(display_rgb(linear), autoLevels=False, levels=(0, 255))
        self.viewbox.autoRange()
        key = self.key()
        saved = self.ws.grids.get(key)
        rows, cols = (saved.rows, saved.cols) if saved is not None else self.reference_layout()
        for w, v in ((self.rows, rows), (self.cols, cols)):
            w.blockSignals(True)
            w.setValue(v)
            w.blockSignals(False)
        if saved is not None:
            self.set_corners(saved.corners)
        else:                                            # shown, not placed: found in its frames when processed
            self.set_corners(self.default_corners(), place=False)

    def default_corners(self) -> np.ndarray:
        """Where the handles start: the virtual lab's target corners, else 10 % inside the frame."""
        vl = self.lab.virtual_lab
        if vl is not None and self.tag() in ("train", "test"):
            rc = np.asarray(vl.scene_for(self.tag()).corners(), dtype=float)
            return (rc[:, ::-1] + 0.5) * 0.5 - 0.5                  # full mosaic (row, col) -> superpixel (x, y)
        h, w = self.image.shape[:2] if self.image is not None else (100, 150)
        return np.array([[0.1 * w, 0.1 * h], [0.9 * w, 0.1 * h], [0.9 * w, 0.9 * h], [0.1 * w, 0.9 * h]])

    # ------------------------------------------------------------------ grid
    def set_corners(self, corners, place: bool = True) -> None:
        corners = np.asarray(corners, dtype=float).reshape(4, 2)
        if self.roi is not None:
            self.viewbox.removeItem(self.roi)
        self.roi = pg.PolyLineROI([QPointF(float(x), float(y)) for x, y in corners], closed=True,
                                  pen=pg.mkPen("#ffd600", width=2), movable=True)
        self.roi.setToolTip("Drag a corner handle onto the outer corner of a corner patch; drag an edge to move "
                            "the whole grid.")
        self.roi.sigRegionChanged.connect(lambda _r: self.update_grid())
        self.viewbox.addItem(self.roi)
        self.update_grid(place=place)

    def corners(self) -> np.ndarray:
        if self.roi is None:
            return self.default_corners()
        pts = [self.roi.mapToParent(h.pos()) for h in self.roi.getHandles()]
        return np.array([[p.x(), p.y()] for p in pts[:4]])

    def move_handle(self, index: int, x: float, y: float) -> None:
        """What dragging handle ``index`` to image point (x, y) does (used by tests and the screenshot run)."""
        if self.roi is None:                        # no image shown yet: nothing to drag
            return
        handle = self.roi.getHandles()[index]
        self.roi.movePoint(handle, self.roi.mapFromParent(QPointF(x, y)))

    def update_grid(self, place: bool = True) -> None:
        """Draw the grid; ``place``: the technician placed it (a drag, rows or columns, Detect, *Use this grid*),
        so this target is sampled with it (the workspace's grid) instead of being found in its frames."""
        original = bool(self.key()) and not self.tag()
        if self.roi is not None:
            self.roi.setVisible(not original)
        if original:                                    # an original: no patch grid over the painting
            self.cells.setData([], [])
            self.outline.setData([], [])
            self.info.setText(f"{Subject.parse(self.key()).label}: shown as captured (no patch grid: not a target)")
            return
        try:
            geometry = self.reference_geometry()          # a known chart: each cell where its patch is (an IT8)
            boxes = geometry.unit_boxes() if geometry is not None and geometry.layout == (
                self.rows.value(), self.cols.value()) else None
            grid = PatchGrid(self.corners(), self.rows.value(), self.cols.value(), self.fraction.value(),
                             cell_boxes=boxes)
        except ValueError as exc:
            self.info.setText(f"Grid not usable: {exc}")
            self.cells.setData([], [])
            return
        self.grid = grid
        polys = grid.sample_polygons()                                    # (n, 4, 2)
        closed = np.concatenate([polys, polys[:, :1], np.full((len(polys), 1, 2), np.nan)], axis=1)
        xy = closed.reshape(-1, 2)
        self.cells.setData(xy[:, 0], xy[:, 1])
        lines = []
        for r in range(grid.rows + 1):
            lines += [grid.to_image(np.array([[0, r / grid.rows], [1, r / grid.rows]])), np.full((1, 2), np.nan)]
        for c in range(grid.cols + 1):
            lines += [grid.to_image(np.array([[c / grid.cols, 0], [c / grid.cols, 1]])), np.full((1, 2), np.nan)]
        ln = np.concatenate(lines)
        self.outline.setData(ln[:, 0], ln[:, 1])
        key = self.key()
        if key and (place or key in self.ws.grids):
            self.ws.set_grid(key, grid)
        where = Subject.parse(key).label if key else "the frame"
        placed = key in self.ws.grids if key else True
        self.info.setText(f"{grid.rows} x {grid.cols} = {grid.n_patches} patches on the {where}; "
                          f"measuring the middle {100 * grid.fraction:.0f}\u00a0% of each"
                          + ("." if placed else " - not placed: found in its frames when processed "
                             "(drag a corner or Use this grid to place it)."))

    def detect(self) -> None:
        if self.image is None:
            self.ctx.errors.report("Detect the ColorChecker", "load a captured target first")
            return
        image = self.image

        def done(det) -> None:
            if det is None:
                self.ctx.errors.report("Detect the ColorChecker",
                                       "no ColorChecker found (or the optional detector is not installed: "
                                       "pip install 'dualrgb[detect]'); drag the four corners by hand",
                                       level=logging.WARNING)
                return
            self.rows.setValue(det.grid.rows)
            self.cols.setValue(det.grid.cols)
            self.set_corners(det.grid.corners)

        self.ctx.runner.submit(lambda: detect_cc24(image), pool="compute", name="detect ColorChecker",
                               on_result=done, on_error=lambda exc: self.ctx.errors.report("Detect", exc))
