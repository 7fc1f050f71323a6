"""What libgphoto2's configuration labels mean: numbers parsed from shutter, aperture and ISO labels, and the
few words the driver must recognise (Bulb, On/Off, Internal RAM / Memory card, NEF (Raw)) in any language.

python-gphoto2 loads libgphoto2's translations, and a program that calls ``setlocale(LC_ALL, "")`` (Qt does,
so the GUI does) gets translated labels: "Langzeitbelichtung" / "Pose longue" for Bulb, "interner Speicher" for
Internal RAM, "NEF (brut)" for NEF (Raw), "%0.4f s" shutter labels. :func:`force_untranslated` re-binds libgphoto2's
two message catalogues to an empty folder, so labels and error texts come back in English whatever the locale;
the matchers below still recognise the translated words (from libgphoto2's po/ files) and, for libgphoto2's
fixed-order choices (On before Off, Internal RAM before Memory card), the position, where re-binding is not
possible.
"""
from __future__ import annotations

import ctypes
import logging
import math
import re
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

from dualrgb.common.formatting import format_exposure

log = logging.getLogger(__name__)

T = TypeVar("T")

# Translations of libgphoto2's msgids in its po/ files (ar cs da de es fr it nl pl ro sv uk vi zh_CN ...), lower case.
BULB_WORDS = frozenset({"bulb", "b", "langzeitbelichtung", "pose longue", "bombilla", "żarówka", "långtidsexponering",
                        "exp. po dobu stisku spouště", "лампа", "lampă cu bec", "b 门", "bóng đèn dây tóc",
                        "ნათურა", "بصلة (bulb)"})
ON_WORDS = frozenset({"on", "an", "ein", "activé", "activar", "acceso", "aan", "włączono", "вкл", "zapnuto", "tændt",
                      "be", "på", "увімк", "activat", "开", "bật", "aktibatuta", "ჩართული", "تشغيل"})
OFF_WORDS = frozenset({"off", "aus", "désactivé", "desactivar", "spento", "uit", "wyłączono", "выкл", "vypnuto",
                       "slukket", "ki", "av", "вимкн", "dezactivat", "关", "tắt", "desaktibatuta", "გამორთ", "إيقاف"})
RAM_WORDS = frozenset({"internal ram", "interner speicher", "mémoire interne", "ram interna", "interne ram",
                       "wewnętrzny ram", "interní paměť", "intern ram", "internt ram", "внутрішня пам'ять",
                       "memorie ram internă", "内部 ram", "ram trên máy", "sdram"})
CARD_WORDS = frozenset({"memory card", "speicherkarte", "carte mémoire", "tarjeta de memoria", "scheda di memoria",
                        "geheugenkaart", "karta pamięci", "paměťová karta", "hukommelseskort", "minneskort",
                        "картка пам'яті", "card de memorie", "存储卡", "thẻ nhớ", "card"})


# ---------------------------------------------------------------------------------------------- numbers
_NUM = r"(\d+(?:[.,]\d*)?|[.,]\d+)"
_UNIT = r"\s*(?:s|sec|secs|second|seconds)?\.?"


def _num(s: str) -> float:
    return float(s.replace(",", "."))


def parse_shutter(text: object) -> float | None:
    """Exposure time in seconds from a shutter-speed label, or None for Bulb/Time/auto/flash-sync/unknown.

    Handles libgphoto2's localised "30,0000s" / "0.0100s" / "0,5000 s", Nikon shutterspeed2 "1/4000", "30",
    "10/13", Canon '0"3' / '30"' and plain numbers.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text) if text > 0 else None
    s = str(text).strip().lower()
    if not s:
        return None
    m = re.fullmatch(_NUM + r"\s*/\s*" + _NUM + _UNIT, s)
    if m:
        den = _num(m.group(2))
        value = _num(m.group(1)) / den if den > 0 else 0.0
        return value if value > 0 else None
    m = re.fullmatch(r'(\d+)"(\d+)?', s)  # Canon: 0"3 = 0.3 s, 30" = 30 s
    if m:
        value = float(f"{m.group(1)}.{m.group(2) or 0}")
        return value if value > 0 else None
    m = re.fullmatch(_NUM + _UNIT, s)
    if m:
        value = _num(m.group(1))
        return value if value > 0 else None
    return None


def parse_aperture(text: object) -> float | None:
    """f-number from "f/5.6", "f5,6", "5.6"; None for anything else (e.g. a lens without aperture contact)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text) if text > 0 else None
    m = re.fullmatch(r"(?:f\s*/?\s*)?" + _NUM, str(text).strip().lower())
    if not m:
        return None
    value = _num(m.group(1))
    return value if value > 0 else None


