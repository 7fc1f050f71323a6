"""Capture sequences (Qt-free): the plans of the one run engine (core.engine). A sequence lists its frames
before anything moves and yields messages (core.messages) and one progress event per step; it holds no
device: the engine alone applies the messages, checks cancel and pause between steps and switches the light off,
read back, at the end. The CLI, the GUI and the demo all run them through the engine."""
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent, Sequence

__all__ = ["PlannedFrame", "ProgressEvent", "Sequence"]
