"""A session's frames grouped by the vocabulary's rules, and the one path that processes them.

``session_frames(session)`` is the only place that decides which frames are darks, which are whose flats and
which belong to which subject and light (latest take of every step; old sessions' strings read);
``process_session`` is the only processing path for a session: the GUI's Results, ``dualrgb process``,
``dualrgb calibrate`` and ``dualrgb demo`` all call it, so the same session gives the same numbers everywhere.
"""
from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.characterise import Characterisation, characterise
from dualrgb.app.processing.hdr import LINEAR_LIMIT_DN
from dualrgb.app.processing.pipeline import CaptureProcessor, ChannelStack, ExposureRef, sub_progress
from dualrgb.app.workflow.calibration.targets import TargetSpec, reference_white
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.core.vocabulary import Role, Subject, latest_takes, light_of, role_of, subject_of
from dualrgb.simulation.lightsource import LightSource

if TYPE_CHECKING:
    from dualrgb.app.processing.figure_files import FigureJob
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.app.processing.placement import Placement
    from dualrgb.app.processing.spectral import SpectralCharacterisation
    from dualrgb.app.workflow.calibration.stand_calibration import StandResult
    from dualrgb.core.protocols import Session
    from dualrgb.core.session.manifest import SessionEntry
    from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

LightFrames = dict[str, list[ExposureRef]]          # light name -> exposures (one subject or the flats)

# the share of process_session's progress each of its steps fills, in order (every step longer than a moment says
# what it does; the report's figures are its sub-steps); the calibration's phases (app.workflow.phase_costs) are
# these steps, timed
PROCESSING_STEPS: dict[str, tuple[float, float]] = {
    "whites": (0.0, 0.15), "training target": (0.15, 0.4), "test target": (0.4, 0.55), "fitting": (0.55, 0.75),
    "spectral estimate": (0.75, 0.8), "stand model": (0.8, 0.85), "report": (0.85, 1.0)}


@dataclass
class SessionFrames:
    """The session's frames by purpose: darks, flats per light, and each subject's exposures per light."""

    darks: list[ExposureRef] = field(default_factory=list)
    flats: LightFrames = field(default_factory=dict)
    subjects: dict[Subject, LightFrames] = field(default_factory=dict)

    def subject(self, subject: Subject) -> LightFrames:
        if subject not in self.subjects:
            have = ", ".join(sorted(s.key for s in self.subjects)) or "none"
            raise ValueError(f"the session has no captures of {subject.key} (subjects: {have})")
        return self.subjects[subject]


def _ref(session: Session, e: SessionEntry) -> ExposureRef:
    if e.exposure_s is None:
        raise ValueError(f"{e.file}: no exposure time in the session manifest")
    return ExposureRef(session.file_path(e), float(e.exposure_s), e.file)


def session_frames(session: Session, *, intact: bool = True) -> SessionFrames:
    """Group the session's latest takes: darks, flats by light, subjects by light (recording order kept).

    A missing or damaged frame is named (core.session.DamagedFramesError), never processed; ``intact=False``: the
    caller checks the frames it uses itself (``dualrgb process``: per original)."""
    if intact:
        session.require_intact()
    out = SessionFrames()
    for e in latest_takes(session.entries()):
        role = role_of(e)
        if role is Role.DARK and e.exposure_s:
            out.darks.append(_ref(session, e))
        elif role is Role.FLAT:
            out.flats.setdefault(light_of(e), []).append(_ref(session, e))
        elif role in (Role.TARGET, Role.ORIGINAL) and (subject := subject_of(e)) is not None:
            out.subjects.setdefault(subject, OrderedDict()).setdefault(light_of(e), []).append(_ref(session, e))
    return out


def subject_entries(session: Session) -> dict[str, dict[str, list]]:
    """Subject key -> light name -> manifest entries (latest takes): what the GUI lists."""
    out: dict[str, dict[str, list]] = {}
    for e in latest_takes(session.entries()):
        subject = subject_of(e)
        if subject is not None:
            out.setdefault(subject.key, {}).setdefault(light_of(e), []).append(e)
    return out


def light_sets(light_names: Sequence[str]) -> dict[str, list[str]]:
    """Group light names by preset ('<preset> light <n>'): a session may hold several presets' captures."""
    out: dict[str, list[str]] = {}
    for name in light_names:
        preset, sep, _n = name.rpartition(" light ")
        out.setdefault(preset if sep else name, []).append(name)
    return out


