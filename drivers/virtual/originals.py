"""Originals for the virtual copy stand: objects that are not charts, with a per-pixel ground truth.

Three originals, registered by name in :data:`ORIGINALS`:

* ``painting`` (reflective): a small landscape with a figure: flat colour fields, smooth gradients (sky,
  field, a grey ramp), fine lines (a hatched strip, a fence, a diagonal hatch), a near-white and a dark area,
  and a row of "flowers" in the 15 saturated NIST CQS samples;
* ``film`` (transmissive): a slide frame in the three-dye Beer-Lambert film model of ``simulation.film_model``
  (the same dyes as the packaged film targets): the clear-base rebate (near-white), a frame line, gradients in
  dye amount (sky, ground, a neutral wedge), colour fields, fine lines and a dense (dark) area;
* ``shadow`` (reflective): a chiaroscuro still life whose deep shadow (the darkest paint mixed with a perfect
  absorber, ~0.1 % reflectance: ~10 DN above black in a frame that puts the open gate at 80 % of the linear
  limit) lies beside near-white areas, so the scene spans ~1000:1 and needs an HDR bracket (thesis 8).

Spectra (all measured, as shipped by colour-science, resampled linearly to the simulation grid like every
target; see :func:`measured_spectra`):

* ``SDS_TCS['CIE 1995']`` TCS01-TCS14: the CIE 13.3 colour-rendering test samples (Munsell samples of moderate
  chroma, strong red / yellow / green / blue, skin, leaf green), 360-830 nm;
* ``SDS_VS['NIST CQS 9.0']`` VS1-VS15: the NIST Colour Quality Scale's saturated Munsell samples, 360-830 nm;
* ``SDS_COLOURCHECKERS['ColorChecker N Ohta']`` neutrals (white 9.5, neutral 8 / 6.5 / 5 / 3.5, black 2),
  380-780 nm: Ohta's measurement, not the BabelColor average the test chart uses.

They are independent of both the training target (rawtoaces-190) and the test target (BabelColor CC24), so
an original is out-of-sample like the test chart. PMC (400-700 nm) misses a fifth of the 410-780 nm grid and
Munsell renotations are colorimetric, not spectral: neither is used.

Model (no spectral work per pixel): an original is a *palette* of classes, each one spectrum, and a class map
painted from strokes. Every class is a convex mix of at most two measured spectra (a flat field is one, a
gradient step is ``(1 - t) a + t b``, a deep shadow is ``w a`` mixed with a perfect absorber), or for the
film the Beer-Lambert transmittance of one dye triplet (a gradient interpolates dye amounts; the
transmittance is computed exactly per class). Gradients are quantised to ``RAMP_STEPS`` classes, and the
ground truth is that of the quantised class, so the rendering and the truth describe the same object: there
is no modelling error, only a gradient made of 1/128 steps (< 0.5 dE00 between neighbours).

Geometry: strokes are placed in fractions of the frame and painted on the *superpixel* grid (one class per
2x2 Bayer cell, cell (i, j) = sensor rows 2i, 2i+1 and columns 2j, 2j+1), so every Bayer cell is one material
and the processing's superpixels (R, mean G, B of a cell, no demosaic) see no colour fringes: the truth binned
to superpixels is exact. Fine lines are 1 superpixel (2 sensor pixels) wide at every frame size. Rows go down,
columns right, as the sensor (and the DNG, orientation "horizontal") stores them.
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from dualrgb.simulation.colorimetry import tristimulus
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid, resample

log = logging.getLogger(__name__)

Box = tuple[float, float, float, float]      # top, left, bottom, right: fractions of the frame height / width
RAMP_STEPS = 128                             # classes per gradient
_MAX_CLASSES = np.iinfo(np.uint16).max


# ---------------------------------------------------------------- strokes (painted on the superpixel grid)
def _span(box: Box, h2: int, w2: int) -> tuple[slice, slice]:
    """Superpixel rows / columns of ``box`` (at least one of each)."""
    top, left, bottom, right = box
    r0, c0 = int(round(top * h2)), int(round(left * w2))
    return slice(r0, max(int(round(bottom * h2)), r0 + 1)), slice(c0, max(int(round(right * w2)), c0 + 1))


@dataclass(frozen=True)
class Fill:
    """A rectangle of one class."""

    box: Box
    cls: int

    def paint(self, cmap: np.ndarray) -> None:
        rs, cs = _span(self.box, *cmap.shape)
        cmap[rs, cs] = self.cls


@dataclass(frozen=True)
class Ellipse:
    """The ellipse inscribed in ``box``, one class."""

    box: Box
    cls: int

    def paint(self, cmap: np.ndarray) -> None:
        rs, cs = _span(self.box, *cmap.shape)
        y = np.arange(rs.start, rs.stop) + 0.5
        x = np.arange(cs.start, cs.stop) + 0.5
        cy, cx = (rs.start + rs.stop) / 2, (cs.start + cs.stop) / 2
        ry, rx = (rs.stop - rs.start) / 2, (cs.stop - cs.start) / 2
        inside = ((y[:, None] - cy) / ry) ** 2 + ((x[None, :] - cx) / rx) ** 2 <= 1.0
        block = cmap[rs, cs]
        block[inside] = self.cls


@dataclass(frozen=True)
class Ramp:
    """A gradient across ``box``: ``classes`` in order along ``axis`` ('v' top to bottom, 'h' left to right)."""

    box: Box
    classes: tuple[int, ...]
    axis: str = "h"

    def paint(self, cmap: np.ndarray) -> None:
        rs, cs = _span(self.box, *cmap.shape)
        ids = np.asarray(self.classes, dtype=np.uint16)
        n = (rs.stop - rs.start) if self.axis == "v" else (cs.stop - cs.start)
        steps = ids[(np.arange(n) * len(ids)) // n]
        cmap[rs, cs] = steps[:, None] if self.axis == "v" else steps[None, :]


@dataclass(frozen=True)
class Lines:
    """Fine lines over ``box``: ``width`` superpixels every ``period`` ('h' rows, 'v' columns, 'd' diagonal)."""

    box: Box
    cls: int
    period: int = 4
    width: int = 1
    direction: str = "v"

    def paint(self, cmap: np.ndarray) -> None:
        rs, cs = _span(self.box, *cmap.shape)
        i = np.arange(rs.stop - rs.start)[:, None]
        j = np.arange(cs.stop - cs.start)[None, :]
        k = {"h": i + 0 * j, "v": j + 0 * i, "d": i + j}[self.direction]
        block = cmap[rs, cs]
        block[k % self.period < self.width] = self.cls


Stroke = Fill | Ellipse | Ramp | Lines


# ---------------------------------------------------------------- the original
@dataclass(frozen=True, eq=False)
class Original:
    """An object for the virtual copy stand: a palette of spectra and the strokes that paint its class map.

    ``spectra`` (n_classes, n_wl) are reflectances (``mode`` 'reflective') or transmittances ('transmissive')
    on ``grid``; ``regions`` name uniform areas (boxes in fractions of the frame) with their class, for
    metering and tests. Frozen and compared by identity; class maps are cached per frame size.
    """

    name: str
    mode: str
    title: str
    spectra: np.ndarray
    class_names: tuple[str, ...]
    strokes: tuple[Stroke, ...]
    regions: dict[str, tuple[Box, int]]
    grid: SpectralGrid = DEFAULT_GRID
    sources: str = ""
    _maps: dict = field(default_factory=dict, repr=False, compare=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    @property
    def n_classes(self) -> int:
        return self.spectra.shape[0]

    def class_map(self, height: int, width: int) -> np.ndarray:
        """(height // 2, width // 2) uint16 class of every superpixel (2x2 Bayer cell); cached, read-only."""
        if height < 8 or width < 8 or height % 2 or width % 2:
            raise ValueError(f"original {self.name!r} at {width}x{height}: expected an even number of pixels >= 8 "
                             "each way (Bayer 2x2 cells)")
        key = (height // 2, width // 2)
        with self._lock:                                   # the GUI's preview and a capture may ask at once
            if key not in self._maps:
                cmap = np.zeros(key, dtype=np.uint16)
                for stroke in self.strokes:
                    stroke.paint(cmap)
                cmap.flags.writeable = False
                if len(self._maps) >= 2:                   # a 24 MP map is 12 MB: keep the last two sizes
                    self._maps.pop(next(iter(self._maps)))
                self._maps[key] = cmap
            return self._maps[key]

    def labels(self, row_idx: np.ndarray, col_idx: np.ndarray, height: int, width: int) -> np.ndarray:
        """Class of sensor pixels (row_idx x col_idx, an outer product) of a ``height`` x ``width`` frame.

        A Bayer plane (``arange(p, H, 2)``) gets the class map itself (no copy, shared by the four planes).
        """
        cmap = self.class_map(height, width)
        r = np.asarray(row_idx) // 2
        c = np.asarray(col_idx) // 2
        whole_r = r.size == cmap.shape[0] and np.array_equal(r, np.arange(cmap.shape[0]))
        whole_c = c.size == cmap.shape[1] and np.array_equal(c, np.arange(cmap.shape[1]))
        if whole_r and whole_c:
            return cmap
        return cmap[(slice(None) if whole_r else r[:, None]), (slice(None) if whole_c else c[None, :])]

    def class_spectra(self, n_wavelengths: int) -> np.ndarray:
        if self.spectra.shape[1] != n_wavelengths:
            raise ValueError(f"original {self.name!r} is on {self.grid.label()} ({self.spectra.shape[1]} samples) "
                             f"but the camera's grid has {n_wavelengths}; build it with original(name, grid)")
        return self.spectra

    def palette_xyz(self, illuminant: np.ndarray, cmfs: np.ndarray) -> np.ndarray:
        """(n_classes, 3) eq 4.2 XYZ of every class (Y of a perfect white / clear film = 100), float64."""
        return tristimulus(self.spectra, illuminant, cmfs)

    def ground_truth_xyz(self, height: int, width: int, illuminant: np.ndarray, cmfs: np.ndarray) -> np.ndarray:
        """(height, width, 3) float32 XYZ of every sensor pixel (each 2x2 Bayer cell is one class)."""
        cells = self.palette_xyz(illuminant, cmfs).astype(np.float32)[self.class_map(height, width)]
        out = np.empty((cells.shape[0], 2, cells.shape[1], 2, 3), dtype=np.float32)     # (even sizes checked)
        out[...] = cells[:, None, :, None, :]                    # each 2x2 Bayer cell is one class
        return out.reshape(2 * cells.shape[0], 2 * cells.shape[1], 3)

    def region_boxes(self, height: int, width: int) -> dict[str, tuple[int, int, int, int]]:
        """Named uniform areas as sensor-pixel boxes (row0, row1, col0, col1), half-open, on even pixels."""
        out = {}
        for key, (box, _cls) in self.regions.items():
            rs, cs = _span(box, height // 2, width // 2)
            out[key] = (2 * rs.start, 2 * rs.stop, 2 * cs.start, 2 * cs.stop)
        return out

    def region_class(self, key: str) -> int:
        return self.regions[key][1]

    def describe(self) -> dict[str, object]:
        return {"original": self.name, "mode": self.mode, "title": self.title, "classes": self.n_classes,
                "spectra": self.sources}


class _Palette:
    """Collects the classes of an original: each a name and a spectrum (built by mixing measured spectra)."""

    def __init__(self) -> None:
        self.spectra: list[np.ndarray] = []
        self.names: list[str] = []

    def add(self, name: str, spectrum: np.ndarray) -> int:
        if len(self.spectra) >= _MAX_CLASSES:
            raise ValueError(f"an original holds at most {_MAX_CLASSES} classes")
        self.spectra.append(np.asarray(spectrum, dtype=float))
        self.names.append(name)
        return len(self.spectra) - 1

    def ramp(self, name: str, a: ArrayLike, b: ArrayLike, steps: int = RAMP_STEPS,
             to_spectrum: Callable[[np.ndarray], np.ndarray] = lambda x: x) -> tuple[int, ...]:
        """``steps`` classes from a to b: ``to_spectrum((1 - t) a + t b)`` (a, b spectra, or film dye amounts)."""
        t = np.linspace(0.0, 1.0, steps)
        return tuple(self.add(f"{name} {k + 1}/{steps}", to_spectrum((1 - tk) * np.asarray(a) + tk * np.asarray(b)))
                     for k, tk in enumerate(t))

    def build(self, name: str, mode: str, title: str, strokes: Sequence[Stroke], regions: dict[str, tuple[Box, int]],
              grid: SpectralGrid, sources: str) -> Original:
        spectra = np.vstack(self.spectra)
        spectra.flags.writeable = False
        return Original(name, mode, title, spectra, tuple(self.names), tuple(strokes), dict(regions), grid, sources)


# ---------------------------------------------------------------- measured spectra
MEASURED_SOURCES = ("colour-science SDS_TCS['CIE 1995'] (TCS01-TCS14), SDS_VS['NIST CQS 9.0'] (VS1-VS15), "
                    "SDS_COLOURCHECKERS['ColorChecker N Ohta'] neutrals")
OHTA_NEUTRALS = {"white 9.5": "white 9.5 (.05 D)", "neutral 8": "neutral 8 (.23 D)",
                 "neutral 6.5": "neutral 6.5 (.44 D)", "neutral 5": "neutral 5 (.70 D)",
                 "neutral 3.5": "neutral 3.5 (1.05 D)", "black 2": "black 2 (1.5 D)"}


@lru_cache(maxsize=4)
def measured_spectra(grid: SpectralGrid = DEFAULT_GRID) -> dict[str, np.ndarray]:
    """The measured reflectances originals are mixed from, resampled to ``grid`` (read-only arrays).

    Keys: 'TCS01'..'TCS14', 'VS1'..'VS15', and the Ohta neutrals 'white 9.5', 'neutral 8', ..., 'black 2'.
    """
    import colour
    from colour.quality import SDS_TCS, SDS_VS

    sds = dict(SDS_TCS["CIE 1995"].items())
    sds.update(SDS_VS["NIST CQS 9.0"].items())
    ohta = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    sds.update({short: ohta[full] for short, full in OHTA_NEUTRALS.items()})
    out = {}
    for key, sd in sds.items():
        v = resample(sd.wavelengths, sd.values, grid)
        v.flags.writeable = False
        out[key] = v
    return out


# ---------------------------------------------------------------- the registry
FILM_SOURCES = ("three-dye Beer-Lambert film model of simulation/film_model.py (the packaged film targets' dyes); "
                "modelled, not measured")


def _film_transmittance(grid: SpectralGrid) -> Callable[[ArrayLike], np.ndarray]:
    """Dye amounts (c, m, y) -> transmittance on ``grid``, the packaged film targets' model."""
    from dualrgb.simulation.film_model import film_transmittance

    wl = grid.wavelengths
    return lambda amounts: film_transmittance(np.asarray(amounts, float)[None, :], wl)[:, 0]


def _row(box: Box, classes: Sequence[int]) -> list[Fill]:
    """Equal blocks side by side across ``box``, one per class."""
    top, left, bottom, right = box
    w = (right - left) / len(classes)
    return [Fill((top, left + k * w, bottom, left + (k + 1) * w), c) for k, c in enumerate(classes)]


def _painting(grid: SpectralGrid) -> Original:
    """A landscape with a figure; regions: near-white (sun), dark (pool), red (coat), skin (face)."""
    m, p = measured_spectra(grid), _Palette()
    white, black = m["white 9.5"], m["black 2"]
    ground = p.add("ground: TCS01", m["TCS01"])
    cls = {k: p.add(f"{label}: {k}", m[k]) for k, label in (
        ("white 9.5", "sun"), ("black 2", "pool, fence"), ("TCS14", "hill"), ("VS13", "far hill"),
        ("TCS02", "house"), ("VS1", "roof"), ("TCS13", "face"), ("TCS09", "coat"), ("TCS05", "path"),
        ("neutral 3.5", "hatching"), ("TCS12", "diagonal hatching"), ("TCS07", "tree"))}
    flowers = [p.add(f"flower: VS{k}", m[f"VS{k}"]) for k in range(1, 16)]
    sky = p.ramp("sky: TCS06 -> white 9.5", m["TCS06"], white)
    field = p.ramp("field: TCS11 -> TCS10", m["TCS11"], m["TCS10"])
    greys = p.ramp("grey ramp: black 2 -> white 9.5", black, white)
    strokes: list[Stroke] = [
        Fill((0, 0, 1, 1), ground), Ramp((0, 0, 0.42, 1), sky, "v"),
        Ellipse((0.06, 0.70, 0.26, 0.84), cls["white 9.5"]),
        Ellipse((0.30, 0.40, 0.62, 1.0), cls["VS13"]), Ellipse((0.32, 0.0, 0.62, 0.62), cls["TCS14"]),
        Ramp((0.52, 0, 0.84, 1), field, "h"),
        Fill((0.36, 0.05, 0.56, 0.25), cls["TCS02"]), Fill((0.30, 0.04, 0.36, 0.26), cls["VS1"]),
        Ellipse((0.12, 0.28, 0.50, 0.40), cls["TCS07"]),
        Fill((0.58, 0.04, 0.82, 0.22), cls["black 2"]),
        Fill((0.56, 0.25, 0.62, 0.42), cls["TCS05"]),
        Lines((0.56, 0.25, 0.70, 0.42), cls["black 2"], period=4, width=1, direction="v"),
        Ellipse((0.28, 0.44, 0.40, 0.51), cls["TCS13"]), Fill((0.40, 0.43, 0.70, 0.52), cls["TCS09"]),
        Lines((0.52, 0.55, 0.68, 0.98), cls["TCS12"], period=6, width=1, direction="d"),
        *_row((0.70, 0.55, 0.82, 0.98), flowers),
        Fill((0.86, 0, 1, 0.45), cls["TCS05"]),
        Lines((0.86, 0, 1, 0.45), cls["neutral 3.5"], period=3, width=1, direction="h"),
        Ramp((0.86, 0.5, 1, 1), greys, "h"),
    ]
    regions = {"near-white": ((0.10, 0.73, 0.22, 0.81), cls["white 9.5"]),
               "dark": ((0.61, 0.06, 0.79, 0.20), cls["black 2"]),
               "red": ((0.45, 0.44, 0.66, 0.51), cls["TCS09"]),
               "skin": ((0.31, 0.46, 0.37, 0.49), cls["TCS13"])}
    return p.build("painting", "reflective", "Landscape with a figure (virtual painting)", strokes, regions, grid,
                   MEASURED_SOURCES)


FILM_NEUTRAL = np.array([1.0, 0.93, 0.88])          # dye ratio of a neutral grey (the film targets' grey scale)


def _film(grid: SpectralGrid) -> Original:
    """A slide in a clear-base rebate; regions: near-white (rebate), dark (dense shadow), highlight, skin."""
    t, p = _film_transmittance(grid), _Palette()
    dye: dict[str, ArrayLike] = {
        "clear base": (0, 0, 0), "frame line": 1.6 * FILM_NEUTRAL, "dense shadow": 1.5 * FILM_NEUTRAL,
        "highlight": 0.03 * FILM_NEUTRAL, "skin": (0.2, 0.45, 0.55), "lines": 1.1 * FILM_NEUTRAL,
        "red": (0.05, 1.0, 0.9), "green": (0.9, 0.1, 0.9), "blue": (1.0, 0.8, 0.05),
        "cyan": (1.0, 0.05, 0.1), "magenta": (0.05, 1.0, 0.05), "yellow": (0.05, 0.05, 1.0)}
    cls = {k: p.add(f"{k}: c, m, y = {tuple(round(float(x), 3) for x in np.asarray(a))}", t(a))
           for k, a in dye.items()}
    sky = p.ramp("sky", (0.9, 0.45, 0.05), (0.15, 0.1, 0.05), to_spectrum=t)
    ground = p.ramp("ground", (0.7, 0.2, 1.1), (0.2, 0.6, 1.2), to_spectrum=t)
    wedge = p.ramp("neutral wedge", (0, 0, 0), 1.5 * FILM_NEUTRAL, to_spectrum=t)
    colours = [cls[k] for k in ("red", "green", "blue", "cyan", "magenta", "yellow")]
    strokes: list[Stroke] = [
        Fill((0, 0, 1, 1), cls["clear base"]), Fill((0.09, 0.05, 0.91, 0.95), cls["frame line"]),
        Ramp((0.10, 0.06, 0.45, 0.94), sky, "v"), Ramp((0.45, 0.06, 0.76, 0.94), ground, "h"),
        Fill((0.14, 0.70, 0.30, 0.88), cls["highlight"]),
        Lines((0.12, 0.08, 0.40, 0.40), cls["cyan"], period=5, width=1, direction="d"),
        Fill((0.50, 0.10, 0.72, 0.30), cls["dense shadow"]),
        Ellipse((0.48, 0.44, 0.72, 0.58), cls["skin"]),
        Lines((0.50, 0.64, 0.74, 0.92), cls["lines"], period=3, width=1, direction="v"),
        Ramp((0.78, 0.06, 0.90, 0.58), wedge, "h"), *_row((0.78, 0.60, 0.90, 0.94), colours),
    ]
    regions = {"near-white": ((0.015, 0.20, 0.07, 0.80), cls["clear base"]),
               "dark": ((0.53, 0.12, 0.69, 0.28), cls["dense shadow"]),
               "highlight": ((0.16, 0.72, 0.28, 0.86), cls["highlight"]),
               "skin": ((0.55, 0.48, 0.65, 0.54), cls["skin"])}
    return p.build("film", "transmissive", "Slide in its rebate (virtual film frame)", strokes, regions, grid,
                   FILM_SOURCES)


DEEP_SHADOW = 0.03          # the deep shadow: black 2 mixed with 97 % perfect absorber (~0.1 % reflectance)


def _shadow(grid: SpectralGrid) -> Original:
    """A chiaroscuro still life; regions: near-white (cloth), deep shadow, dark (black 2), red (apple)."""
    m, p = measured_spectra(grid), _Palette()
    white, black = m["white 9.5"], m["black 2"]
    deep = p.add(f"deep shadow: black 2 x {DEEP_SHADOW}", DEEP_SHADOW * black)
    cls = {k: p.add(f"{label}: {k}", m[k]) for k, label in (
        ("white 9.5", "table cloth"), ("black 2", "dark wall"), ("TCS09", "apple"), ("TCS10", "lemon"),
        ("TCS04", "jug"))}
    cloth = p.add(f"blue cloth in shadow: TCS12 x {DEEP_SHADOW * 2:g}", 2 * DEEP_SHADOW * m["TCS12"])
    falloff = p.ramp("light fall-off: black 2 -> deep shadow", black, DEEP_SHADOW * black)
    lit = p.ramp("lit wall: white 9.5 -> black 2", white, black)
    strokes: list[Stroke] = [
        Fill((0, 0, 1, 1), deep), Ramp((0, 0, 0.65, 0.22), lit, "h"),
        Fill((0, 0.22, 0.65, 0.35), cls["black 2"]), Ramp((0, 0.35, 0.65, 0.58), falloff, "h"),
        Fill((0.65, 0, 1, 0.58), cls["white 9.5"]),
        Ellipse((0.40, 0.05, 0.68, 0.22), cls["TCS09"]), Ellipse((0.46, 0.24, 0.66, 0.38), cls["TCS10"]),
        Fill((0.20, 0.40, 0.66, 0.50), cls["TCS04"]),
        Fill((0.30, 0.62, 0.58, 0.96), cloth),
        Lines((0.05, 0.62, 0.25, 0.96), cls["white 9.5"], period=6, width=1, direction="v"),
    ]
    regions = {"near-white": ((0.72, 0.05, 0.95, 0.50), cls["white 9.5"]),
               "deep shadow": ((0.66, 0.64, 0.95, 0.95), deep),
               "dark": ((0.08, 0.24, 0.27, 0.33), cls["black 2"]),
               "red": ((0.47, 0.09, 0.61, 0.18), cls["TCS09"])}
    return p.build("shadow", "reflective", "Still life in deep shadow (virtual HDR original)", strokes, regions,
                   grid, MEASURED_SOURCES)


ORIGINALS: dict[str, Callable[[SpectralGrid], Original]] = {"painting": _painting, "film": _film, "shadow": _shadow}


@lru_cache(maxsize=16)
def original(name: str, grid: SpectralGrid = DEFAULT_GRID) -> Original:
    """The registered original ``name`` on ``grid`` (built once, then shared)."""
    if name not in ORIGINALS:
        raise ValueError(f"unknown original {name!r}: expected one of {', '.join(ORIGINALS)}")
    return ORIGINALS[name](grid)


def ground_truth_xyz(name: str, height: int, width: int, grid: SpectralGrid = DEFAULT_GRID,
                     illuminant: np.ndarray | None = None, cmfs: np.ndarray | None = None) -> np.ndarray:
    """(height, width, 3) float32 per-pixel XYZ of original ``name`` (eq 4.2: D65, CIE 1931 2 degree,
    410-780 nm; Y of a perfect white, or of the open gate for film, = 100), rows down, columns right."""
    if illuminant is None or cmfs is None:
        from dualrgb.simulation.datasets import default_setup

        setup = default_setup("reflective", grid)
        illuminant = setup.illuminant if illuminant is None else illuminant
        cmfs = setup.cmfs if cmfs is None else cmfs
    return original(name, grid).ground_truth_xyz(int(height), int(width), illuminant, cmfs)


# ---------------------------------------------------------------- the copy stand
ORIGINAL_PREFIX = "original:"


def original_name(what: str) -> str:
    """'original:painting' or 'painting' -> 'painting' (a registered name), else a one-line ValueError."""
    name = what[len(ORIGINAL_PREFIX):] if what.startswith(ORIGINAL_PREFIX) else what
    if name not in ORIGINALS:
        raise ValueError(f"unknown original {what!r}: expected {', '.join(ORIGINAL_PREFIX + n for n in ORIGINALS)}")
    return name
