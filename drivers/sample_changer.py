"""An automated sample changer on the copy stand: the device that puts what a step needs under the camera (a
target, the open gate, the lens cap, an original), so that nobody has to when a plan asks for it.

Its serial protocol (docs/sample-changer-protocol.md; the command table is :data:`COMMANDS`, the one place both
ends read): ASCII lines, ``\\n``-terminated, one reply line per request, ``OK <KEYWORD> [fields]`` or
``ERR <code> <message>``. A thing's name and an identifier travel percent-encoded UTF-8 (:func:`encode`: ``東博 7``
is ``%E6%9D%B1%E5%8D%9A%207``), so a field is one word of ASCII whatever the original is called.

* ``IDN?`` -> ``OK IDN <model> <version> <serial>``
* ``PLACE <nd> <what>`` -> ``OK PLACE <nd> <what>`` once ``what`` (percent-encoded) lies under the camera (``nd``
  1: with the ND filter laid over it as the changer's ND setting says); ``what``: ``train``, ``test``,
  ``open-gate``, ``lens-cap`` or ``original:<identifier>``
* ``PLACED?`` -> ``OK PLACED <nd> <what>`` (``-`` for nothing yet)
* ``LOAD <slot> <identifier>`` -> ``OK LOAD <slot> <identifier>``: the original ``identifier`` is in magazine slot
  ``slot`` (``*`` for any original not loaded by name)
* ``CHART <role> <layout> <leave-out> <file>`` -> ``OK CHART <role>``: the virtual lab's changer only (a physical
  one holds the charts that were put in it): hold the chart of reference ``file`` (layout ``ROWSxCOLS``, patches
  left out comma-separated, ``-`` for none or the file's own) as the training (``train``) or test (``test``)
  target; ``CHART <role> - - -`` the packaged one again

The transport is a pyserial URL (a USB-serial port, or ``socket://HOST:PORT`` as `dualrgb lab serve` prints).

    with SampleChanger("socket://127.0.0.1:40125") as changer:
        changer.place("test")                   # returns when it lies there
"""
from __future__ import annotations

import logging
import re
import threading
from typing import Any
from urllib.parse import quote, unquote

import serial

from dualrgb.common.errors import ReportedError

log = logging.getLogger(__name__)

MAX_LINE = 512                          # a request: an identifier of 40 CJK characters, percent-encoded, fits
TIMEOUT_S = 30.0                        # moving a chart takes the changer a few seconds at most
COMMANDS = {                            # keyword -> the reply's keyword (one table for both ends)
    "IDN?": "IDN", "PLACE": "PLACE", "PLACED?": "PLACED", "LOAD": "LOAD",
    "CHART": "CHART",                   # the virtual lab's changer only: which chart it holds (module docstring)
}
PLACES = ("train", "test", "open-gate", "lens-cap")
ORIGINAL_PREFIX = "original:"
ANY_ORIGINAL = "*"
NOTHING = "-"
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
ERR_UNKNOWN, ERR_ARGUMENT, ERR_CANNOT, ERR_TOO_LONG = 1, 2, 3, 5


class ChangerError(ReportedError, RuntimeError):
    """The sample changer did not do what it was asked (one line saying what to do)."""


def encode(text: str) -> str:
    """A name as one field of the protocol: percent-encoded UTF-8 (``:`` and ``*`` kept)."""
    return quote(str(text), safe=":*")


def decode(field: str) -> str:
    """:func:`encode` undone."""
    return unquote(field)


def check_thing(what: str) -> str:
    """``what`` when the changer can be asked to place it, else a one-line ValueError."""
    what = str(what).strip()
    ok = what in PLACES or (what.startswith(ORIGINAL_PREFIX) and len(what) > len(ORIGINAL_PREFIX))
    if not ok or _CONTROL.search(what) or len(encode(what)) > MAX_LINE - 16:
        raise ValueError(f"cannot place {what!r}: expected one of {', '.join(PLACES)} or {ORIGINAL_PREFIX}<identifier>")
    return what


