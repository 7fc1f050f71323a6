"""The gphoto2 camera's configuration: libgphoto2's widget tree read and written by config name, and the copy
stand's settings (shutter, ISO, aperture, image quality, capture target, auto ISO, long-exposure noise reduction).

Numeric settings are matched by parsed value, never by the (localised) label; word choices by meaning
(drivers.camera.gphoto_labels). Nikon offers two shutter settings: ``shutterspeed2`` ("1/8000", "10/13", "30",
exact) is preferred over ``shutterspeed`` (0.1 ms steps: 1/8000 reads "0,0001s"), so the exposure recorded in
the manifest and used by HDR weighting is the exact one.

:class:`GPhotoSettings` is a mixin of :class:`drivers.camera.gphoto.GPhotoCamera`, which provides ``_call``
(one libgphoto2 call with deadline, busy retry and error mapping), ``_require_open``, ``_gp_module`` and the
state used here.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from dualrgb.drivers.camera.base import CameraError, CameraSettings
from dualrgb.drivers.camera.gphoto_errors import GP_ERROR_BAD_PARAMETERS, GP_ERROR_NOT_SUPPORTED, camera_error
from dualrgb.drivers.camera.gphoto_host import GPhotoHost
from dualrgb.drivers.camera.gphoto_labels import (
    bulb_choice,
    capture_target_choice,
    format_shutter,
    is_bulb_label,
    is_on_label,
    is_pair_quality,
    is_raw_only_quality,
    nearest_by_value,
    on_off_choice,
    parse_aperture,
    parse_iso,
    parse_shutter,
    raw_quality_choice,
)

log = logging.getLogger(__name__)

# Name -> libgphoto2 widget type (gphoto2.GP_WIDGET_*)
WIDGET_KINDS = {0: "window", 1: "section", 2: "text", 3: "range", 4: "toggle", 5: "radio", 6: "menu",
                7: "button", 8: "date"}
CHOICE_KINDS = ("radio", "menu")

# Config names, most preferred first (Nikon PTP names; Canon/others where they differ)
ISO_NAMES = ("iso", "isospeed")
SHUTTER_NAMES = ("shutterspeed2", "shutterspeed", "exptime")
APERTURE_NAMES = ("f-number", "aperture")
QUALITY_NAMES = ("imagequality", "imageformat")
TARGET_NAMES = ("capturetarget",)
AUTO_ISO_NAMES = ("isoauto", "autoiso")
LONG_EXPOSURE_NR_NAMES = ("longexpnr",)

RAW_QUALITY = "NEF (Raw)"
RAM_TARGET = "Internal RAM"
BULB_LIMIT_S = 30.0          # the D610's longest timed speed; longer exposures use bulb
SNAP_WARN_STOPS = 1.0 / 6.0  # warn when the offered speed/aperture is further than this from the request


IMAGE_AREA_NAMES = ("imagesize", "imagearea", "dxcropmode", "autodxcrop")   # what sets a frame's size and crop


@dataclass
class ConfigEntry:
    """One leaf of the camera's configuration tree, for display and for setting values."""

    name: str
    label: str
    kind: str                           # 'text', 'range', 'toggle', 'radio', 'menu', 'button', 'date'
    value: Any
    readonly: bool = False
    choices: list[str] = field(default_factory=list)
    range: tuple[float, float, float] | None = None   # (min, max, step) for 'range'


