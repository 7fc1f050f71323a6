"""The 10-LED integrating sphere over serial: protocol table, driver (LedSphere), its one error (SphereError),
what is known after switching it off (LightReport) and the host's on-time supervisor."""
from __future__ import annotations

from typing import Any

from dualrgb.drivers.led_sphere.errors import LightReport, SphereError

__all__ = ["LedSphere", "LightReport", "SphereError"]


def __getattr__(name: str) -> Any:
    """``LedSphere`` is imported on first use: the driver loads pyserial and numpy, which the CLI's parser and
    the protocol table do not need (PEP 562)."""
    if name == "LedSphere":
        from dualrgb.drivers.led_sphere.driver import LedSphere

        return LedSphere
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
