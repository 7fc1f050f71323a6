"""The Newport / Oriel Cornerstone 130 / 260 monochromators' ASCII serial protocol, declared in one place
(docs/monochromator-protocol.md describes it for people).

Every statement the driver uses is one row of :data:`TABLE`: its Python name, its keyword on the wire, the typed
argument it takes (validated on the host before anything is sent, parsed on the device side) and, for a query,
the typed answer. Both sides use the same rows: the host driver (:mod:`drivers.monochromator.driver`) encodes
statements and decodes answers with them, and the emulator (:mod:`drivers.virtual.monochromator_emulator`) parses
statements and renders answers with them, so the two cannot drift apart (pymeasure's ``Instrument.control`` idea,
written out because pymeasure is not a dependency).

Wire format, from the Cornerstone 130 / 260 manuals (appendix "Low level commands and queries", standard mode):

* RS-232, 9600 baud, 8 data bits, no parity, 1 stop bit, no flow control;
* a *statement* is one ASCII line ending in CR LF (a bare LF is accepted too), upper or lower case; numeric
  parameters are decimal strings separated from the keyword by a space;
* under RS-232 the monochromator **echoes every statement** back as it receives it; a *command* (``GOWAVE 550``)
  gets nothing more, a *query* (``WAVE?``) is followed by one answer line ending in CR LF;
* errors are not answered: they set bit 5 of the status byte (``STB?`` answers ``00`` or ``20``, hexadecimal)
  and an error code (``ERROR?``, table :class:`ErrorCode`); reading either clears it. The driver reads ``STB?``
  after every command and, when it is not ``00``, ``ERROR?``;
* while the wavelength drive, the grating turret or the filter wheel moves, the next statement is answered only
  when the motion has ended, so the ``STB?`` after a motion waits up to the motion timeout.

The manual gives the answers' shapes (``SHUTTER?`` -> ``O`` / ``C``, ``GRAT?`` -> ``<n>,<lines/mm>,<label>``,
``FILTER?`` -> the position, ``0`` when the wheel is out of position); what it leaves open (the text of
``INFO?``, what ``ERROR?`` answers when there is no error: an empty line here) is marked in the protocol note.
"""
from __future__ import annotations

import enum
import logging
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

BAUDRATE = 9600
BYTESIZE = 8
PARITY = "N"
STOPBITS = 1
TERMINATOR = b"\r\n"          # statements and answers; the device also accepts a bare b"\n"
MAX_LINE_BYTES = 80           # the longest statement or answer line, terminator included
STATUS_OK = 0x00
STATUS_ERROR = 0x20           # bit 5: an error code is waiting in ERROR?
MAX_WAVELENGTH_NM = 2500.0    # the host refuses anything above (the device refuses outside the grating's range)
N_GRATINGS = 3
N_FILTERS = 6
UNITS = ("NM", "UM", "WN")    # nanometres, micrometres, wavenumbers (cm^-1); the driver always uses NM


class ErrorCode(enum.IntEnum):
    """The codes ``ERROR?`` answers (Cornerstone manual, "Error codes for low level commands")."""

    SYSTEM = 0                    # system error (miscellaneous)
    NOT_UNDERSTOOD = 1            # command not understood
    BAD_PARAMETER = 2             # bad parameter used in command
    DESTINATION_NOT_ALLOWED = 3   # destination position for wavelength motion not allowed
    NO_ACCESSORY = 6              # accessory not present (usually the filter wheel)
    ALREADY_THERE = 7             # accessory already in the specified position
    HOME_FAILED = 8               # could not home the wavelength drive
    LABEL_TOO_LONG = 9            # label too long