def select_lights(frames: LightFrames, lights: Sequence[str] | None = None,
                  exposures: Mapping[str, Sequence[float]] | None = None) -> LightFrames:
    """The exposures of ``lights`` (default: every light, in recording order), only ``exposures`` when given."""
    names = list(lights) if lights is not None else list(frames)
    missing = [n for n in names if n not in frames]
    if missing:
        raise ValueError(f"no frames under {', '.join(missing)} (lights captured: {', '.join(frames) or 'none'})")
    out = {}
    for n in names:
        refs = frames[n]
        if exposures is not None and n in exposures:
            wanted = [float(t) for t in exposures[n]]
            refs = [r for r in refs if any(abs(r.exposure_s - t) <= 0.02 * t for t in wanted)]
            if not refs:
                raise ValueError(f"{n}: none of the exposures {wanted} was captured")
        out[n] = refs
    return out


def build_processor(frames: SessionFrames, lights: Sequence[str], *, white_level: float | None = None,
                    linear_limit: float | None = LINEAR_LIMIT_DN, progress: ProgressCallback | None = None,
                    cancel: CancelToken | None = None, mode: str | None = None) -> CaptureProcessor:
    """A processor with the session's dark frames and the HDR whites (flats) of ``lights``; ``mode``
    ('reflective' / 'transmissive') picks the HDR merge the HDR study chose for it."""
    proc = CaptureProcessor(dark_frames=frames.darks, white_level=white_level, linear_limit=linear_limit, mode=mode)
    missing = [n for n in lights if n not in frames.flats]
    if missing:
        raise ValueError(f"no flats (open-gate frames) for {', '.join(missing)}: shoot them first")
    for i, name in enumerate(lights):
        proc.set_white(name, frames.flats[name], progress=sub_progress(progress, i / len(lights),
                                                                        (i + 1) / len(lights)), cancel=cancel)
    return proc


@dataclass
class SessionResult:
    characterisation: Characterisation
    report: dict
    files: dict[str, Path]
    patch_values: dict[str, np.ndarray]
    processor: CaptureProcessor
    lights: list[str]
    spectral: SpectralCharacterisation | None = None      # the spectral estimate (known target spectra)
    stand: StandResult | None = None                        # the stand model fitted to the captures
    grids: dict[str, PatchGrid] = field(default_factory=dict)   # 'train' / 'test': the grid sampled (found or given)


@dataclass
class SampledTarget:
    """A captured target's patch values (n, C), their standard deviations, its stack, the grid they were sampled
    with (given, or found: app.processing.chart_detect) and what the placement checks found
    (app.processing.placement)."""

    values: np.ndarray
    std: np.ndarray
    stack: ChannelStack
    grid: PatchGrid
    placement: Placement


def _target_grid(spec: TargetSpec, stack: ChannelStack) -> tuple[PatchGrid, str]:
    """The spec's grid, else the chart found in the stack (its layout and geometry alone, the reference deciding
    which way up): with how it was placed."""
    from dualrgb.app.processing.chart_detect import detect_chart

    if spec.grid is not None:
        return spec.grid, "given"
    if spec.geometry is None:
        raise ValueError(f"{spec.subject.label}: no patch grid given and the chart's layout is not known; place the "
                         "grid")
    grid = detect_chart(stack.data, spec.geometry, reference=spec.xyz, cells=spec.cell_indices(),
                        label=spec.subject.label)
    return grid, "detected"


