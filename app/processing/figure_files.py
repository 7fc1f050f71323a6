"""Report figures as files: a matplotlib figure on the Agg canvas (no GUI backend, safe off the main thread) and
its save through the atomic write (a full disk leaves no half PNG; the error names the file). Used by the target
report (app.processing.report), its quality figures (app.processing.quality_figures) and the ground-truth maps."""
from __future__ import annotations

from pathlib import Path

from dualrgb.common.atomic_files import atomic_output


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