def request_line(keyword: str, *fields: object) -> bytes:
    """The canonical request line (``PLACE 0 test\\n``)."""
    if keyword not in COMMANDS:
        raise ValueError(f"unknown sample changer command {keyword!r}")
    text = " ".join([keyword, *(str(f) for f in fields)])
    if len(text) + 1 > MAX_LINE or not text.isascii() or _CONTROL.search(text):
        raise ValueError(f"sample changer request {text[:40]!r}...: at most {MAX_LINE} ASCII bytes")
    return text.encode() + b"\n"


def parse_reply(keyword: str, line: bytes) -> list[str]:
    """The fields of the reply to ``keyword``; ChangerError for ``ERR`` or anything else."""
    text = line.decode("ascii", "replace").strip()
    if text.startswith("ERR "):
        raise ChangerError(f"sample changer: {text[4:].partition(' ')[2] or text}")
    parts = text.split(" ", 2)
    if len(parts) < 2 or parts[0] != "OK" or parts[1] != COMMANDS[keyword]:
        raise ChangerError(f"sample changer: unexpected reply {text[:60]!r} to {keyword}")
    return parts[2].split(" ", 1) if len(parts) > 2 else []


class SampleChanger:
    """The sample changer on ``port`` (a pyserial URL); see the module docstring."""

    def __init__(self, port: str, timeout: float = TIMEOUT_S):
        self.port, self.timeout = str(port), float(timeout)
        self._ser: Any = None
        self._lock = threading.Lock()

    def open(self) -> SampleChanger:
        if self._ser is None:
            try:
                self._ser = serial.serial_for_url(self.port, timeout=self.timeout, write_timeout=self.timeout)
            except (serial.SerialException, OSError, ValueError) as exc:
                raise ChangerError(f"cannot open the sample changer on {self.port}: {exc}; check the address "
                                   "(`dualrgb lab serve` prints it) and the cable") from None
        return self

    def close(self) -> None:
        ser, self._ser = self._ser, None
        if ser is not None:
            ser.close()

    def __enter__(self) -> SampleChanger:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request(self, keyword: str, *fields: object) -> list[str]:
        """One request (:data:`COMMANDS`) and the fields of its reply."""
        return self._ask(keyword, *fields)

    def _ask(self, keyword: str, *fields: object) -> list[str]:
        with self._lock:
            if self._ser is None:
                self.open()
            try:
                self._ser.reset_input_buffer()
                self._ser.write(request_line(keyword, *fields))
                line = self._ser.read_until(b"\n", MAX_LINE)
            except (serial.SerialException, OSError) as exc:
                raise ChangerError(f"sample changer on {self.port}: {exc}; check the cable") from None
        if not line.endswith(b"\n"):
            raise ChangerError(f"sample changer on {self.port}: no answer to {keyword} within {self.timeout:g} s")
        return parse_reply(keyword, line)

    def identify(self) -> dict[str, str]:
        model, _, rest = " ".join(self._ask("IDN?")).partition(" ")
        version, _, serial_no = rest.partition(" ")
        return {"model": model, "version": version, "serial": serial_no}

    def place(self, what: str, nd: bool = False) -> str:
        """Put ``what`` under the camera (``nd``: with the ND filter over it); returns when it lies there."""
        fields = self._ask("PLACE", int(bool(nd)), encode(check_thing(what)))
        log.info("sample changer: %s%s placed", what, " + ND" if nd else "")
        return decode(fields[-1]) if fields else what

    def placed(self) -> tuple[str, bool] | None:
        """What lies under the camera now (None: nothing placed yet)."""
        nd, what = (self._ask("PLACED?") + ["0", NOTHING])[:2]
        return None if what == NOTHING else (decode(what), nd == "1")

    def load(self, identifier: str, slot: str) -> None:
        """Magazine slot ``slot`` holds the original ``identifier`` (:data:`ANY_ORIGINAL`: any not loaded by name)."""
        if not slot.strip() or not identifier.strip() or _CONTROL.search(slot + identifier):
            raise ValueError(f"magazine slot {slot!r} for {identifier!r}: expected a slot and an identifier")
        self._ask("LOAD", encode(slot), encode(identifier))
