"""From raw files to the N-channel stack, the characterisation, the output files and the report.

Steps (thesis 7 and 8.2):
  1. master dark per exposure time (8.2.1), built lazily from the dark frames when an exposure first needs it;
  2. per light, the HDR white (8.2.2): dark-subtracted, per-second, weighted mean of the white exposures (hdr.py);
  3. per light and subject, the HDR image (8.2.3) of the subject's exposures, flat-fielded by that white
     (eq 7.1), reduced to the half-size superpixel RGB (no demosaic);
  4. the lights' RGBs side by side: an (H/2, W/2, 3 x n_lights) float32 stack, channels R1 G1 B1 R2 G2 B2 ...

Each raw file is decoded once per use and processed in row bands; the mosaic-size buffers alive at a time are
the master darks in use, one HDR accumulator (3 arrays) and one HDR white per light, so a 24 MP dual-RGB HDR
set stays well under 2.5 GB (see bench/bench_processing.py for the measured figures).

API for the sequences and the demo::

    proc = CaptureProcessor(dark_frames=[ExposureRef(path, t), ...], white_level=15520)
    proc.set_white("light 1", [ExposureRef(white_short, 1/250), ExposureRef(white_long, 1/15)])
    proc.set_white("light 2", [...])
    stack = proc.stack({"light 1": [ExposureRef(...), ...], "light 2": [...]})  # ChannelStack
    train = grid.sample(stack.data)                                          # PatchGrid -> PatchValues

    # or everything from a CaptureSession (roles dark / flat / target / object, meta 'target' / 'subject'):
    proc, subjects = processor_from_session(session)
    stack = proc.stack(subjects["target:train"])
"""
from __future__ import annotations

import logging
from collections import OrderedDict, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional, Sequence

import numpy as np

from app.processing.calibration import FlatField, MasterDark
from app.processing.hdr import LINEAR_LIMIT_DN, HdrMerge, HdrResult
from app.processing.mosaic import FrameLike, cfa_of, iter_open_raw, mosaic_of, white_level_of
from simulation.camera_model import CHANNELS
from simulation.progress import CancelToken, ProgressCallback, check, report

log = logging.getLogger(__name__)


@dataclass
class ExposureRef:
    """One raw exposure: a path, a drivers.raw.RawFrame or a mosaic array, and its exposure time (s).

    For bare arrays pass ``white_level`` and ``black_level`` to the CaptureProcessor (files carry their own)."""

    source: FrameLike
    exposure_s: float
    label: str = ""


@dataclass
class ChannelStack:
    """Flat-fielded HDR superpixel channels: ``data`` (H/2, W/2, C) float32, channel names R1, G1, B1, ..."""

    data: np.ndarray
    channels: list[str]
    lights: list[str]
    clipped_fraction: dict[str, float] = field(default_factory=dict)

    def rgb(self, light_index: int = 0) -> np.ndarray:
        return self.data[..., 3 * light_index: 3 * light_index + 3]


def _sub(progress: Optional[ProgressCallback], lo: float, hi: float) -> Optional[ProgressCallback]:
    if progress is None:
        return None
    return lambda f, m: progress(lo + (hi - lo) * min(max(f, 0.0), 1.0), m)