#: What the operator should do, per error code (used in MonochromatorError messages).
ERROR_ADVICE = {
    ErrorCode.SYSTEM: "switch the monochromator off and on again; if it persists, have it serviced",
    ErrorCode.NOT_UNDERSTOOD: "host and monochromator disagree on the protocol; check the model (INFO?) and that "
                              "nothing else writes to the port",
    ErrorCode.BAD_PARAMETER: "the value was refused; check the grating / filter numbers this unit has",
    ErrorCode.DESTINATION_NOT_ALLOWED: "the wavelength is outside the current grating's range; choose another "
                                       "grating or range",
    ErrorCode.NO_ACCESSORY: "this unit has no filter wheel (or it is unplugged)",
    ErrorCode.ALREADY_THERE: "the accessory was already in that position",
    ErrorCode.HOME_FAILED: "the wavelength drive could not find home: switch the monochromator off and on again",
    ErrorCode.LABEL_TOO_LONG: "labels are at most 8 characters",
}


class RequestError(Exception):
    """Device side: a statement the monochromator refuses (it sets the status byte and this error code)."""

    def __init__(self, code: ErrorCode, message: str):
        super().__init__(message)
        self.code = ErrorCode(code)
        self.message = message


class ReplyError(ValueError):
    """Host side: an echo or answer line that is not what the statement expects (garbled)."""


@dataclass(frozen=True)
class GratingInfo:
    """``GRAT?``: the grating in use, its groove density and its label (e.g. the blaze, ``500NM``)."""

    number: int
    lines_per_mm: int
    label: str


# --------------------------------------------------------------------------------------------------- values
@dataclass(frozen=True)
class Arg:
    """The typed parameter of a command: ``float`` (``decimals`` on the wire), ``int`` or ``choice``."""

    name: str
    kind: str
    lo: float | None = None
    hi: float | None = None
    decimals: int = 0
    choices: tuple[str, ...] = ()

    def check(self, value: Any) -> Any:
        """Host side: validate a Python value; returns it normalised (ValueError naming the value otherwise)."""
        if self.kind == "choice":
            text = str(value).upper()
            if text not in self.choices:
                raise ValueError(f"{self.name} {value!r}: expected one of {', '.join(self.choices)}")
            return text
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"{self.name} {value!r} is not a finite number")
        if self.kind == "int" and not float(value).is_integer():
            raise ValueError(f"{self.name} {value!r} is not a whole number")
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            raise ValueError(f"{self.name} {value:g} is outside {self.lo:g}..{self.hi:g}")
        return int(value) if self.kind == "int" else float(value)

    def render(self, value: Any) -> str:
        if self.kind == "float":
            return f"{float(value):.{self.decimals}f}"
        return str(int(value)) if self.kind == "int" else str(value)

    def parse(self, token: str) -> Any:
        """Device side: a parameter token -> value; raises RequestError(BAD_PARAMETER)."""
        try:
            value: Any = token.upper() if self.kind == "choice" else float(token)
            return self.check(value)
        except ValueError:
            raise RequestError(ErrorCode.BAD_PARAMETER, f"{self.name} {token!r}") from None


@dataclass(frozen=True)
class Answer:
    """The typed answer line of a query: ``pattern`` (a full match of the line without CR LF), ``convert`` to
    the Python value and ``render`` back to the wire (device side)."""

    pattern: str
    convert: Callable[[re.Match[str]], Any]
    render: Callable[[Any], str]
    shape: str                    # for docs and messages

    def parse(self, text: str) -> Any:
        m = re.fullmatch(self.pattern, text)
        if m is None:
            raise ReplyError(f"answer {text[:40]!r} does not match {self.shape}")
        return self.convert(m)


def _grating_text(g: GratingInfo) -> str:
    return f"{g.number},{g.lines_per_mm},{g.label}"


def _error_text(code: int | None) -> str:
    return "" if code is None else str(int(code))


