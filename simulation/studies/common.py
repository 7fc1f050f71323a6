"""Shared pieces of the studies: picklable setup specs (for Dask tasks), an evaluator that records the
best-so-far trace of any optimiser, and the output folder (JSON, PNG charts through matplotlib's Agg canvas,
Markdown summary).

Charts use ``matplotlib.figure.Figure`` with an explicit Agg canvas, never pyplot, so importing a study never
changes the process-wide backend (the GUI runs Qt in the same process).
"""
from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.common.atomic_files import atomic_output, atomic_write
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.simulation.datasets import SimulationSetup, default_setup
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.versions import stamped

if TYPE_CHECKING:
    from matplotlib.figure import Figure  # imported lazily at run time: a study's import stays light

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SetupSpec:
    """Everything needed to rebuild a :class:`SimulationSetup` in another process (Dask workers)."""

    mode: str = "reflective"
    step: float = 10.0
    start: float = 410.0
    end: float = 780.0
    camera_csv: str | None = None
    leds_csv: str | None = None
    train_csv: str | None = None
    test_csv: str | None = None

    @property
    def grid(self) -> SpectralGrid:
        return SpectralGrid(self.start, self.end, self.step)

    def build(self) -> SimulationSetup:
        return default_setup(self.mode, self.grid, camera_csv=self.camera_csv, leds_csv=self.leds_csv,
                             train_csv=self.train_csv, test_csv=self.test_csv)

    def label(self) -> str:
        return f"{self.mode}, {self.grid.label()}"

    def to_dict(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


@lru_cache(maxsize=8)
def evaluator_for(spec: SetupSpec) -> Evaluator:
    """One evaluator per spec and process (workers reuse it across tasks)."""
    return Evaluator(spec.build())


class Trace:
    """Best cost seen so far against evaluations and seconds since ``start``: the anytime curve of a run."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.evaluations: list[int] = []
        self.seconds: list[float] = []
        self.best: list[float] = []
        self._n = 0
        self._best = math.inf

    def record(self, n_new: int, costs: np.ndarray) -> None:
        self._n += int(n_new)
        if len(costs):
            self._best = min(self._best, float(np.min(costs)))
        self.evaluations.append(self._n)
        self.seconds.append(time.perf_counter() - self.t0)
        self.best.append(self._best)

    def to_dict(self, max_points: int = 200) -> dict:
        """Thinned to at most ``max_points`` (log-spaced in evaluations) for JSON."""
        n = len(self.best)
        if n == 0:
            return {"evaluations": [], "seconds": [], "best": []}
        keep = np.unique(np.round(np.geomspace(1, n, min(n, max_points))).astype(int) - 1)
        return {"evaluations": [self.evaluations[i] for i in keep],
                "seconds": [round(self.seconds[i], 5) for i in keep],
                "best": [round(self.best[i], 6) for i in keep]}


class TracedEvaluator:
    """Wraps an :class:`Evaluator`: every ``cost_indexed`` call is recorded in ``trace``; everything else is
    delegated, so it can be handed to ``pso``, ``ga``, ``exhaustive`` and the study optimisers unchanged."""

    def __init__(self, evaluator: Evaluator) -> None:
        self._ev = evaluator
        self.trace = Trace()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ev, name)

    @property
    def base(self) -> Evaluator:
        return self._ev

    def cost_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        costs = self._ev.cost_indexed(idx, w)
        self.trace.record(len(costs), costs)
        return costs

    def record_external(self, costs: np.ndarray) -> None:
        """Evaluations made outside the fast kernel (e.g. the float64 cost of the gradient method)."""
        self._ev.evaluations += len(costs)
        self.trace.record(len(costs), costs)


def to_jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return None if not math.isfinite(v) else v
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable(dataclasses.asdict(obj))
    if isinstance(obj, Path):
        return str(obj)
    return obj


class StudyOutput:
    """An output folder: ``<name>.json``, PNG charts and ``SUMMARY.md``; remembers what it wrote."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OSError(f"output folder {self.folder}: cannot create it ({exc.strerror or exc})") from exc
        self.files: list[Path] = []

    def write_json(self, name: str, data: Any) -> Path:
        """``data`` (a dict) behind the format tag (its own 'format', else dualrgb-study-<name>/1) and versions."""
        path = self.folder / name
        data = stamped(data.get("format") or f"dualrgb-study-{Path(name).stem.replace('_', '-')}/1", data)
        atomic_write(path, strict_dumps(to_jsonable(data), indent=2) + "\n")
        self.files.append(path)
        return path

    def save_figure(self, fig: Figure, name: str) -> Path:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        path = self.folder / name
        FigureCanvasAgg(fig)
        with atomic_output(path, "wb") as fh:
            fig.savefig(fh, format="png", dpi=110)
        self.files.append(path)
        return path

    def write_summary(self, title: str, lines: list[str]) -> Path:
        path = self.folder / "SUMMARY.md"
        atomic_write(path, f"# {title}\n\n" + "\n".join(lines).rstrip() + "\n")
        self.files.append(path)
        return path


def markers(name: str) -> tuple[str, str]:
    """The lines that bound a study's generated section in a Markdown file: ``<!-- name:start -->`` / end."""
    return f"<!-- {name}:start -->", f"<!-- {name}:end -->"


def replace_marked(text: str, body: str, name: str, source: str = "the page") -> str:
    """``text`` with everything between the ``name`` section's markers replaced by ``body``; ValueError naming
    ``source`` unless it has one start line before one end line."""
    start, end = markers(name)
    if text.count(start) != 1 or text.count(end) != 1 or text.index(start) > text.index(end):
        raise ValueError(f"{source}: needs one {start} line before one {end} line")
    head, rest = text.split(start)
    _, tail = rest.split(end)
    return f"{head}{start}\n{body}\n{end}{tail}"


def write_marked(path: str | Path, body: str, name: str) -> Path:
    """:func:`replace_marked` on the file ``path``, written atomically."""
    p = Path(path)
    atomic_write(p, replace_marked(p.read_text(encoding="utf-8"), body, name, str(p)))
    return p


def new_figure(width: float = 7.5, height: float = 4.8, ncols: int = 1, nrows: int = 1):
    """A matplotlib Figure on the Agg canvas and its axes (one per column; rows x columns when ``nrows`` > 1)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols)
    return fig, axes


def median_spread(values: list[float] | np.ndarray) -> dict:
    """Median, min and max of a list of per-seed values (the spread the charts draw as error bars)."""
    v = np.asarray(values, dtype=float)
    return {"median": float(np.median(v)), "min": float(v.min()), "max": float(v.max()),
            "n": int(v.size)}


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the non-dominated points (minimise both), ordered by the first coordinate.

    Along the returned order the first coordinate increases and the second strictly decreases.
    """
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front: list[int] = []
    best = math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def study_charts() -> list[tuple[str, Path]]:
    """(label, PNG) of the charts to show: the user's own ``dualrgb study`` runs (in the per-user data folder,
    where the studies write by default) first, then the reference charts packaged with the app."""
    from dualrgb import resources
    mine = resources.user_path("studies")
    charts = [(f"{p.parent.name}/{p.name}", p) for p in sorted(mine.glob("*/*.png"))] if mine.is_dir() else []
    packaged = resources.path("figures")
    if packaged.is_dir():
        charts += [(f"{p.name} (reference run)", p) for p in sorted(packaged.glob("*.png"))]
    return charts