class CaptureProcessor:
    """Darks -> HDR whites -> flat-fielded HDR stacks, with caching of master darks and whites."""

    def __init__(self, *, darks: Optional[MasterDark] = None, dark_frames: Sequence[ExposureRef] = (),
                 white_level: Optional[float] = None, black_level: Optional[float] = None,
                 linear_limit: Optional[float] = LINEAR_LIMIT_DN, cfa: Optional[str] = None, band_rows: int = 256,
                 reject_high: int = 1, reject_low: int = 1, hdr_method: Optional[str] = None):
        """``hdr_method``: the HDR merge estimator (app.processing.hdr; None: the parsimony study's default)."""
        self.darks = darks or MasterDark()
        self._dark_frames: dict[float, list[ExposureRef]] = defaultdict(list)
        for ref in dark_frames:
            self._dark_frames[self._dark_key(ref.exposure_s)].append(ref)
        self.white_level = white_level
        self.black_level = black_level
        self.linear_limit = linear_limit
        self.cfa = cfa
        self.band_rows = band_rows
        self.reject = (reject_high, reject_low)
        self.hdr_method = hdr_method
        self._whites: "OrderedDict[str, FlatField]" = OrderedDict()
        self._work: dict = {}          # scratch buffers reused across darks and merges (see calibration._buffer)

    def _dark_key(self, t: float) -> float:
        for k in self._dark_frames:
            if abs(k - t) <= 0.02 * max(k, t):
                return k
        return float(t)

    # ---- darks ----
    def master_dark(self, exposure_s: float, *, progress: Optional[ProgressCallback] = None,
                    cancel: Optional[CancelToken] = None) -> Optional[np.ndarray]:
        """The master dark for ``exposure_s`` (built from the dark frames on first use), or None if none."""
        if exposure_s in self.darks:
            return self.darks.get(exposure_s)
        refs = self._dark_frames.get(self._dark_key(exposure_s))
        if not refs:
            return None
        self.darks.add(exposure_s, [r.source for r in refs], reject_high=self.reject[0],
                       reject_low=self.reject[1], progress=progress, cancel=cancel, work=self._work)
        return self.darks.get(exposure_s)

    def _dark_for(self, frame, exposure_s: float, cancel) -> np.ndarray | float:
        d = self.master_dark(exposure_s, cancel=cancel)
        if d is not None:
            return d
        black = getattr(frame, "black_levels", None)
        level = float(np.mean(black)) if black else 0.0
        log.warning("no dark frames for %.6g s: subtracting the file's black level (%.1f DN) instead", exposure_s,
                    level)
        return level

    # ---- HDR ----
    def _merge(self, refs: Sequence[ExposureRef], progress, cancel, own_result: bool) -> HdrMerge:
        if not refs:
            raise ValueError("no exposures to merge")
        merge: Optional[HdrMerge] = None
        refs = sorted(refs, key=lambda r: r.exposure_s)
        for i, (ref, frame) in enumerate(zip(refs, iter_open_raw([r.source for r in refs]))):
            check(cancel)
            if self.white_level is None:
                self.white_level = white_level_of(frame)
            if self.cfa is None:
                self.cfa = cfa_of(frame)
            if self.black_level is None:
                black = getattr(frame, "black_levels", None)
                self.black_level = float(np.mean(black)) if black else 0.0
            if merge is None:
                merge = HdrMerge(self.white_level, self.linear_limit, black_level=self.black_level,
                                 method=self.hdr_method, band_rows=self.band_rows, work=self._work,
                                 own_result=own_result)
            dark = self._dark_for(frame, ref.exposure_s, cancel)
            merge.add(mosaic_of(frame), ref.exposure_s, dark, cancel=cancel)
            report(progress, (i + 1) / len(refs), f"exposure {ref.exposure_s:.6g} s {ref.label}".strip())
        return merge

    def hdr(self, refs: Sequence[ExposureRef], *, progress: Optional[ProgressCallback] = None,
            cancel: Optional[CancelToken] = None) -> HdrResult:
        """Dark-subtracted HDR mosaic (DN/s, the configured estimator) of the exposures of one light and subject
        (in new arrays: the result is the caller's to keep)."""
        return self._merge(refs, progress, cancel, True).result()

    def set_white(self, light: str, refs: Sequence[ExposureRef], *, min_fraction: float = 0.01,
                  progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None) -> FlatField:
        """HDR white of one light (8.2.2), kept for flat-fielding that light's images."""
        res = self.hdr(refs, progress=progress, cancel=cancel)
        ff = FlatField(res.radiance, min_fraction=min_fraction)
        self._whites[light] = ff
        log.info("white for %s: %d exposures, %.3f %% clipped", light, len(refs), 100 * res.clipped_fraction)
        return ff

    def has_white(self, light: str) -> bool:
        return light in self._whites

    def white(self, light: str) -> FlatField:
        """The HDR white of ``light`` set by set_white (the quality report measures its uniformity)."""
        return self._whites[light]

    def stack(self, scenes: Mapping[str, Sequence[ExposureRef]], *, progress: Optional[ProgressCallback] = None,
              cancel: Optional[CancelToken] = None) -> ChannelStack:
        """Flat-fielded HDR superpixel RGB of each light (in mapping order), stacked into one image."""
        lights = list(scenes)
        missing = [n for n in lights if n not in self._whites]
        if missing:
            raise ValueError(f"no white (flat) frames for {', '.join(missing)}: call set_white first")
        out: Optional[np.ndarray] = None
        clipped = {}
        for li, name in enumerate(lights):
            merge = self._merge(scenes[name], _sub(progress, li / len(lights), (li + 0.9) / len(lights)), cancel,
                                False)
            ff = self._whites[name]
            h, w = ff.white.shape
            if out is None:
                out = np.empty((h // 2, w // 2, 3 * len(lights)), dtype=np.float32)
            check(cancel)
            n_clipped = merge.flat_superpixel(ff.white, ff.threshold, self.cfa or "RGGB",
                                              out[..., 3 * li: 3 * li + 3])
            clipped[name] = n_clipped / (4 * out.shape[0] * out.shape[1])
            report(progress, (li + 1) / len(lights), f"{name} flat-fielded")
        channels = [f"{c}{i + 1}" for i in range(len(lights)) for c in CHANNELS]
        return ChannelStack(out, channels, lights, clipped)


def _group_refs(session, entries) -> dict[str, list[ExposureRef]]:
    by_light: "OrderedDict[str, list[ExposureRef]]" = OrderedDict()
    for e in entries:
        if e.exposure_s is None:
            raise ValueError(f"{e.file}: no exposure time in the session manifest")
        by_light.setdefault(e.light_name or "light", []).append(
            ExposureRef(session.file_path(e), float(e.exposure_s), e.file))
    return by_light


def processor_from_session(session, *, white_level: Optional[float] = None,
                           linear_limit: Optional[float] = LINEAR_LIMIT_DN, white_role: str = "flat",
                           progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None
                           ) -> tuple[CaptureProcessor, dict[str, dict[str, list[ExposureRef]]]]:
    """A processor with the session's darks and (HDR) whites, and the subjects to stack.

    Subjects are keyed ``"<role>"`` or ``"<role>:<meta target/subject>"`` (e.g. ``"target:train"``,
    ``"object:folio 3"``); each maps light name -> exposures. Whites are merged here (progress 0..1).
    """
    session.require_intact()     # a missing or damaged frame is named (DamagedFramesError), never processed
    darks = [ExposureRef(session.file_path(e), float(e.exposure_s), e.file) for e in session.entries("dark")
             if e.exposure_s]
    proc = CaptureProcessor(dark_frames=darks, white_level=white_level, linear_limit=linear_limit)
    whites = _group_refs(session, session.entries(white_role))
    for i, (light, refs) in enumerate(whites.items()):
        proc.set_white(light, refs, progress=_sub(progress, i / max(len(whites), 1), (i + 1) / max(len(whites), 1)),
                       cancel=cancel)
    subjects: dict[str, list] = defaultdict(list)
    for e in session.entries():
        if e.role in ("dark", white_role, "crf"):
            continue
        tag = e.meta.get("target") or e.meta.get("subject")
        subjects[f"{e.role}:{tag}" if tag else e.role].append(e)
    return proc, {k: _group_refs(session, v) for k, v in subjects.items()}


def write_stack_outputs(out_dir: Path, stack: ChannelStack, characterisation, *, prefix: str = "image",
                        progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None
                        ) -> dict[str, Path]:
    """The output files for one stack with the best matrix of ``characterisation`` (outputs module)."""
    from app.processing.outputs import write_image_outputs

    return write_image_outputs(Path(out_dir), stack.data, stack.channels, characterisation.matrix,
                               characterisation.white, prefix=prefix, progress=progress, cancel=cancel)


# ---------------------------------------------------------------- whole session
@dataclass
class TargetSpec:
    """A colour target captured in the session: where its patches are and what they should be.

    ``grid`` is in the stack's (superpixel, half-size) pixel coordinates; use ``PatchGrid.scaled(0.5)`` for a
    grid placed on the full mosaic. None tries ``detect_cc24`` on the first light's RGB (24-patch targets).
    ``simulated`` (n, C) are the simulated camera values for the thesis Fig 7.4 check (optional).
    """

    subject: str                       # session subject key, e.g. "target:train"
    xyz: np.ndarray                    # (n, 3) reference XYZ (eq 4.2 scale, Y of a perfect white = 100)
    names: list[str]
    grid: Optional["PatchGrid"] = None
    layout: Optional[tuple[int, int]] = None
    simulated: Optional[np.ndarray] = None
    label: str = ""


@dataclass
class SessionResult:
    characterisation: "Characterisation"
    report: dict
    files: dict[str, Path]
    patch_values: dict[str, np.ndarray]


def _sample_target(proc: CaptureProcessor, spec: TargetSpec, subjects, progress, cancel) -> tuple[np.ndarray, list[str]]:
    from app.processing.patches import PatchGrid, detect_cc24

    if spec.subject not in subjects:
        have = ", ".join(sorted(subjects)) or "none"
        raise ValueError(f"the session has no captures of {spec.subject!r} (subjects: {have})")
    stack = proc.stack(subjects[spec.subject], progress=progress, cancel=cancel)
    grid = spec.grid
    if grid is None:
        det = detect_cc24(stack.rgb(0)) if len(spec.names) == 24 else None
        if det is None:
            raise ValueError(f"{spec.subject}: no patch grid given and no chart detected; place the grid by hand")
        grid = det.grid
    # patches fill the grid row by row; a partly filled last row is fine (190 patches on 12 x 17 cells)
    if not len(spec.names) <= grid.n_patches < len(spec.names) + grid.cols:
        raise ValueError(f"{spec.subject}: the grid has {grid.n_patches} cells ({grid.rows} x {grid.cols}) but the "
                         f"target {len(spec.names)} patches")
    values = grid.sample(stack.data).mean[:len(spec.names)]
    return values, stack.channels


def process_session(session, out_dir: Path, train: TargetSpec, test: Optional[TargetSpec] = None, *,
                    images: Sequence[str] = (), white_level: Optional[float] = None,
                    linear_limit: Optional[float] = LINEAR_LIMIT_DN, optimise: bool = True,
                    white_xyz: Optional[np.ndarray] = None, title: str = "dual-RGB capture", progress: Optional[ProgressCallback] = None,
                    cancel: Optional[CancelToken] = None) -> SessionResult:
    """Darks, HDR whites, target stacks -> patch values -> both matrices -> outputs for ``images`` (subject
    keys, e.g. "object") and for the targets -> report.json + figures + CSVs in ``out_dir``.

    ``white_xyz`` is the Lab reference white on the scale of the targets' XYZ (default: D65, Y = 100)."""
    from app.processing.characterise import characterise
    from app.processing.outputs import write_image_outputs, write_matrices_csv, write_patch_csv
    from app.processing.quality import CalibrationFrames
    from app.processing.report import TargetData, build_report
    from simulation.colorimetry import white_point
    from simulation.datasets import default_setup

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    proc, subjects = processor_from_session(session, white_level=white_level, linear_limit=linear_limit,
                                            progress=_sub(progress, 0.0, 0.15), cancel=cancel)
    vt, channels = _sample_target(proc, train, subjects, _sub(progress, 0.15, 0.4), cancel)
    vs = None
    if test is not None:
        vs, _ = _sample_target(proc, test, subjects, _sub(progress, 0.4, 0.55), cancel)
    if white_xyz is None:
        setup = default_setup("reflective")
        white = white_point(setup.illuminant, setup.cmfs)
    else:
        white = np.asarray(white_xyz, dtype=float)
    c = characterise(vt, train.xyz, white, vs, test.xyz if test is not None else None, channels,
                     optimise=optimise, progress=_sub(progress, 0.55, 0.7), cancel=cancel)
    files: dict[str, Path] = {}
    files["matrices"] = write_matrices_csv(out_dir / "matrices.csv", {k: r.matrix for k, r in c.results.items()})
    for label, spec, values in (("train", train, vt), ("test", test, vs)):
        if spec is None:
            continue
        preds = {k: r.matrix.apply(values) for k, r in c.results.items()}
        errs = {k: (r.train_errors if label == "train" else r.test_errors) for k, r in c.results.items()}
        files[f"patches_{label}"] = write_patch_csv(out_dir / f"patches_{label}.csv", spec.names, values, channels,
                                                    spec.xyz, preds, errs, target=label)
    for i, subject in enumerate(images):
        check(cancel)
        if subject not in subjects:
            raise ValueError(f"the session has no captures of {subject!r}")
        stack = proc.stack(subjects[subject], progress=_sub(progress, 0.7, 0.8), cancel=cancel)
        name = subject.replace(":", "_").replace(" ", "_")
        for k, p in write_image_outputs(out_dir, stack.data, stack.channels, c.matrix, white, prefix=name,
                                        cancel=cancel).items():
            files[f"{name}_{k}"] = p
        del stack
    calibration = CalibrationFrames(proc, [ExposureRef(session.file_path(e), float(e.exposure_s), e.file)
                                           for e in session.entries("dark") if e.exposure_s],
                                    _group_refs(session, session.entries("flat")))
    rep = build_report(out_dir, c, TargetData(train.names, train.xyz, vt, train.layout, train.label or "train"),
                       TargetData(test.names, test.xyz, vs, test.layout, test.label or "test") if test else None,
                       simulated_train=train.simulated, title=title,
                       extra={"session": str(session.path), "darks": proc.darks.exposures}, calibration=calibration)
    files["report"] = out_dir / "report.json"
    report(progress, 1.0, "processing done")
    return SessionResult(c, rep, files, {"train": vt, **({"test": vs} if vs is not None else {})})