class GPhotoSettings(GPhotoHost):
    """Configuration access and the copy stand's settings (mixin of GPhotoCamera)."""

    _names: dict[str, str]
    _bulb_exposure_s: float | None
    _timed_shutter: tuple[str, str] | None
    auto_iso: str
    long_exposure_nr: str

    # ---------------------------------------------------------------------------------- the widget tree
    def _walk_config(self, widget: Any) -> list[ConfigEntry]:
        gp = self._gp_module()
        out: list[ConfigEntry] = []
        stack = [widget]
        while stack:
            w = stack.pop(0)
            kind = WIDGET_KINDS.get(w.get_type(), str(w.get_type()))
            if kind in ("window", "section"):
                stack[:0] = [w.get_child(i) for i in range(w.count_children())]
                continue
            try:
                value = w.get_value()
            except gp.GPhoto2Error:
                value = None
            entry = ConfigEntry(name=w.get_name(), label=w.get_label(), kind=kind, value=value,
                                readonly=bool(w.get_readonly()))
            if kind in CHOICE_KINDS:
                entry.choices = [w.get_choice(i) for i in range(w.count_choices())]
            elif kind == "range":
                lo, hi, step = w.get_range()
                entry.range = (float(lo), float(hi), float(step))
            out.append(entry)
        return out

    def list_config(self) -> dict[str, ConfigEntry]:
        """Every configuration leaf by name (value, choices, read-only flag) as the camera reports it now."""
        cam = self._require_open()
        entries = self._walk_config(self._call("read configuration", cam.get_config))
        return {e.name: e for e in entries}

    def _first_name(self, names: Iterable[str]) -> str | None:
        return next((n for n in names if n in self._names), None)

    def _entry(self, name: str) -> ConfigEntry:
        cam = self._require_open()
        w = self._call(f"read {name}", cam.get_single_config, name)
        return self._walk_config(w)[0]

    def get_config_value(self, name: str) -> Any:
        if name not in self._names:
            raise CameraError(f"this camera has no '{name}' setting", GP_ERROR_NOT_SUPPORTED)
        return self._entry(name).value

    @staticmethod
    def _choice_for(name: str, entry: ConfigEntry, value: Any) -> str:
        """The offered choice meaning ``value``: same text (any case), or the same meaning in another language."""
        wanted = str(value).strip().lower()
        match = next((c for c in entry.choices if c.strip().lower() == wanted), None)
        if match is None and name in TARGET_NAMES:
            match = capture_target_choice(entry.choices, str(value))
        if match is None and is_raw_only_quality(value) and name in QUALITY_NAMES:
            match = raw_quality_choice(entry.choices)
        if match is None and is_bulb_label(value):
            match = bulb_choice(entry.choices)
        if match is None:
            shown = ", ".join(entry.choices[:12]) + (" ..." if len(entry.choices) > 12 else "")
            raise CameraError(f"set {name}: {value!r} is not offered; the camera offers {shown}",
                              GP_ERROR_BAD_PARAMETERS)
        return match

    def _typed_value(self, name: str, entry: ConfigEntry, value: Any) -> Any:
        if entry.readonly:
            raise CameraError(f"set {name}: read-only on this camera now (set the mode dial to M, or change "
                              "it on the camera body)", GP_ERROR_NOT_SUPPORTED)
        if entry.kind in CHOICE_KINDS:
            return self._choice_for(name, entry, value)
        if entry.kind == "toggle":
            return int(bool(value))
        if entry.kind == "range":
            return float(value)
        if entry.kind == "date":
            return int(value)
        return str(value)

    def set_config_value(self, name: str, value: Any) -> Any:
        """Set one configuration leaf by name; a choice must be one offered (compared case-insensitively, or by
        meaning for Bulb, capture target and raw quality). Returns the value read back from the camera.

        libgphoto2 answers -2 also when the camera is busy or the setting became read-only: the setting is then
        read again and written once more (a read-only one is refused in one line).
        """
        cam = self._require_open()
        if name not in self._names:
            raise CameraError(f"this camera has no '{name}' setting", GP_ERROR_NOT_SUPPORTED)
        for attempt in (1, 2):
            w = self._call(f"read {name}", cam.get_single_config, name)
            typed = self._typed_value(name, self._walk_config(w)[0], value)
            try:
                w.set_value(typed)
                self._call(f"set {name} to {typed!r}", cam.set_single_config, name, w)
                break
            except CameraError as exc:
                if exc.code != GP_ERROR_BAD_PARAMETERS or attempt == 2:
                    raise
                log.info("set %s: the camera answered -2 (busy or read-only): reading it again", name)
                self._sleep(self.busy_delay_s)
            except self._gp_module().GPhoto2Error as exc:   # set_value refused the value itself
                raise camera_error(exc, f"set {name} to {typed!r}") from exc
        log.debug("set %s = %r", name, typed)
        return self._entry(name).value

    def _set_toggle(self, name: str, value: int) -> None:
        """Write a toggle (``bulb``, ``viewfinder``) as it is, without reading it back."""
        cam = self._require_open()
        w = self._call(f"read {name}", cam.get_single_config, name)
        w.set_value(value)
        self._call(f"set {name} to {value!r}", cam.set_single_config, name, w)

    # ------------------------------------------------------------------------------------- shutter
    def _shutter_entry(self, writable: bool = False) -> ConfigEntry | None:
        """The preferred shutter-speed setting that offers parsable speeds (Nikon: shutterspeed2, then
        shutterspeed); ``writable``: skip read-only ones."""
        for name in SHUTTER_NAMES:
            if name in self._names and self._names[name] in CHOICE_KINDS:
                entry = self._entry(name)
                if any(parse_shutter(c) for c in entry.choices) and not (writable and entry.readonly):
                    return entry
        return None

    @staticmethod
    def _shutter_options(entry: ConfigEntry) -> list[tuple[float, str]]:
        opts = [(parse_shutter(c), c) for c in entry.choices]
        return sorted((v, c) for v, c in opts if v is not None)

    def image_area(self) -> str:
        """The settings among :data:`IMAGE_AREA_NAMES` this body has, as 'name value' pairs (libgphoto2's names
        for Nikon's image size and FX / DX crop)."""
        return ", ".join(f"{n} {self._entry(n).value}" for n in IMAGE_AREA_NAMES if n in self._names)

    def shutter_speeds(self) -> list[float]:
        self._require_open()
        entry = self._shutter_entry()
        return [] if entry is None else [v for v, _ in self._shutter_options(entry)]

    def _shutter_now(self) -> tuple[float | None, str, str]:
        """(exposure in s or None, label, setting name) as the camera reports it, exact where it can be."""
        entry = self._shutter_entry()
        if entry is None:
            return None, "", ""
        if is_bulb_label(entry.value):
            return self._bulb_exposure_s, str(entry.value), entry.name
        return parse_shutter(entry.value), str(entry.value), entry.name

    def _needs_bulb(self, exposure_s: float, options: list[tuple[float, str]]) -> bool:
        longest = options[-1][0] if options else 0.0
        # beyond the longest timed speed by more than a third of a stop: a timed speed would be wrong
        return exposure_s > self.bulb_limit_s and exposure_s > longest * 2 ** (1 / 3)

    def _set_shutter(self, exposure_s: float) -> tuple[float, bool]:
        """Set the shutter for ``exposure_s``; returns (exposure the camera will give, uses bulb)."""
        if not exposure_s or exposure_s <= 0 or not math.isfinite(exposure_s):
            raise CameraError(f"exposure must be a positive number of seconds, got {exposure_s!r}")
        entry = self._shutter_entry(writable=True)
        if entry is None:
            raise CameraError("this camera offers no shutter-speed setting over USB (set the mode dial to M)",
                              GP_ERROR_NOT_SUPPORTED)
        options = self._shutter_options(entry)
        if self._needs_bulb(exposure_s, options):
            bulb = bulb_choice(entry.choices)
            if bulb is None or "bulb" not in self._names:
                raise CameraError(f"set shutter: {format_shutter(exposure_s)} is longer than the longest speed "
                                  f"{format_shutter(options[-1][0])} and this camera offers no bulb over USB "
                                  "(mode dial to M, shutter to Bulb)", GP_ERROR_NOT_SUPPORTED)
            if entry.value != bulb:
                self._timed_shutter = (entry.name, str(entry.value))    # restored after the bulb exposure
                self.set_config_value(entry.name, bulb)
            self._bulb_exposure_s = exposure_s
            return exposure_s, True
        value, label = nearest_by_value(exposure_s, options)
        stops = abs(math.log2(value / exposure_s))
        if stops > SNAP_WARN_STOPS:
            log.warning("shutter %s not offered; using %s (%.2f stops off)", format_shutter(exposure_s),
                        label, stops)
        if entry.value != label:
            self.set_config_value(entry.name, label)
        self._bulb_exposure_s = None
        self._timed_shutter = None
        return value, False

    def _restore_timed_shutter(self) -> None:
        """Back from Bulb to the timed speed set before it (the camera refuses live view on Bulb)."""
        if self._timed_shutter is None:
            return
        name, label = self._timed_shutter
        try:
            self.set_config_value(name, label)
        except CameraError as exc:
            log.warning("could not set the shutter back from Bulb to %s: %s", label, exc)
            return
        self._timed_shutter = None
        self._bulb_exposure_s = None
        log.info("shutter back from Bulb to %s", label)

    # ------------------------------------------------------------------------------- copy-stand setup
    def _switch_off(self, names: Iterable[str], what: str) -> str:
        """Switch an On/Off setting off; returns what the session record says about it."""
        name = self._first_name(names)
        if name is None:
            return "not offered"
        try:
            entry = self._entry(name)
            if is_on_label(entry.value, entry.choices) is False:
                return "off"
            off = on_off_choice(entry.choices, on=False)
            if off is None:
                return f"unknown ({entry.value}: no Off choice among {', '.join(entry.choices)})"
            self.set_config_value(name, off)
            log.info("%s switched off (%s)", what, name)
            return "switched off"
        except CameraError as exc:
            log.warning("%s could not be switched off: %s", what, exc)
            return f"on: could not be switched off ({exc})"

    def _force_raw_quality(self) -> str:
        """Image quality to raw only (one file per capture); returns the quality now set."""
        name = self._first_name(QUALITY_NAMES)
        if name is None:
            return ""
        entry = self._entry(name)
        if is_raw_only_quality(entry.value):
            return str(entry.value)
        raw = raw_quality_choice(entry.choices)
        if raw is None:
            return str(entry.value)
        try:
            value = self.set_config_value(name, raw)
            log.info("image quality %s -> %s", entry.value, value)
            return str(value)
        except CameraError as exc:
            log.warning("image quality stays %s (%s); the raw file is picked from each capture", entry.value, exc)
            return str(entry.value)

    def _prepare_for_copy_stand(self) -> None:
        """At open: raw only, auto ISO off, long-exposure noise reduction off (each recorded per frame)."""
        self.image_quality = self._force_raw_quality()
        self.auto_iso = self._switch_off(AUTO_ISO_NAMES, "auto ISO")
        self.long_exposure_nr = self._switch_off(LONG_EXPOSURE_NR_NAMES, "long-exposure noise reduction")

    @property
    def stores_pairs(self) -> bool:
        """Each capture stores raw + JPEG (the quality could not be set to raw only)."""
        return is_pair_quality(getattr(self, "image_quality", ""))

    @property
    def expects_raw(self) -> bool:
        """The camera's quality is raw (only, or with a JPEG): the raw file of each capture is the one to keep."""
        q = getattr(self, "image_quality", "")
        return is_raw_only_quality(q) or is_pair_quality(q)

    # ------------------------------------------------------------------------------------- settings
    def settings(self) -> CameraSettings:
        self._require_open()
        s = CameraSettings()
        name = self._first_name(ISO_NAMES)
        if name:
            s.iso = parse_iso(self._entry(name).value)
        s.shutter_s = self._shutter_now()[0]
        name = self._first_name(APERTURE_NAMES)
        if name:
            s.aperture = parse_aperture(self._entry(name).value)
        name = self._first_name(QUALITY_NAMES)
        if name:
            s.image_quality = self._entry(name).value
        name = self._first_name(TARGET_NAMES)
        if name:
            s.capture_target = self._entry(name).value
        return s

    def _require_name(self, names: Iterable[str], what: str) -> str:
        name = self._first_name(names)
        if name is None:
            raise CameraError(f"this camera has no {what} setting over USB", GP_ERROR_NOT_SUPPORTED)
        return name

    def _apply_iso(self, iso: float) -> None:
        name = self._require_name(ISO_NAMES, "ISO")
        self.auto_iso = self._switch_off(AUTO_ISO_NAMES, "auto ISO")   # else the camera picks its own ISO
        entry = self._entry(name)
        options = [(float(v), c) for v, c in ((parse_iso(c), c) for c in entry.choices) if v]
        if not options:
            raise CameraError(f"set ISO: the camera offers no numeric ISO ({entry.choices[:6]})",
                              GP_ERROR_NOT_SUPPORTED)
        value, label = nearest_by_value(float(iso), options)
        if value != iso:
            log.warning("ISO %s not offered; using %s", iso, label)
        self.set_config_value(name, label)

    def _apply_aperture(self, aperture: float) -> None:
        name = self._require_name(APERTURE_NAMES, "aperture (manual lens?)")
        entry = self._entry(name)
        options = [(v, c) for v, c in ((parse_aperture(c), c) for c in entry.choices) if v]
        if not options:
            raise CameraError(f"set aperture: the camera offers no f-numbers ({entry.choices[:6]}); "
                              "a manual lens is set on the lens", GP_ERROR_NOT_SUPPORTED)
        value, label = nearest_by_value(float(aperture), options)
        if abs(math.log2(value / aperture)) > SNAP_WARN_STOPS:
            log.warning("aperture f/%g not offered; using %s", aperture, label)
        self.set_config_value(name, label)

    def apply(self, settings: CameraSettings) -> CameraSettings:
        self._require_open()
        with self._lock:
            if settings.image_quality is not None:
                name = self._require_name(QUALITY_NAMES, "image-quality")
                self.image_quality = str(self.set_config_value(name, settings.image_quality))
            if settings.capture_target is not None:
                self.set_config_value(self._require_name(TARGET_NAMES, "capture-target"), settings.capture_target)
            if settings.iso is not None:
                self._apply_iso(settings.iso)
            if settings.aperture is not None:
                self._apply_aperture(settings.aperture)
            if settings.shutter_s is not None:
                self._set_shutter(float(settings.shutter_s))
            return self.settings()