def sample_target_placed(proc: CaptureProcessor, spec: TargetSpec, frames: LightFrames, progress=None,
                         cancel=None, pixels: list[np.ndarray] | None = None) -> SampledTarget:
    """A captured target's stack, its grid (``spec.grid`` or found in the stack), the placement checked
    (app.processing.placement: refused in one line when a window spans two patches or the chart fits its
    reference better turned or mirrored) and the patch values; ``pixels``, when given, gets each patch's (m, C)
    pixel values (at most simulation.pixel_error.MAX_PIXELS_PER_PATCH, a regular subsample) for the per-pixel
    colour error."""
    from dualrgb.app.processing.placement import check_placement

    stack = proc.stack(frames, progress=sub_progress(progress, 0.0, 0.6), cancel=cancel)
    report(progress, 0.6, f"{spec.subject.label}: " + ("placing the grid" if spec.grid is not None
                                                       else "finding the chart in the frame"))
    grid, method = _target_grid(spec, stack)
    cells = spec.cell_indices()
    # patches fill the grid row by row (a partly filled last row is fine: 190 patches on 12 x 17 cells), or each
    # lies in the cell its chart names (simulation.charts)
    fits = (len(spec.names) <= grid.n_patches < len(spec.names) + grid.cols if cells == list(range(len(cells)))
            else (grid.rows, grid.cols) == tuple(spec.layout or ()) and max(cells) < grid.n_patches)
    if not fits:
        raise ValueError(f"{spec.subject.label}: the grid has {grid.n_patches} cells ({grid.rows} x {grid.cols}) "
                         f"but the target {len(spec.names)} patches"
                         + (f" on {spec.layout[0]} x {spec.layout[1]} cells" if spec.layout else ""))
    sampled = grid.sample(stack.data)
    if pixels is not None:
        pixels.extend(patch_pixels(grid, stack.data, cells))
    report(progress, 0.85, f"{spec.subject.label}: checking the placement of the patches")
    placement = check_placement(grid, stack.data, spec.xyz, cells, spec.names, label=spec.subject.label,
                                method=method, means=sampled.mean)
    return SampledTarget(sampled.mean[cells], sampled.std[cells], stack, grid, placement)