FLOAT_ANSWER = Answer(r"-?\d{1,5}(?:\.\d{1,4})?", lambda m: float(m[0]), lambda v: f"{float(v):.3f}", "<number>")
INT_ANSWER = Answer(r"-?\d{1,9}", lambda m: int(m[0]), lambda v: str(int(v)), "<integer>")
TEXT_ANSWER = Answer(r"[ -~]{1,64}", lambda m: m[0].strip(), str, "<text>")
SHUTTER_ANSWER = Answer(r"[OC]", lambda m: m[0] == "O", lambda v: "O" if v else "C", "O or C")
GRATING_ANSWER = Answer(r"(?P<n>[1-9]),\s*(?P<lines>\d{1,5}),\s*(?P<label>[ -~]{0,16})",
                        lambda m: GratingInfo(int(m["n"]), int(m["lines"]), m["label"].strip()), _grating_text,
                        "<grating>,<lines/mm>,<label>")
FILTER_ANSWER = Answer(r"[0-9]", lambda m: int(m[0]), lambda v: str(int(v)), "a filter position 0..6")
UNITS_ANSWER = Answer("|".join(UNITS), lambda m: m[0], str, "NM, UM or WN")
STATUS_ANSWER = Answer(r"[0-9A-Fa-f]{2}", lambda m: int(m[0], 16), lambda v: f"{int(v):02X}", "two hex digits")
ERROR_ANSWER = Answer(r"\d?", lambda m: int(m[0]) if m[0] else None, _error_text, "an error code 0..9 or nothing")


# --------------------------------------------------------------------------------------------------- statements
@dataclass(frozen=True)
class Statement:
    """One statement: a command (``arg`` may be None) or a query (keyword ending in ``?``, with an ``answer``).
    ``motion``: the device moves a motor; the next statement is answered when it stops."""

    name: str
    keyword: str
    arg: Arg | None = None
    answer: Answer | None = None
    motion: bool = False
    doc: str = ""
    example: tuple[Any, Any] = (None, None)     # (argument value, answer value) for docs and tests

    @property
    def is_query(self) -> bool:
        return self.answer is not None

    def encode(self, value: Any = None) -> bytes:
        """Host side: the statement line for ``value`` (ValueError for a missing or invalid one)."""
        if self.arg is None:
            if value is not None:
                raise ValueError(f"{self.keyword} takes no parameter, got {value!r}")
            return self.keyword.encode("ascii") + TERMINATOR
        if value is None:
            raise ValueError(f"{self.keyword} needs its {self.arg.name}")
        text = f"{self.keyword} {self.arg.render(self.arg.check(value))}"
        return text.encode("ascii") + TERMINATOR

    def decode(self, line: bytes) -> Any:
        """Host side: the value of an answer line (ReplyError when it is garbled)."""
        if self.answer is None:
            raise ReplyError(f"{self.keyword} is a command: it has no answer")
        return self.answer.parse(line_text(line))

    def render_answer(self, value: Any) -> bytes:
        """Device side: the answer line for ``value``."""
        assert self.answer is not None, f"{self.keyword} is not a query"
        return self.answer.render(value).encode("ascii") + TERMINATOR

    def example_bytes(self) -> tuple[bytes, bytes]:
        """(statement, what comes back: its echo, then the answer of a query)."""
        arg, answer = self.example
        request = self.encode(arg)
        return request, request + (self.render_answer(answer) if self.is_query else b"")


NM = Arg("wavelength_nm", "float", 0.0, MAX_WAVELENGTH_NM, decimals=3)

