"""Capture sequences (Qt-free): the plans of the one run engine (app.workflow.engine). A sequence lists its frames
before anything moves and yields one progress event per step; the engine checks cancel and pause between steps
and switches the light off at the end. The CLI, the GUI and the demo all run them through the engine."""
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent, Sequence

__all__ = ["PlannedFrame", "ProgressEvent", "Sequence"]