def sample_target(proc: CaptureProcessor, spec: TargetSpec, frames: LightFrames, progress=None, cancel=None,
                  pixels: list[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray, ChannelStack]:
    """Patch values (n, C), their standard deviations (n, C) and the stack of a captured target
    (:func:`sample_target_placed`)."""
    t = sample_target_placed(proc, spec, frames, progress, cancel, pixels)
    return t.values, t.std, t.stack


def patch_pixels(grid, image: np.ndarray, cells: Sequence[int]) -> list[np.ndarray]:
    """Each of ``cells``' (m, C) pixels inside the grid's sampled area (the pixels its patch mean is made of)."""
    from dualrgb.simulation.pixel_error import subsample

    masks = grid.masks(image.shape[:2])
    return [subsample(image[rs, cs][mask].astype(np.float64)) for rs, cs, mask in (masks[k] for k in cells)]


def process_session(session: Session, out_dir: Path, train: TargetSpec, test: TargetSpec | None = None, *,
                    lights: Sequence[str] | None = None, exposures: Mapping[str, Sequence[float]] | None = None,
                    white_level: float | None = None, linear_limit: float | None = LINEAR_LIMIT_DN,
                    optimise: bool = True, white_xyz: np.ndarray | None = None, title: str = "dual-RGB capture",
                    progress: ProgressCallback | None = None, cancel: CancelToken | None = None,
                    mode: str | None = None, stand_start: StandModel | None = None) -> SessionResult:
    """Darks, HDR whites, target stacks -> patch values -> matrices -> report.json + figures + CSVs in ``out_dir``.

    ``lights`` picks the light set (a session may hold several presets' captures; default: the training
    target's lights), ``exposures`` per light restricts which exposures are merged (default: all captured).
    ``white_xyz`` is the Lab reference white on the targets' XYZ scale (default: D65, Y = 100). ``mode``
    ('reflective' / 'transmissive'): the HDR merge is that mode's default (resources/parsimony.json). When the
    targets' spectra and the lights are known the stand model is fitted to the captures (app.workflow.
    stand_calibration; from ``stand_start``: nominal, or with measurements) and the report shows the thesis Fig 7.4
    check before (nominal, ``dn_validation``) and after (``stand_model``).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    frames = session_frames(session)
    train_frames = select_lights(frames.subject(train.subject), lights, exposures)
    names = list(train_frames)
    proc = build_processor(frames, names, white_level=white_level, linear_limit=linear_limit,
                           progress=step_progress(progress, "whites"), cancel=cancel, mode=mode)
    pixels: dict[str, list[np.ndarray]] = {"train": [], "test": []}     # each patch's, for the per-pixel dE00
    placed = _sample_targets(proc, frames, (train, train_frames), test, names, exposures, pixels, progress, cancel)
    vt, st, stack = placed["train"].values, placed["train"].std, placed["train"].stack
    vs, stack_t = (placed["test"].values, placed["test"].stack) if "test" in placed else (None, None)
    channels = stack.channels
    white = reference_white() if white_xyz is None else np.asarray(white_xyz, dtype=float)
    c = characterise(vt, train.xyz, white, vs, test.xyz if test is not None else None, channels,
                     optimise=optimise, pixels={k: v for k, v in pixels.items() if v},
                     progress=step_progress(progress, "fitting"), cancel=cancel)
    check(cancel)
    step_start(progress, "spectral estimate", "spectral estimate: fitting and choosing the estimator")
    spectral = _spectral(session, train, test, (vt, st, vs), channels, c.linear_matrix.matrix, names, cancel)
    step_start(progress, "stand model", "stand model: fitting it to the captures")
    stand = fit_session_stand(session, frames, proc, names, (train, vt, st, stack), (test, vs, stack_t), c, stand_start)
    check(cancel)
    files = _patch_files(out_dir, c, channels, ((train, vt), (test, vs)))
    data = [_target_data(s, placed[lbl], lbl) for s, lbl in ((train, "train"), (test, "test")) if s and lbl in placed]
    rep = _report(out_dir, c, data, stand, train, (session, proc, frames, names, spectral, title), progress, cancel)
    files["report"] = out_dir / "report.json"
    report(progress, 1.0, "processing done")
    return SessionResult(c, rep, files, {"train": vt, **({"test": vs} if vs is not None else {})}, proc, names,
                         spectral, stand, {k: p.grid for k, p in placed.items()})


def step_progress(progress: ProgressCallback | None, step: str) -> ProgressCallback | None:
    """``progress`` for one of :data:`PROCESSING_STEPS` (its share of the whole)."""
    return sub_progress(progress, *PROCESSING_STEPS[step])


def step_start(progress: ProgressCallback | None, step: str, message: str) -> None:
    """Say that ``step`` (of :data:`PROCESSING_STEPS`) begins: the bar at its start, the message what it does."""
    report(progress, PROCESSING_STEPS[step][0], message)


def _report(out_dir: Path, c: Characterisation, data: list, stand: StandResult | None, train: TargetSpec,
            what: tuple, progress: ProgressCallback | None, cancel: CancelToken | None) -> dict:
    """report.json and its figures (app.processing.report.build_report), each figure one sub-step of the
    'report' step ("report: figure 3 of 11, ..."). ``what``: (session, processor, frames, lights, spectral,
    title)."""
    from dualrgb.app.processing.figure_files import figure_message
    from dualrgb.app.processing.quality import CalibrationFrames
    from dualrgb.app.processing.report import build_report

    session, proc, frames, names, spectral, title = what
    simulated, extra, stand_figures = _stand_report(stand, train, out_dir, list(c.channels))
    lo, hi = PROCESSING_STEPS["report"]
    report(progress, lo, "report: listing its figures")

    def figure_done(k: int, n: int, shown: str) -> None:
        report(progress, lo + (hi - lo) * k / max(n, 1), figure_message(k, n, shown))
    calibration = CalibrationFrames(proc, frames.darks, {n: frames.flats[n] for n in names})
    return build_report(out_dir, c, data[0], data[1] if len(data) > 1 else None, simulated_train=simulated,
                        title=title, extra={"session": str(session.path), "darks": proc.darks.exposures,
                                            "lights": names, **extra}, calibration=calibration, spectral=spectral,
                        more_figures=stand_figures, progress=figure_done, cancel=cancel)


def _sample_targets(proc: CaptureProcessor, frames: SessionFrames, train: tuple[TargetSpec, LightFrames],
                    test: TargetSpec | None, names: Sequence[str], exposures: Mapping[str, Sequence[float]] | None,
                    pixels: dict[str, list[np.ndarray]], progress: ProgressCallback | None,
                    cancel: CancelToken | None) -> dict[str, SampledTarget]:
    """The training and (when given) test targets sampled: 'train' / 'test' -> SampledTarget; ``pixels`` gets
    their patches' pixels."""
    spec, train_frames = train
    placed = {"train": sample_target_placed(proc, spec, train_frames, step_progress(progress, "training target"),
                                            cancel, pixels["train"])}
    if test is not None:
        test_frames = select_lights(frames.subject(test.subject), names, exposures)
        placed["test"] = sample_target_placed(proc, test, test_frames, step_progress(progress, "test target"),
                                              cancel, pixels["test"])
    return placed


def _target_data(spec: TargetSpec, placed: SampledTarget, label: str):
    """The report's data of one sampled target, its grid drawn over the first light's frame."""
    from dualrgb.app.processing.report import Placed, TargetData

    return TargetData(spec.names, spec.xyz, placed.values, spec.layout, spec.label or label, std=placed.std,
                      placement=Placed(placed.grid, placed.stack.rgb(0), placed.placement.to_dict(),
                                       spec.cell_indices()))


def _stand_report(stand: StandResult | None, train: TargetSpec, out_dir: Path, channels: list[str]
                  ) -> tuple[np.ndarray | None, dict, list[FigureJob]]:
    """The report's simulated training values for Fig 7.4 (the target's own, else the nominal stand model's), its
    ``stand_model`` section (the fitted model's check, app.workflow.calibration.stand_calibration) and that
    section's figure (to draw with the report's)."""
    if stand is None:
        return train.simulated, {}, []
    from dualrgb.app.workflow.calibration.stand_calibration import report_section

    simulated = train.simulated if train.simulated is not None else stand.values("start")
    section, job = report_section(stand, out_dir, channels, train.names)
    return simulated, {"stand_model": section}, [job]


def _patch_files(out_dir: Path, c: Characterisation, channels: list[str],
                 targets: Sequence[tuple[TargetSpec | None, np.ndarray | None]]) -> dict[str, Path]:
    """matrices.csv and patches_<target>.csv (every fitted matrix's prediction and error per patch)."""
    from dualrgb.app.processing.outputs import write_matrices_csv, write_patch_csv

    files = {"matrices": write_matrices_csv(out_dir / "matrices.csv", {k: r.matrix for k, r in c.results.items()})}
    for label, (spec, values) in zip(("train", "test"), targets, strict=True):
        if spec is not None and values is not None:
            preds = {k: r.matrix.apply(values) for k, r in c.results.items()}
            errs = {k: r.errors(label) for k, r in c.results.items()}
            files[f"patches_{label}"] = write_patch_csv(out_dir / f"patches_{label}.csv", spec.names, values,
                                                        channels, spec.xyz, preds, errs, target=label)
    return files


def frame_lights(session: Session, subject: Subject, names: Sequence[str]) -> list[LightSource] | None:
    """The lights (LEDs, exact levels) the manifest recorded for ``subject``'s frames under ``names``, in that
    order; None when a light was not recorded."""
    from dualrgb.core.session.light_dose import light_from_record

    found: dict[str, LightSource] = {}
    for e in latest_takes(session.entries()):
        if subject_of(e) == subject and e.light and light_of(e) in names:
            found.setdefault(light_of(e), light_from_record(e.light))
    return [found[n] for n in names] if all(n in found for n in names) else None


def _spectral(session: Session, train: TargetSpec, test: TargetSpec | None, values: tuple, channels: list[str],
              xyz_matrix: np.ndarray, names: Sequence[str], cancel: CancelToken | None):
    """The spectral estimate (app.processing.spectral) when the training target's spectra are known, else None.
    ``values``: training means, training per-pixel spread, test means."""
    from dualrgb.app.processing.spectral import SpectralInputs, characterise_spectra

    if train.spectra is None or not train.mode:
        return None
    vt, st, vs = values
    with_test = test is not None and test.spectra is not None and vs is not None
    ranges = {"train": train.measured_range, "test": test.measured_range if test is not None else None}
    return characterise_spectra(SpectralInputs(
        train.mode, list(channels), vt, train.spectra, st, vs if with_test else None,
        test.spectra if with_test and test is not None else None, xyz_matrix,
        frame_lights(session, train.subject, names), ranges), cancel)


def fit_session_stand(session: Session, frames: SessionFrames, proc: CaptureProcessor, names: Sequence[str],
                      train: tuple, test: tuple, c: Characterisation, start: StandModel | None) -> StandResult | None:
    """The stand model fitted to the processed captures (app.workflow.calibration.stand_calibration) when the training
    target's spectra and the lights' levels are known, else None. ``train``: (spec, means, per-pixel sd, stack);
    ``test``: (spec or None, means, stack)."""
    from dualrgb.app.workflow.calibration.stand_calibration import fit_processed

    spec = train[0]
    lights = frame_lights(session, spec.subject, names)
    if spec.spectra is None or not spec.mode or lights is None:
        return None
    entry = next((e for e in latest_takes(session.entries()) if subject_of(e) == spec.subject), None)
    settings = (getattr(entry, "iso", None), getattr(entry, "aperture", None))
    return fit_processed(proc, frames, list(names), lights, train, test, c, start, settings)
