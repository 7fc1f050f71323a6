"""Report figures as files: a matplotlib figure on the Agg canvas (no GUI backend, safe off the main thread) and
its save through the atomic write (a full disk leaves no half PNG; the error names the file). Used by the target
report (app.processing.report), its quality figures (app.processing.quality_figures) and the ground-truth maps.

A report lists its figures first as :class:`FigureJob` s and then draws them one by one (:func:`draw_figures`), so
that the number of figures is known before the first is drawn and each one is a sub-step of the progress
("report: figure 3 of 11, test chart: ΔE00 per patch"): a figure takes about a second, a report a dozen of them.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from dualrgb.common.atomic_files import atomic_output
from dualrgb.common.progress import CancelToken, check

FigureProgress = Callable[[int, int, str], None]     # (figures written, figures planned, what the last one shows)


@dataclass(frozen=True)
class FigureJob:
    """One figure to draw: what it shows (for the progress line) and the call that draws and saves it."""

    what: str
    draw: Callable[[], Path]


def draw_figures(jobs: Sequence[FigureJob], progress: FigureProgress | None = None,
                 cancel: CancelToken | None = None) -> list[str]:
    """Draw ``jobs`` in order; after each, ``progress(k, n, what)`` (k = 1..n); the file names written. A cancel is
    noticed between figures."""
    names = []
    for k, job in enumerate(jobs, start=1):
        check(cancel)
        names.append(job.draw().name)
        if progress is not None:
            progress(k, len(jobs), job.what)
    return names


def figure_message(done: int, total: int, what: str) -> str:
    """The progress line of one report figure: 'report: figure 3 of 11, <what>'."""
    return f"report: figure {done} of {total}, {what}"


def new_figure(w: float, h: float):
    """A ``w`` x ``h`` inch figure at 110 dpi on its own Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=110)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path: Path, **kwargs) -> Path:
    """``fig.savefig`` through the atomic write; the format follows the file's suffix."""
    path = Path(path)
    with atomic_output(path, "wb") as fh:
        fig.savefig(fh, format=path.suffix.lstrip(".") or "png", **kwargs)
    return path


def save_tight(fig, path: Path) -> Path:
    """:func:`save_figure` after ``tight_layout``."""
    fig.tight_layout()
    return save_figure(fig, path)
