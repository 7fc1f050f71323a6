"""The virtual spectroradiometer on a serial transport of its own (drivers.virtual.line_server), so `dualrgb lab
serve` serves it beside the sphere: a minimal line protocol of the lab's (no physical instrument's; a real one's
readings come into dualrgb as the files it writes, app.workflow.led_readings), one reply line per request:

* ``IDN?`` -> ``OK IDN <model> <version> <serial>``
* ``RANGE?`` -> ``OK RANGE <start_nm> <end_nm> <step_nm>``
* ``MEAS?`` -> ``OK MEAS <t_s> <n> <v1> ... <vn>``: one reading of what the sphere emits now (spectral radiance in
  W sr^-1 m^-2 nm^-1 at the RANGE's wavelengths, with the instrument's noise; ``t_s`` on the emulator's clock)
* anything else -> ``ERR 1 <message>``
"""
from __future__ import annotations

import logging

from dualrgb.drivers.virtual.spectroradiometer import VirtualSpectroradiometer
from dualrgb.drivers.virtual.transport import line_server

log = logging.getLogger(__name__)

MAX_REQUEST = 64


class SpectroradiometerServer:
    """``instrument`` (a :class:`VirtualSpectroradiometer`) served on a line server (module docstring)."""

    model = "DRGB-SPECTRO-EMU"
    version = "1.0.0"

    def __init__(self, instrument: VirtualSpectroradiometer, transport: str | None = None):
        self.instrument = instrument
        self._server = line_server("spectroradiometer", self._on_line, max_line=MAX_REQUEST, transport=transport)

    def start(self) -> str:
        return self._server.start()

    def stop(self) -> None:
        self._server.close()

    def handle(self, text: str) -> str:
        """The reply line (without its ``\\n``) to one request."""
        keyword = text.strip().upper()
        s = self.instrument.settings
        if keyword == "IDN?":
            return f"OK IDN {self.model} {self.version} {s.serial}"
        if keyword == "RANGE?":
            return f"OK RANGE {s.start_nm:g} {s.end_nm:g} {s.step_nm:g}"
        if keyword == "MEAS?":
            reading = self.instrument.measure()
            values = " ".join(f"{v:.6g}" for v in reading.radiance)
            return f"OK MEAS {reading.t_s:.3f} {len(reading.radiance)} {values}"
        return f"ERR 1 unknown request {keyword[:20]!r}: expected IDN?, RANGE? or MEAS?"

    def _on_line(self, line: bytes, too_long: bool = False) -> None:
        reply = "ERR 5 request too long" if too_long else self.handle(line.decode("ascii", "replace"))
        self._server.respond(reply.encode() + b"\n")