TABLE: tuple[Statement, ...] = (
    Statement("info", "INFO?", answer=TEXT_ANSWER, doc="model and firmware (free text)",
              example=(None, "CS130 VER 1.01 EMULATOR")),
    Statement("goto", "GOWAVE", NM, motion=True, doc="move the wavelength drive to <nm> (in UNITS, here NM)",
              example=(550.0, None)),
    Statement("wavelength", "WAVE?", answer=FLOAT_ANSWER, doc="the wavelength the drive is at",
              example=(None, 550.0)),
    Statement("shutter", "SHUTTER", Arg("state", "choice", choices=("O", "C")),
              doc="open (O) or close (C) the output shutter", example=("C", None)),
    Statement("shutter_state", "SHUTTER?", answer=SHUTTER_ANSWER, doc="O (open) or C (closed)",
              example=(None, False)),
    Statement("set_grating", "GRAT", Arg("grating", "int", 1, N_GRATINGS), motion=True,
              doc="select grating 1..3 (the turret turns; the wavelength is kept)", example=(1, None)),
    Statement("grating", "GRAT?", answer=GRATING_ANSWER, doc="grating in use, its lines/mm and label",
              example=(None, GratingInfo(1, 1200, "500NM"))),
    Statement("set_filter", "FILTER", Arg("position", "int", 1, N_FILTERS), motion=True,
              doc="turn the filter wheel to position 1..6", example=(1, None)),
    Statement("filter", "FILTER?", answer=FILTER_ANSWER,
              doc="filter wheel position (0: out of position or no wheel)", example=(None, 1)),
    Statement("set_units", "UNITS", Arg("units", "choice", choices=UNITS),
              doc="units of GOWAVE / WAVE?: NM, UM or WN", example=("NM", None)),
    Statement("units", "UNITS?", answer=UNITS_ANSWER, doc="the units in use", example=(None, "NM")),
    Statement("step", "STEP?", answer=INT_ANSWER, doc="wavelength drive position in motor steps",
              example=(None, 123450)),
    Statement("status_byte", "STB?", answer=STATUS_ANSWER,
              doc="status byte, hex: 00 no error, 20 an error code is waiting (reading clears it)",
              example=(None, STATUS_OK)),
    Statement("error", "ERROR?", answer=ERROR_ANSWER,
              doc="the last error code (reading clears it); an empty line when there is none",
              example=(None, int(ErrorCode.DESTINATION_NOT_ALLOWED))),
)

COMMANDS: dict[str, Statement] = {s.name: s for s in TABLE}
BY_KEYWORD: dict[str, Statement] = {s.keyword: s for s in TABLE}
assert len(COMMANDS) == len(TABLE) and len(BY_KEYWORD) == len(TABLE), "duplicate statement in TABLE"


def line_text(line: bytes) -> str:
    """A received line without its terminator, as text (ReplyError when not printable ASCII)."""
    body = bytes(line)
    for end in (b"\r\n", b"\n", b"\r"):
        if body.endswith(end):
            body = body[:-len(end)]
            break
    try:
        text = body.decode("ascii")
    except UnicodeDecodeError:
        raise ReplyError(f"line {show(line)} is not ASCII") from None
    if not text.isprintable():
        raise ReplyError(f"line {show(line)} contains control characters")
    return text


def show(line: bytes, limit: int = 40) -> str:
    """A received line for a message (cut, escaped)."""
    return repr(bytes(line[:limit])) + ("..." if len(line) > limit else "")


def is_echo(line: bytes, request: bytes) -> bool:
    """Whether ``line`` is the monochromator's echo of ``request`` (the same statement, in any case)."""
    try:
        return line_text(line).strip().upper() == request.decode("ascii").strip().upper()
    except ReplyError:
        return False


def parse_statement(line: bytes) -> tuple[Statement, Any]:
    """Device side: one statement line (terminator stripped) -> (statement, argument value or None).

    Keywords are case-insensitive; raises RequestError (NOT_UNDERSTOOD or BAD_PARAMETER)."""
    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError:
        raise RequestError(ErrorCode.NOT_UNDERSTOOD, "statement is not ASCII") from None
    keyword, _, rest = text.partition(" ")
    stmt = BY_KEYWORD.get(keyword.upper())
    if stmt is None:
        raise RequestError(ErrorCode.NOT_UNDERSTOOD, f"unknown statement {keyword[:16]!r}")
    rest = rest.strip()
    if stmt.arg is None:
        if rest:
            raise RequestError(ErrorCode.BAD_PARAMETER, f"{stmt.keyword} takes no parameter")
        return stmt, None
    if not rest or " " in rest:
        raise RequestError(ErrorCode.BAD_PARAMETER, f"{stmt.keyword} takes one parameter")
    return stmt, stmt.arg.parse(rest)