def parse_iso(text: object) -> int | None:
    """ISO number from "100", "ISO 100"; None for 'Auto', 'Hi 1', 'Lo 1' and other labels."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return int(text) if text > 0 else None
    m = re.fullmatch(r"(?:iso\s*)?(\d+)", str(text).strip().lower())
    return int(m.group(1)) if m and int(m.group(1)) > 0 else None


def nearest_by_value(target: float, options: Sequence[tuple[float, T]]) -> tuple[float, T]:
    """The (value, label) nearest to ``target`` in log space (stops), ties to the first offered."""
    if not options:
        raise ValueError("no values to choose from")
    return min(options, key=lambda o: abs(math.log(o[0] / target)))


def format_shutter(seconds: float | None) -> str:
    """'1/60 s', '0.7727 s', '8 s' (common.formatting: one notation for the command line and the window)."""
    return format_exposure(seconds)


# ---------------------------------------------------------------------------------------------- words
def _word(text: object) -> str:
    return " ".join(str(text).strip().lower().split())


def is_bulb_label(text: object) -> bool:
    """Bulb, in English or as libgphoto2's catalogues translate it."""
    return _word(text) in BULB_WORDS


def bulb_choice(choices: Sequence[str]) -> str | None:
    return next((c for c in choices if is_bulb_label(c)), None)


def on_off_choice(choices: Sequence[str], on: bool) -> str | None:
    """The choice meaning On (or Off) of a libgphoto2 On/Off setting (Nikon: ``longexpnr``, ``isoauto``).

    By word where it is known, else by libgphoto2's fixed order (On first, Off second)."""
    words = ON_WORDS if on else OFF_WORDS
    match = next((c for c in choices if _word(c) in words), None)
    if match is None and len(choices) == 2:
        match = choices[0 if on else 1]
    return match


def is_on_label(text: object, choices: Sequence[str] = ()) -> bool | None:
    """True/False for an On/Off value (by word, or by position among ``choices``); None when unknown."""
    if _word(text) in ON_WORDS:
        return True
    if _word(text) in OFF_WORDS:
        return False
    if len(choices) == 2 and text in choices:
        return choices.index(text) == 0
    return None


def capture_target_choice(choices: Sequence[str], wanted: str) -> str | None:
    """The offered capture target meaning ``wanted`` ("Internal RAM" / "Memory card", any language or case);
    libgphoto2 lists Internal RAM first and Memory card second."""
    w = _word(wanted)
    exact = next((c for c in choices if _word(c) == w), None)
    if exact is not None:
        return exact
    for words, index in ((RAM_WORDS, 0), (CARD_WORDS, 1)):
        if w in words:
            match = next((c for c in choices if _word(c) in words), None)
            if match is None and len(choices) == 2:
                match = choices[index]
            return match
    return None


def is_raw_only_quality(label: object) -> bool:
    """A raw-only image quality: "NEF (Raw)", "NEF (brut)", "NEF (Crudo)", "RAW"; not "NEF+Fine"."""
    w = _word(label)
    return ("nef" in w or "raw" in w) and "+" not in w


def is_pair_quality(label: object) -> bool:
    """Raw and JPEG together ("NEF+Fine", "RAW + L"): each capture stores two files."""
    w = _word(label)
    return ("nef" in w or "raw" in w) and "+" in w


def raw_quality_choice(choices: Sequence[str]) -> str | None:
    """The raw-only choice of an image-quality setting, whatever its language."""
    return next((c for c in choices if is_raw_only_quality(c)), None)


# ---------------------------------------------------------------------------------------------- locale
GPHOTO_DOMAINS = ("libgphoto2-6", "libgphoto2_port-12")     # libgphoto2 2.5's gettext domains
_EMPTY_LOCALEDIR: str | None = None


def _domains(gp: Any) -> list[str]:
    """The gettext domains of the catalogues python-gphoto2 bundles (their .mo names), else libgphoto2's."""
    root = Path(getattr(gp, "__file__", "") or ".").parent / "libgphoto2" / "locale"
    found = sorted({mo.stem for mo in root.glob("*/LC_MESSAGES/*.mo")}) if root.is_dir() else []
    return found or list(GPHOTO_DOMAINS)


def force_untranslated(gp: Any) -> bool:
    """Make libgphoto2 and libgphoto2_port answer in English (labels and error texts) in this process.

    python-gphoto2 binds libgphoto2's catalogues on import, and libgphoto2's own ``gp_init_localedir`` ignores
    every later call, so the two gettext domains are re-bound to an empty folder through the C library's
    ``bindtextdomain`` (ctypes: there is no Python call for it); the process locale (Qt's, the GUI's) and other
    libraries' messages are left alone. Returns False where that is not possible (a stand-in module, a C library
    without gettext): the word matchers above still apply.
    """
    global _EMPTY_LOCALEDIR
    if not getattr(gp, "__file__", None):
        return False
    try:
        libc = ctypes.CDLL(None)
        bind = libc.bindtextdomain
    except (OSError, AttributeError) as exc:
        log.info("cannot re-bind libgphoto2's translations (%s); translated labels are matched by meaning", exc)
        return False
    bind.restype, bind.argtypes = ctypes.c_char_p, [ctypes.c_char_p, ctypes.c_char_p]
    if _EMPTY_LOCALEDIR is None:
        _EMPTY_LOCALEDIR = tempfile.mkdtemp(prefix="dualrgb-no-gphoto2-catalogues-")
    for domain in _domains(gp):
        if bind(domain.encode(), _EMPTY_LOCALEDIR.encode()) is None:
            log.info("could not re-bind %s; translated labels are matched by meaning", domain)
            return False
    return True
