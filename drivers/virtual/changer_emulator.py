"""The virtual lab's sample changer: drivers/sample_changer.py's protocol on a real serial transport
(drivers.virtual.line_server), putting things on the virtual copy stand when a client asks.

``place(what, nd)`` is the lab's (drivers.virtual.lab.VirtualLab.place, under the camera's lock in `dualrgb lab
serve`). An original (``original:<identifier>``) is shown as the virtual stand-in its magazine slot holds
(``LOAD <slot> <identifier>``; ``*`` any identifier not loaded by name; else ``stand_in``): a virtual original's
name (drivers/virtual/originals.py), or a chart: ``test``, ``train``, ``test+nd`` (with the ND filter).
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from dualrgb.drivers.sample_changer import (
    ANY_ORIGINAL,
    COMMANDS,
    ERR_ARGUMENT,
    ERR_CANNOT,
    ERR_TOO_LONG,
    ERR_UNKNOWN,
    MAX_LINE,
    NOTHING,
    ORIGINAL_PREFIX,
    check_thing,
    decode,
    encode,
)
from dualrgb.drivers.virtual.transport import line_server

log = logging.getLogger(__name__)

Place = Callable[[str, bool], Any]
LoadChart = Callable[[str, str, str, str], None]        # role, layout, leave-out, file ('-': none / packaged)
CHART_STAND_INS = ("train", "test")


class ChangerEmulator:
    """See the module docstring."""

    model = "DRGB-CHANGER-EMU"
    version = "1.0.0"
    serial = "EMU-0001"

    def __init__(self, place: Place, stand_in: str, transport: str | None = None, load_chart: LoadChart | None = None):
        self._place = place
        self._load_chart = load_chart
        self.stand_in = stand_in
        self.magazine: dict[str, str] = {}
        self.placed: tuple[str, bool] | None = None
        self._lock = threading.Lock()
        self._server = line_server("sample-changer-emulator", self._on_line, max_line=MAX_LINE, transport=transport)

    def start(self) -> str:
        port = self._server.start()
        log.info("sample changer emulator on %s", port)
        return port

    def stop(self) -> None:
        self._server.close()

    @property
    def port(self) -> str:
        return self._server.port

    def shown_as(self, what: str, nd: bool) -> tuple[str, bool]:
        """What the lab puts on the stand for ``what``: an original as its stand-in (module docstring)."""
        if not what.startswith(ORIGINAL_PREFIX):
            return what, nd
        identifier = what[len(ORIGINAL_PREFIX):]
        name = self.magazine.get(identifier) or self.magazine.get(ANY_ORIGINAL) or self.stand_in
        chart, plus, _ = name.partition("+nd")
        if chart in CHART_STAND_INS:
            return chart, bool(plus) or nd
        return ORIGINAL_PREFIX + name, nd

    def _chart(self, rest: str) -> list[str]:
        role, layout, leave_out, file = (rest.split(" ") + ["", "", "", ""])[:4]
        leave_out, file = decode(leave_out), decode(file)
        if role not in CHART_STAND_INS or not file:
            raise ValueError("CHART <train|test> <layout|-> <leave-out|-> <file|->")
        if self._load_chart is None:
            raise RuntimeError("this changer holds the charts it was loaded with")
        with self._lock:
            self._load_chart(role, layout, leave_out, file)
            self.placed = None                  # what lies there is placed again, as the new chart
        return [role]

    def _on_line(self, line: bytes, too_long: bool = False) -> None:
        if too_long:
            self._server.respond(f"ERR {ERR_TOO_LONG} request longer than {MAX_LINE} bytes\n".encode())
            return
        self._server.respond(self.handle(line.decode("ascii", "replace")).encode() + b"\n")

    def handle(self, text: str) -> str:
        """The reply line (without its ``\\n``) to one request line."""
        keyword, _, rest = text.strip().partition(" ")
        keyword = keyword.upper()
        if keyword not in COMMANDS:
            return f"ERR {ERR_UNKNOWN} unknown command {keyword[:20]!r}"
        try:
            fields = self._execute(keyword, rest.strip())
        except ValueError as exc:
            return f"ERR {ERR_ARGUMENT} {exc}"
        except Exception as exc:  # noqa: BLE001 - the lab could not do it (an unknown stand-in): said, logged
            log.warning("sample changer: %s: %s", text.strip(), exc)
            return f"ERR {ERR_CANNOT} {str(exc).splitlines()[0][:100]}"
        return " ".join(["OK", COMMANDS[keyword], *fields])

    def _execute(self, keyword: str, rest: str) -> list[str]:
        if keyword == "IDN?":
            return [self.model, self.version, self.serial]
        if keyword == "PLACED?":
            placed = self.placed
            return ["0", NOTHING] if placed is None else [str(int(placed[1])), encode(placed[0])]
        if keyword == "CHART":
            return self._chart(rest)
        if keyword == "LOAD":
            slot, _, identifier = rest.partition(" ")
            if not slot or not identifier or " " in identifier:
                raise ValueError("LOAD <slot> <identifier>")
            self.magazine[decode(identifier)] = decode(slot)
            return [slot, identifier]
        nd, _, field = rest.partition(" ")
        if nd not in ("0", "1") or not field or " " in field:
            raise ValueError("PLACE <nd 0|1> <what>")
        what = check_thing(decode(field))
        with self._lock:
            if self.placed != (what, nd == "1"):
                self._place(*self.shown_as(what, nd == "1"))
                self.placed = (what, nd == "1")
        return [nd, encode(what)]
