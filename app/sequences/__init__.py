"""Capture sequences (Qt-free): plain objects whose ``run()`` generator yields progress events, checks a cancel
flag between steps and can pause/resume. The CLI and the GUI both drive them."""
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent, Sequence, SequenceCancelled

__all__ = ["PlannedFrame", "ProgressEvent", "Sequence", "SequenceCancelled"]
