"""The packaged data the simulation runs on, and loading of users' own measured CSVs.

Defaults reproduce the thesis (chapters 4-5): 410-780 nm at 10 nm, CIE 1931 2-degree CMFs, D65,
the 10-LED sphere of Table 4.2, 'Nikon 5100 (NPL)' as the camera, rawtoaces-190 / CC24 (reflective)
and the IT8.7/1-like / CC24-on-film targets (transmissive).
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import colour
import numpy as np

from dualrgb import resources
from dualrgb.simulation.choices import MODES
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid, resample
from dualrgb.simulation.lightsource import N_SPHERE_LEDS
from dualrgb.simulation.spectral_io import SpectralDataError, SpectralTable, read_spectral_csv, require_response

log = logging.getLogger(__name__)

REFERENCE_EQ_4_2 = "eq-4.2"              # target reference XYZ: the thesis' grid sum (target_xyz)
REFERENCE_ASTM_E308 = "astm-e308"        # ... or colour-science's ASTM E308 integration of the measured spectra
REFERENCE_XYZ_METHODS = (REFERENCE_EQ_4_2, REFERENCE_ASTM_E308)
TARGET_FILES = {
    "reflective": ("reflective_train_rawtoaces190.csv", "reflective_test_babelcolor_cc24.csv"),
    "transmissive": ("film_train_it87_288.csv", "film_test_cc24.csv"),
}


@dataclass
class Target:
    """Patch spectra on a grid: ``spectra`` has shape (n_patches, n_wavelengths) (reflectance or transmittance)."""

    name: str
    spectra: np.ndarray
    patch_names: list[str]
    layout: tuple[int, int] | None = None
    source: str = ""
    measured: SpectralTable | None = None     # the spectra as read (own wavelengths), for ASTM E308 references
    extended: str = ""                        # how the grid was reached beyond the measured range ('' = not)
    measured_range: tuple[float, float] | None = None   # first and last wavelength the reference file measured

    def __len__(self) -> int:
        return self.spectra.shape[0]

    def measured_mask(self, wavelengths: np.ndarray) -> np.ndarray | None:
        """Where on ``wavelengths`` the reference was measured (None: everywhere); outside it the spectra are the
        file's end values held (grid.resample), fine for colorimetry, never a spectral figure's reference."""
        return measured_mask(wavelengths, self.measured_range)


def measured_mask(wavelengths: np.ndarray, measured_range: tuple[float, float] | None) -> np.ndarray | None:
    """Boolean mask of ``wavelengths`` inside ``measured_range`` (None: no range known, everything counts)."""
    if measured_range is None:
        return None
    wl = np.asarray(wavelengths, dtype=float)
    return (wl >= measured_range[0] - 1e-9) & (wl <= measured_range[1] + 1e-9)


@dataclass
class SimulationSetup:
    """Everything one simulation needs, resampled to one grid."""

    mode: str
    grid: SpectralGrid
    leds: np.ndarray                # (n_leds, n_wl), relative radiance
    camera: np.ndarray              # (n_wl, 3) R, G, B sensitivities
    illuminant: np.ndarray          # (n_wl,) D65 for ground truth (eq 4.2) and the 3-channel baseline
    cmfs: np.ndarray                # (n_wl, 3)
    train: Target
    test: Target
    camera_name: str = "Nikon 5100 (NPL)"
    led_names: list[str] = field(default_factory=lambda: [f"LED{i}" for i in range(1, 11)])
    reference_xyz: str = REFERENCE_EQ_4_2   # how the targets' reference XYZ are computed (target_xyz)
    flare: float = 0.0              # veiling glare, fraction of the mean signal (camera_model.with_flare)

    def describe(self) -> dict:
        return {"mode": self.mode, "grid": self.grid.label(), "camera": self.camera_name,
                "train": f"{self.train.name} ({len(self.train)})", "test": f"{self.test.name} ({len(self.test)})",
                "leds": len(self.led_names)}


def _layout(meta: dict[str, str]) -> tuple[int, int] | None:
    text = meta.get("layout", "").split()[0] if meta.get("layout") else ""
    if "x" in text:
        rows, cols = text.split("x")
        try:
            return int(rows), int(cols)
        except ValueError:
            return None
    return None


def load_target(path: str | Path, grid: SpectralGrid = DEFAULT_GRID, name: str | None = None) -> Target:
    """A target's measured spectra (reflectance factor or transmittance, one column per patch), resampled to
    ``grid``: a spectral CSV, or a CGATS / X-Rite measurement file (simulation.cgats, recognised by its
    BEGIN_DATA_FORMAT line). The one reader of reference spectra: ``simulate --train-csv``, the calibration's
    charts (simulation.charts) and the packaged targets all come through here.

    Values above 1 are accepted up to 2 (fluorescent samples have reflectance factors above 1). Beyond the
    measured range the grid is reached by holding the end values, at most :data:`MAX_EXTENSION_NM` at either end
    (said in one warning line: :func:`extension_note`); farther is refused.
    """
    table = read_reference_table(path)
    if table.values.max() > 2.0 * (1 + 1e-9):
        raise SpectralDataError(f"{table.source}: value {table.values.max():g} exceeds 2 (reflectance factor)")
    extended = _check_covers(table, grid)
    return Target(name or table.meta.get("title", Path(path).stem), resample(table.wavelengths, table.values, grid).T,
                  table.columns, _layout(table.meta), table.source, table, extended,
                  (float(table.wavelengths[0]), float(table.wavelengths[-1])))


def read_reference_table(path: str | Path) -> SpectralTable:
    """The spectra of a reference file as measured: a CGATS / X-Rite / ArgyllCMS file (``.cie``, ``.ti3``,
    ``.txt``: recognised by its BEGIN_DATA_FORMAT line, simulation.cgats) or a spectral CSV."""
    from dualrgb.simulation.cgats import is_cgats, read_cgats_spectra

    return read_cgats_spectra(path) if is_cgats(path) else read_spectral_csv(path, max_value=2.0)


#: The standard-uncertainty columns a measured camera CSV may carry after R, G, B (``dualrgb measure csrf``).
CAMERA_UNCERTAINTY_COLUMNS = ("u_red", "u_green", "u_blue")


def load_camera(path: str | Path, grid: SpectralGrid = DEFAULT_GRID) -> np.ndarray:
    """A camera sensitivity CSV with three columns (R, G, B), resampled to ``grid``; a measured one may add their
    standard uncertainties as three more columns named :data:`CAMERA_UNCERTAINTY_COLUMNS` (not used here)."""
    table = read_spectral_csv(path)
    extra = [c.strip().lower() for c in table.columns[3:]]
    if len(table.columns) != 3 and tuple(extra) != CAMERA_UNCERTAINTY_COLUMNS:
        raise SpectralDataError(f"{table.source}: expected 3 data columns (R, G, B; optionally followed by "
                                f"{', '.join(CAMERA_UNCERTAINTY_COLUMNS)}), found {len(table.columns)}")
    require_response(table, 3, "camera channel")
    _check_covers(table, grid)
    return resample(table.wavelengths, table.values[:, :3], grid)


def load_leds(path: str | Path, grid: SpectralGrid = DEFAULT_GRID, expected: int | None = None) -> np.ndarray:
    """An LED spectra CSV (one column per LED, LED 1 first), resampled to ``grid``: shape (n_leds, n_wl)."""
    table = read_spectral_csv(path, expected_columns=expected)
    _check_covers(table, grid)
    return resample(table.wavelengths, table.values, grid).T


#: How far beyond a file's measured range the grid may reach (by holding the end value), at either end: vendors'
#: chart references and an i1Pro measure 380-730 nm, 50 nm short of the 780 nm the grids end at.
MAX_EXTENSION_NM = 60.0


def extension_note(table: SpectralTable, grid: SpectralGrid) -> str:
    """How ``grid`` is reached beyond ``table``'s measured range ('' when it lies inside it), e.g.
    '380-730 nm measured; 730-780 nm held at the 730 nm values'."""
    lo, hi = float(table.wavelengths[0]), float(table.wavelengths[-1])
    parts = [f"{grid.start:g}-{lo:g} nm held at the {lo:g} nm values"] if grid.start < lo - 1e-9 else []
    if float(grid.wavelengths[-1]) > hi + 1e-9:
        parts.append(f"{hi:g}-{float(grid.wavelengths[-1]):g} nm held at the {hi:g} nm values")
    return f"{lo:g}-{hi:g} nm measured; {', '.join(parts)}" if parts else ""


def _check_covers(table: SpectralTable, grid: SpectralGrid, max_gap_nm: float = MAX_EXTENSION_NM) -> str:
    """Extrapolation holds the end values, at most ``max_gap_nm`` at either end (farther is refused); an
    extension is said in one warning line (an info line for the packaged data, whose extension the docs state:
    docs/how-to/own-charts.md).
    Returns the note ('' when the grid lies inside the measured range)."""
    lo, hi = table.wavelengths[0], table.wavelengths[-1]
    if lo - grid.start > max_gap_nm or grid.end - hi > max_gap_nm:
        raise SpectralDataError(
            f"{table.source}: covers {lo:g}-{hi:g} nm but the simulation grid is {grid.label()}; at most "
            f"{max_gap_nm:g} nm at either end is extended (by holding the end value)"
        )
    note = extension_note(table, grid)
    if note:
        packaged = Path(table.source).resolve().is_relative_to(resources.path().resolve())
        log.log(logging.INFO if packaged else logging.WARNING, "%s: %s (grid %s)", table.source, note, grid.label())
    return note


@lru_cache(maxsize=16)
def _colorimetry(grid: SpectralGrid) -> tuple[np.ndarray, np.ndarray]:
    shape = colour.SpectralShape(grid.start, float(grid.wavelengths[-1]), grid.step)   # exactly the grid's samples
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    return np.asarray(cmfs.values), np.asarray(d65.values)


def led_spectra(grid: SpectralGrid = DEFAULT_GRID, absolute: bool = False) -> np.ndarray:
    name = "sphere10_absolute.csv" if absolute else "sphere10_relative.csv"
    return load_leds(resources.path("leds", name), grid, expected=10)


@lru_cache(maxsize=16)
def _default_setup(mode: str, grid: SpectralGrid) -> SimulationSetup:
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: expected one of {', '.join(MODES)}")
    train_file, test_file = TARGET_FILES[mode]
    cmfs, d65 = _colorimetry(grid)
    return SimulationSetup(
        mode=mode, grid=grid, leds=led_spectra(grid),
        camera=load_camera(resources.path("cameras", "nikon_5100_npl.csv"), grid),
        illuminant=d65, cmfs=cmfs,
        train=load_target(resources.path("targets", train_file), grid),
        test=load_target(resources.path("targets", test_file), grid),
    )


def default_setup(mode: str = "reflective", grid: SpectralGrid | None = None, *, camera_csv: str | None = None,
                  leds_csv: str | None = None, train_csv: str | None = None,
                  test_csv: str | None = None, reference_xyz: str = REFERENCE_EQ_4_2) -> SimulationSetup:
    """The packaged data for ``mode``, optionally with a user's own measured CSVs replacing parts of it, and the
    way the targets' reference XYZ are computed (``target_xyz``). ``grid`` None: the grid the parsimony study
    chose for the mode (simulation.defaults.default_grid; the thesis' 410-780 nm at 10 nm where it suffices)."""
    check_reference_method(reference_xyz)
    if grid is None:
        from dualrgb.simulation.defaults import default_grid

        grid = default_grid(mode) if mode in MODES else DEFAULT_GRID
    base = _default_setup(mode, grid)
    if reference_xyz != base.reference_xyz:
        base = dataclasses.replace(base, reference_xyz=reference_xyz)
    if not any((camera_csv, leds_csv, train_csv, test_csv)):
        return base
    cmfs, d65 = _colorimetry(grid)
    setup = SimulationSetup(
        mode=mode, grid=grid,
        leds=load_leds(leds_csv, grid, expected=N_SPHERE_LEDS) if leds_csv else base.leds,
        camera=load_camera(camera_csv, grid) if camera_csv else base.camera,
        illuminant=d65, cmfs=cmfs,
        train=load_target(train_csv, grid) if train_csv else base.train,
        test=load_target(test_csv, grid) if test_csv else base.test,
        camera_name=Path(camera_csv).stem if camera_csv else base.camera_name, reference_xyz=reference_xyz,
    )
    check_setup(setup)
    warn_setup(setup)
    return setup


def check_setup(setup: SimulationSetup) -> None:
    """The shapes every fast path relies on (SpectralDataError, one line): spectra on the grid, 3 camera
    channels, the sphere's 10 LEDs, finite values."""
    n_wl = len(setup.grid)
    shapes = {"LED spectra": (setup.leds, 2, 1), "camera sensitivities": (setup.camera, 2, 0),
              "training target": (setup.train.spectra, 2, 1), "test target": (setup.test.spectra, 2, 1)}
    for what, (arr, ndim, axis) in shapes.items():
        arr = np.asarray(arr)
        if arr.ndim != ndim or arr.shape[axis] != n_wl or not np.isfinite(arr).all():
            raise SpectralDataError(f"{what}: shape {arr.shape} does not fit the {n_wl}-sample grid "
                                    f"{setup.grid.label()} (or holds NaN)")
    if np.asarray(setup.camera).shape[1] != 3:
        raise SpectralDataError(f"camera sensitivities: {np.asarray(setup.camera).shape[1]} channels, expected 3")
    if len(setup.leds) != N_SPHERE_LEDS:
        raise SpectralDataError(f"LED spectra: {len(setup.leds)} LEDs, the sphere has {N_SPHERE_LEDS}")


def warn_setup(setup: SimulationSetup) -> None:
    """Warnings for a user's data that runs but cannot mean what was meant: an all-zero camera channel or
    LED, identical training spectra."""
    for i, name in enumerate("RGB"):
        if not np.any(setup.camera[:, i]):
            log.warning("camera sensitivities (%s): channel %s is zero at every wavelength of the grid",
                        setup.camera_name, name)
    for k in np.flatnonzero(~np.any(np.asarray(setup.leds), axis=1)):
        log.warning("LED spectra: LED %d is zero at every wavelength of the grid (lights using it are dark)", k + 1)
    _warn_identical(setup.train, "training")


def _warn_identical(target: Target, role: str) -> None:
    spectra = np.asarray(target.spectra)
    _, first, counts = np.unique(spectra, axis=0, return_index=True, return_counts=True)
    if len(first) == 1 and len(spectra) > 1:
        log.warning("%s target %s: all %d patches have identical spectra; the characterisation cannot be fitted "
                    "meaningfully", role, target.name, len(spectra))
    elif (counts > 1).any():
        dup = int((counts > 1).sum())
        log.warning("%s target %s: %d spectra occur more than once (e.g. patch %s); duplicates add no information",
                    role, target.name, dup, target.patch_names[int(first[np.argmax(counts > 1)])])


# ---- reference XYZ of the targets ----------------------------------------------------------------------
def check_reference_method(method: str) -> str:
    if method not in REFERENCE_XYZ_METHODS:
        raise ValueError(f"reference XYZ method {method!r}: expected one of {', '.join(REFERENCE_XYZ_METHODS)}")
    return method


def target_xyz(setup: SimulationSetup, target: Target, method: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Reference XYZ (n, 3) of ``target``'s patches and the Lab reference white, Y of a perfect white = 100.

    ``"eq-4.2"`` (default): the thesis' eq 4.2, a plain sum over the simulation grid (410-780 nm, 10 nm) with
    the CMFs and D65 sampled there, the same sum that predicts the camera's view, so reference and prediction
    integrate alike. ``"astm-e308"``: ``colour.msds_to_XYZ(method="ASTM E308")`` on the spectra as measured
    (their own wavelengths and interval; CIE 1931 2 degree observer and D65 over 360-830 nm, ASTM E308 weighting
    and extrapolation): the standard integration for measured spectra. The two differ by 0.078 mean / 0.256 max
    dE00 on the packaged CC24 (tests/simulation/test_reference_xyz.py).
    """
    from dualrgb.simulation.colorimetry import tristimulus, white_point

    method = check_reference_method(method or setup.reference_xyz)
    if method == REFERENCE_EQ_4_2:
        return tristimulus(target.spectra, setup.illuminant, setup.cmfs), white_point(setup.illuminant, setup.cmfs)
    if target.measured is not None:
        wl, values = target.measured.wavelengths, target.measured.values
    else:
        wl, values = setup.grid.wavelengths, target.spectra.T
    return astm_e308_xyz(wl, values)


def astm_e308_xyz(wavelengths: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ASTM E308 XYZ of spectra ``values`` (n_wl, n) and of the perfect white on the same wavelengths (D65, CIE
    1931 2 degree; colour-science). Irregular or unusual intervals are interpolated to 1 nm first."""
    wl = np.asarray(wavelengths, dtype=float)
    values = np.asarray(values, dtype=float).reshape(len(wl), -1)
    steps = np.diff(wl)
    if not (np.allclose(steps, steps[0]) and float(steps[0]) in (1.0, 5.0, 10.0, 20.0)):
        fine = np.arange(np.ceil(wl[0]), np.floor(wl[-1]) + 1.0)
        values = np.stack([np.interp(fine, wl, v) for v in values.T], axis=1)
        wl = fine
    shape = colour.SpectralShape(float(wl[0]), float(wl[-1]), float(wl[1] - wl[0]))
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    both = np.concatenate([values, np.ones((len(wl), 1))], axis=1)
    msds = colour.MultiSpectralDistributions(both, wl, labels=[str(i) for i in range(both.shape[1])])
    with colour.utilities.suppress_warnings(colour_runtime_warnings=True):    # "aligning ... shape" notices
        xyz = np.asarray(colour.msds_to_XYZ(msds, cmfs, d65, method="ASTM E308", shape=shape))
    return xyz[:-1], xyz[-1]
