"""The LED sphere's serial protocol, declared in one place (docs/led-sphere-protocol.md describes it for people).

Every command is one row of :data:`TABLE`: its Python name, its keyword on the wire, the typed fields of the request
and of the ``OK`` reply, which reply fields must echo the request, and how the reply becomes a Python value.
Both sides use the same rows: the host driver (:mod:`drivers.led_sphere.driver`) encodes requests and decodes
replies with them, and the emulator (:mod:`drivers.virtual.sphere_emulator`) parses requests and renders replies
with them, so the two cannot drift apart. (The idea follows pymeasure's declarative ``Instrument.control``; it is
written out here because our firmware protocol is ours and pymeasure is not a dependency.)

Wire format: ASCII lines, 115200 8N1, each request ends with ``\\n``; exactly one reply line per request:
``OK <KEYWORD> [fields]\\n`` or ``ERR <code> <message>\\n``. Wire units are integers where the firmware counts
(PWM 0..65535, milliseconds) and decimals where it measures (seconds, degrees Celsius).
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

BAUDRATE = 115200
BYTESIZE = 8
PARITY = "N"
STOPBITS = 1
TERMINATOR = b"\n"
MAX_REQUEST_BYTES = 96      # the firmware's line buffer, terminator included (LEVELS with 16 channels fits)
MAX_REPLY_BYTES = 160       # the longest reply the firmware sends, terminator included
PWM_MAX = 65535             # 16-bit PWM: level 1.0
MAX_CHANNELS = 16           # the protocol allows up to 16 channels; the sphere has 10
WATCHDOG_MIN_MS = 100
WATCHDOG_MAX_MS = 3_600_000
DEFAULT_WATCHDOG_MS = 30_000
ON_LIMIT_MIN_MS = 100       # ON <ms>: the on-time limit the device enforces by itself
ON_LIMIT_MAX_MS = 3_600_000
FIRMWARE_VERSION = "1.1.0"  # the protocol version this table describes (ON <ms> came with 1.1.0)


class ErrorCode(enum.IntEnum):
    """The codes in ``ERR <code> <message>`` replies."""

    UNKNOWN_COMMAND = 1      # keyword not known
    ARGUMENT_COUNT = 2       # too few / too many arguments
    NOT_A_NUMBER = 3         # an argument is not an unsigned decimal integer
    OUT_OF_RANGE = 4         # LED number, PWM value or watchdog time outside its range
    LINE_TOO_LONG = 5        # request longer than MAX_REQUEST_BYTES; the rest of the line is discarded
    LED_FAULT = 6            # the LED's driver reports a fault (open circuit / short); level not taken
    OVER_TEMPERATURE = 7     # sphere too hot: LIGHT 1 refused (and light switched off if it was on)


#: What the operator should do, per device error code (used in SphereError messages).
ERROR_ADVICE = {
    ErrorCode.UNKNOWN_COMMAND: "the firmware does not know this command; check the firmware version (identify)",
    ErrorCode.ARGUMENT_COUNT: "host and firmware disagree on the protocol; check the firmware version (identify)",
    ErrorCode.NOT_A_NUMBER: "host and firmware disagree on the protocol; check the firmware version (identify)",
    ErrorCode.OUT_OF_RANGE: "use LED 1..channels, level 0..1 and a watchdog of 0.1..3600 s",
    ErrorCode.LINE_TOO_LONG: "the request was cut; check baud rate 115200 and that nothing else writes to the port",
    ErrorCode.LED_FAULT: "that LED channel is faulty: check its connector and driver, or leave it out of the preset",
    ErrorCode.OVER_TEMPERATURE: "let the sphere cool down (light off, check its fan) before switching on again",
}


class RequestError(Exception):
    """Device side: a request the firmware answers with ``ERR <code> <message>``."""

    def __init__(self, code: ErrorCode, message: str):
        super().__init__(message)
        self.code = ErrorCode(code)
        self.message = message


class ReplyError(ValueError):
    """Host side: a reply line that is not a well-formed answer to the request (garbled)."""


class StaleReply(ReplyError):
    """Host side: a well-formed OK reply, but to another request (a late reply); the host skips it."""


class DeviceReply(Exception):
    """Host side: the device answered ``ERR <code> <message>``."""

    def __init__(self, code: int, message: str):
        super().__init__(f"ERR {code} {message}")
        self.code = code
        self.message = message


# --------------------------------------------------------------------------------------------------- fields
def _number_text(value: float | None) -> str:
    if value is None:
        return ""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


_PATTERNS = {
    "int": r"\d{1,7}",
    "float": r"-?\d{1,7}(?:\.\d{1,4})?",
    "word": r"[!-~]{1,32}",
    "ints": r"\d{1,5}(?: \d{1,5}){0,15}",
}


@dataclass(frozen=True)
class Field:
    """One typed value on the wire: ``int`` (unsigned decimal), ``float`` (fixed decimals), ``word`` (printable
    ASCII, no spaces) or ``ints`` (1..16 space-separated unsigned integers, last field only).
    ``key`` fields are written ``name=value`` (STATUS?)."""

    name: str
    kind: str
    lo: float | None = None
    hi: float | None = None
    decimals: int = 0
    key: bool = False

    def __post_init__(self) -> None:
        if self.kind not in _PATTERNS:
            raise ValueError(f"field {self.name}: unknown kind {self.kind!r}")

    @property
    def pattern(self) -> str:
        prefix = re.escape(self.name + "=") if self.key else ""
        return f"{prefix}(?P<{self.name}>{_PATTERNS[self.kind]})"

    def _range_text(self) -> str:
        """``lo..hi`` as the ERR 4 message and the docs write it: whole numbers in full (``100..3600000``, not
        ``3.6e+06``: the reference firmware prints the same text, firmware/src/protocol_table.h)."""
        return f"{_number_text(self.lo)}..{_number_text(self.hi)}"

    def _check_number(self, v: float) -> None:
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"{self.name} {v} is not a finite number")
        if (self.lo is not None and v < self.lo) or (self.hi is not None and v > self.hi):
            raise ValueError(f"{self.name} {v} is outside {self._range_text()}")

    def check(self, value: Any) -> Any:
        """Validate a Python value for this field (host side); returns the normalised value."""
        if self.kind == "int":
            if isinstance(value, bool) or not float(value).is_integer():
                raise ValueError(f"{self.name} {value!r} is not an integer")
            value = int(value)
            self._check_number(value)
        elif self.kind == "float":
            value = float(value)
            self._check_number(value)
        elif self.kind == "word":
            value = str(value)
            if not re.fullmatch(_PATTERNS["word"], value):
                raise ValueError(f"{self.name} {value!r} is not a printable word")
        else:
            items = [Field(self.name, "int", self.lo, self.hi).check(v) for v in value]
            if not 1 <= len(items) <= MAX_CHANNELS:
                raise ValueError(f"{self.name}: {len(items)} values, expected 1..{MAX_CHANNELS}")
            value = tuple(items)
        return value

    def render(self, value: Any) -> str:
        if self.kind == "float":
            text = f"{float(value):.{self.decimals}f}"
        elif self.kind == "ints":
            text = " ".join(str(int(v)) for v in value)
        elif self.kind == "int":
            text = str(int(value))
        else:
            text = str(value)
        return f"{self.name}={text}" if self.key else text

    def parse(self, text: str) -> Any:
        """Parse wire text (already matched by :attr:`pattern`); raises ValueError when out of range."""
        if self.kind == "int":
            value: Any = int(text)
            self._check_number(value)
        elif self.kind == "float":
            value = float(text)
            self._check_number(value)
        elif self.kind == "ints":
            value = tuple(int(t) for t in text.split(" "))
            for v in value:
                Field(self.name, "int", self.lo, self.hi)._check_number(v)
        else:
            value = text
        return value


# --------------------------------------------------------------------------------------------------- commands
def _single(fields: dict[str, Any]) -> Any:
    return next(iter(fields.values())) if len(fields) == 1 else (fields or None)


@dataclass(frozen=True)
class Command:
    """One request/reply pair. ``echo`` names reply fields that must equal the request's (so a late reply to
    an earlier request is recognised and skipped). ``result`` turns the parsed reply fields into the value the
    driver returns (default: the single field's value, a dict for several, None for none)."""

    name: str
    keyword: str
    args: tuple[Field, ...] = ()
    reply: tuple[Field, ...] = ()
    echo: tuple[str, ...] = ()
    result: Callable[[dict[str, Any]], Any] = _single
    doc: str = ""
    example: tuple[dict[str, Any], dict[str, Any]] = ({}, {})   # (request args, reply fields) for docs and tests
    since: str = "1.0.0"        # the firmware version that introduced the command (older firmware: ERR 1)

    @property
    def reply_keyword(self) -> str:
        return self.keyword.rstrip("?")

    @property
    def reply_regex(self) -> re.Pattern[str]:
        body = "".join(" " + f.pattern for f in self.reply)
        return re.compile(f"OK {re.escape(self.reply_keyword)}{body}")

    # host side ------------------------------------------------------------------------------------------
    def encode(self, **values: Any) -> bytes:
        """The request line for these argument values; raises ValueError for a missing/invalid value."""
        names = [f.name for f in self.args]
        if sorted(values) != sorted(names):
            raise ValueError(f"{self.name}: expected arguments {names}, got {sorted(values)}")
        parts = [self.keyword] + [f.render(f.check(values[f.name])) for f in self.args]
        line = (" ".join(parts)).encode("ascii") + TERMINATOR
        if len(line) > MAX_REQUEST_BYTES:
            raise ValueError(f"{self.name}: request of {len(line)} bytes exceeds {MAX_REQUEST_BYTES}")
        return line

    def decode(self, line: bytes, sent: dict[str, Any] | None = None) -> dict[str, Any]:
        """Parse one reply line (terminator included or not) to this request.

        Returns the reply fields; raises :class:`DeviceReply` for ``ERR``, :class:`StaleReply` for a reply to
        another request, :class:`ReplyError` for anything malformed."""
        text = _reply_text(line)
        if text.startswith("ERR "):
            m = _ERR_RE.fullmatch(text)
            if not m:
                raise ReplyError(f"malformed error reply {_show(line)}")
            raise DeviceReply(int(m["code"]), m["message"])
        if not text.startswith("OK "):
            raise ReplyError(f"reply {_show(line)} is neither 'OK ...' nor 'ERR <code> <message>'")
        keyword = text[3:].split(" ", 1)[0]
        if keyword != self.reply_keyword:
            if keyword in _REPLY_KEYWORDS:
                raise StaleReply(f"reply {_show(line)} answers {keyword}, not {self.reply_keyword}")
            raise ReplyError(f"reply {_show(line)} has unknown keyword {keyword[:20]!r}")
        m = self.reply_regex.fullmatch(text)
        if not m:
            raise ReplyError(f"reply {_show(line)} does not match 'OK {self.reply_format()}'")
        try:
            fields = {f.name: f.parse(m[f.name]) for f in self.reply}
        except ValueError as exc:
            raise ReplyError(f"reply {_show(line)}: {exc}") from None
        for name in self.echo:
            expected = (sent or {}).get(name)
            if expected is not None and fields[name] != _normalise(expected):
                raise StaleReply(f"reply {_show(line)} echoes {name}={fields[name]}, sent {expected}")
        return fields

    def value(self, fields: dict[str, Any]) -> Any:
        return self.result(fields)

    # device side ----------------------------------------------------------------------------------------
    def parse_args(self, tokens: list[str]) -> dict[str, Any]:
        """Device side: argument tokens (after the keyword) -> values; raises :class:`RequestError`."""
        fields = self.args
        list_field = fields[-1] if fields and fields[-1].kind == "ints" else None
        n_fixed = len(fields) - (1 if list_field else 0)
        if len(tokens) < len(fields) or (not list_field and len(tokens) > len(fields)) \
                or (list_field and len(tokens) - n_fixed > MAX_CHANNELS):
            raise RequestError(ErrorCode.ARGUMENT_COUNT,
                               f"{self.keyword} takes {self.arg_format() or 'no arguments'}")
        values: dict[str, Any] = {}
        for i, f in enumerate(fields):
            chunk = tokens[i:] if f is list_field else [tokens[i]]
            if not all(t.isdigit() and t.isascii() and len(t) <= 7 for t in chunk):
                raise RequestError(ErrorCode.NOT_A_NUMBER, f"{f.name} must be an unsigned integer")
            try:
                values[f.name] = f.parse(" ".join(chunk))
            except ValueError:
                raise RequestError(ErrorCode.OUT_OF_RANGE, f"{f.name} outside {f._range_text()}") from None
        return values

    def render_reply(self, **values: Any) -> bytes:
        """Device side: the ``OK`` reply line for these field values."""
        parts = ["OK", self.reply_keyword] + [f.render(values[f.name]) for f in self.reply]
        return " ".join(parts).encode("ascii") + TERMINATOR

    # documentation --------------------------------------------------------------------------------------
    def arg_format(self) -> str:
        return " ".join(f"<{f.name}>" + (" ..." if f.kind == "ints" else "") for f in self.args)

    def reply_format(self) -> str:
        fields = [(f"{f.name}=" if f.key else "") + f"<{f.name}>" + (" ..." if f.kind == "ints" else "")
                  for f in self.reply]
        return " ".join([self.reply_keyword] + fields)

    def example_bytes(self) -> tuple[bytes, bytes]:
        args, reply = self.example
        return self.encode(**args), self.render_reply(**reply)


def render_error(code: ErrorCode, message: str) -> bytes:
    """Device side: an ``ERR`` line (message cut to fit, printable ASCII only)."""
    clean = "".join(c if " " <= c <= "~" else "?" for c in message)[:100] or "error"
    return f"ERR {int(code)} {clean}".encode("ascii") + TERMINATOR


_ERR_RE = re.compile(r"ERR (?P<code>\d{1,3}) (?P<message>[ -~]{1,140})")


def _reply_text(line: bytes) -> str:
    if line.endswith(b"\r\n"):
        line = line[:-2]
    elif line.endswith(b"\n"):
        line = line[:-1]
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        raise ReplyError(f"reply {_show(line)} is not ASCII") from None
    if not text.isprintable():
        raise ReplyError(f"reply {_show(line)} contains control characters")
    return text


def _show(line: bytes, limit: int = 48) -> str:
    text = repr(bytes(line[:limit]))
    return text + ("..." if len(line) > limit else "")


def _normalise(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return tuple(int(v) for v in value)
    return value


def version_tuple(version: str) -> tuple[int, ...]:
    """'1.1.0' -> (1, 1, 0); a version that does not parse counts as (0,) (older than any)."""
    try:
        return tuple(int(part) for part in str(version).split("."))
    except ValueError:
        return (0,)


def supports(cmd: Command, firmware: str) -> bool:
    """Whether firmware ``firmware`` knows ``cmd`` (by the version that introduced it)."""
    return version_tuple(firmware) >= version_tuple(cmd.since)


def level_to_pwm(level: float) -> int:
    """Level 0..1 -> 16-bit PWM (round to nearest)."""
    return int(round(float(level) * PWM_MAX))


def pwm_to_level(pwm: int) -> float:
    return int(pwm) / PWM_MAX


# --------------------------------------------------------------------------------------------------- the table
LED = Field("led", "int", 1, MAX_CHANNELS)
PWM = Field("pwm", "int", 0, PWM_MAX)
PWMS = Field("pwms", "ints", 0, PWM_MAX)
STATE = Field("state", "int", 0, 1)
WATCHDOG = Field("ms", "int", WATCHDOG_MIN_MS, WATCHDOG_MAX_MS)
SECONDS = Field("seconds", "float", 0, None, decimals=3)
CELSIUS = Field("celsius", "float", -55, 150, decimals=2)
MASK = Field("mask", "int", 0, 2 ** MAX_CHANNELS - 1)
_ZEROS10 = (0,) * 10
_EX_LEVELS = (0, 65535, 0, 0, 0, 32768, 0, 0, 0, 0)

TABLE: tuple[Command, ...] = (
    Command("identify", "IDN?",
            reply=(Field("model", "word"), Field("firmware", "word"), Field("serial", "word")), result=dict,
            doc="model, firmware version and serial number (no spaces in any of them)",
            example=({}, {"model": "DRGB-SPHERE10", "firmware": "1.1.0", "serial": "SN0001"})),
    Command("channels", "CHANNELS?", reply=(Field("count", "int", 1, MAX_CHANNELS),),
            doc="number of LED channels (10 on our sphere)", example=({}, {"count": 10})),
    Command("set_level", "LEVEL", args=(LED, PWM), reply=(LED, PWM), echo=("led", "pwm"),
            result=lambda f: f["pwm"],
            doc="set one LED's PWM level (0..65535 = level 0..1); emitted only while the light is on",
            example=({"led": 4, "pwm": 32768}, {"led": 4, "pwm": 32768})),
    Command("get_level", "LEVEL?", args=(LED,), reply=(LED, PWM), echo=("led",), result=lambda f: f["pwm"],
            doc="read one LED's PWM level back", example=({"led": 4}, {"led": 4, "pwm": 32768})),
    Command("set_levels", "LEVELS", args=(PWMS,), reply=(PWMS,), echo=("pwms",),
            doc="set every channel at once (exactly <channels> values, LED 1 first); atomic: all or none",
            example=({"pwms": _EX_LEVELS}, {"pwms": _EX_LEVELS})),
    Command("get_levels", "LEVELS?", reply=(PWMS,), doc="read every channel's PWM level",
            example=({}, {"pwms": _ZEROS10})),
    Command("all_off", "ALLOFF", doc="every LED's level to 0 (the master switch is left as it is)"),
    Command("set_light", "LIGHT", args=(STATE,), reply=(STATE,), echo=("state",),
            doc="master enable: 1 = LEDs emit at their levels, 0 = nothing emits (levels are kept)",
            example=({"state": 1}, {"state": 1})),
    Command("light_on_for", "ON", args=(Field("ms", "int", ON_LIMIT_MIN_MS, ON_LIMIT_MAX_MS),),
            reply=(Field("ms", "int", ON_LIMIT_MIN_MS, ON_LIMIT_MAX_MS),), echo=("ms",), since="1.1.0",
            doc="light on (as LIGHT 1) for at most <ms> ms counted from the moment it came on; then the "
                "firmware switches it off by itself (LIGHT 0, trip = 1). Sent again while on, it never "
                "extends the lit period beyond <ms> from that moment",
            example=({"ms": 10000}, {"ms": 10000})),
    Command("get_light", "LIGHT?", reply=(STATE,), doc="master enable state", example=({}, {"state": 0})),
    Command("temperature", "TEMP?", reply=(CELSIUS,), doc="sphere (LED heat sink) temperature in degrees C",
            example=({}, {"celsius": 27.31})),
    Command("on_time", "ONTIME?", reply=(SECONDS,),
            doc="seconds since the light was switched on (0.000 while off)", example=({}, {"seconds": 12.5})),
    Command("led_on_time", "LEDTIME?", args=(LED,), reply=(LED, SECONDS), echo=("led",),
            result=lambda f: f["seconds"],
            doc="seconds this LED has been emitting continuously (0.000 while dark)",
            example=({"led": 4}, {"led": 4, "seconds": 8.25})),
    Command("set_watchdog", "WDOG", args=(WATCHDOG,), reply=(WATCHDOG,), echo=("ms",),
            doc="watchdog in ms (100..3600000): with no request for that long, the sphere switches every LED off",
            example=({"ms": 30000}, {"ms": 30000})),
    Command("get_watchdog", "WDOG?", reply=(WATCHDOG,), doc="watchdog time in ms",
            example=({}, {"ms": 30000})),
    Command("ping", "PING", doc="keepalive: does nothing but restart the watchdog (every request does that)"),
    Command("faults", "FAULT?", reply=(MASK,),
            doc="bit mask of LED channels reporting a fault (bit 0 = LED 1), e.g. an open circuit while driven",
            example=({}, {"mask": 8})),
    Command("status", "STATUS?",
            reply=(Field("light", "int", 0, 1, key=True), Field("ontime", "float", 0, None, 3, key=True),
                   Field("temp", "float", -55, 150, 2, key=True),
                   Field("wdog", "int", WATCHDOG_MIN_MS, WATCHDOG_MAX_MS, key=True),
                   Field("trip", "int", 0, 1, key=True), Field("fault", "int", 0, 2 ** MAX_CHANNELS - 1, key=True)),
            result=dict,
            doc="light state, on-time (s), temperature (C), watchdog (ms), trip = 1 if the sphere switched the "
                "light off by itself (watchdog, on-time limit) since the last LIGHT 1 / ON, fault mask",
            example=({}, {"light": 1, "ontime": 12.5, "temp": 27.31, "wdog": 30000, "trip": 0, "fault": 0})),
)

COMMANDS: dict[str, Command] = {c.name: c for c in TABLE}
BY_KEYWORD: dict[str, Command] = {c.keyword: c for c in TABLE}
_REPLY_KEYWORDS = frozenset(c.reply_keyword for c in TABLE)
assert len(COMMANDS) == len(TABLE) and len(BY_KEYWORD) == len(TABLE), "duplicate command in TABLE"


def parse_request(line: bytes) -> tuple[Command, dict[str, Any]]:
    """Device side: one request line (terminator stripped) -> (command, argument values).

    Keywords are case-insensitive and arguments may be separated by any run of spaces; raises RequestError."""
    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError:
        raise RequestError(ErrorCode.UNKNOWN_COMMAND, "request is not ASCII") from None
    tokens = text.split()
    if not tokens:
        raise RequestError(ErrorCode.UNKNOWN_COMMAND, "empty request")
    cmd = BY_KEYWORD.get(tokens[0].upper())
    if cmd is None:
        shown = "".join(c if " " <= c <= "~" else "?" for c in tokens[0][:16])
        raise RequestError(ErrorCode.UNKNOWN_COMMAND, f"unknown command {shown}")
    return cmd, cmd.parse_args(tokens[1:])
