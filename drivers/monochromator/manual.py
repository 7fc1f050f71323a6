"""ManualMonochromator: a monochromator set by hand, with the same interface as the motorised driver.

A sequence asks it what to tell the person (:meth:`ManualMonochromator.prompt_to_set`, ``prompt_to_close``), shows
that as a prompt (the CLI on the terminal, the GUI in a dialog) and, once the person has continued, calls
:meth:`ManualMonochromator.goto`, which only records the wavelength the person set. The shutter is the person's:
the prompts say when it must be open (each wavelength) and closed (the dark frames).
"""
from __future__ import annotations

import logging

from dualrgb.drivers.monochromator.errors import MonochromatorError, ShutterReport
from dualrgb.drivers.monochromator.protocol import NM

log = logging.getLogger(__name__)


class ManualMonochromator:
    """A hand-operated monochromator (``description``: what it is, for the measurement's provenance)."""

    manual = True

    def __init__(self, description: str = "monochromator set by hand"):
        self.description = description
        self.wavelength_nm: float | None = None
        self.wavelengths_set: list[float] = []      # what the person was asked to set, in order

    def describe(self) -> dict[str, str]:
        return {"instrument": "manual monochromator (set by hand at each wavelength)", "model": self.description}

    def prepare(self) -> None:
        """Nothing to configure: the person sets the instrument."""

    def prompt_to_set(self, wavelength_nm: float) -> str:
        return f"Set the monochromator to {wavelength_nm:g} nm with its shutter open, then continue"

    def prompt_to_close(self) -> str:
        return "Close the monochromator's shutter (or cap the lens) for the dark frames, then continue"

    def goto(self, wavelength_nm: float) -> float:
        """The person has set ``wavelength_nm`` (after :meth:`prompt_to_set`): record it."""
        try:
            nm = NM.check(wavelength_nm)
        except ValueError as exc:
            raise MonochromatorError(f"wavelength: {exc}", kind="argument") from None
        self.wavelength_nm = nm
        self.wavelengths_set.append(nm)
        log.info("manual monochromator: set to %g nm by hand", nm)
        return nm

    def open_shutter(self) -> None:
        """The person opened it when asked to set the wavelength."""

    def close_shutter(self) -> None:
        """The person closes it when asked (the dark frames)."""

    def ensure_closed(self) -> ShutterReport:
        return ShutterReport(False, "the manual monochromator's shutter is operated by hand: close it (or cap the "
                                    "lens) when the measurement ends")
