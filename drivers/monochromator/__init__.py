"""Monochromators for measuring the camera's spectral sensitivity (thesis 4.2): the Cornerstone 130 / 260 serial
protocol and driver (Cornerstone), a hand-set one (ManualMonochromator), their one error (MonochromatorError) and
what is known after closing the shutter (ShutterReport)."""
from __future__ import annotations

from typing import Any

from dualrgb.drivers.monochromator.errors import MonochromatorError, ShutterReport
from dualrgb.drivers.monochromator.manual import ManualMonochromator

__all__ = ["Cornerstone", "ManualMonochromator", "MonochromatorError", "ShutterReport"]


def __getattr__(name: str) -> Any:
    """``Cornerstone`` is imported on first use: the driver loads pyserial, which the CLI's parser does not need
    (PEP 562)."""
    if name == "Cornerstone":
        from dualrgb.drivers.monochromator.driver import Cornerstone

        return Cornerstone
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
