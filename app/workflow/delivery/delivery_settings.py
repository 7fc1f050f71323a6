"""What a delivery holds beyond the masters every original gets, and who the institution is: the delivery settings
(a TOML file; the one reader of it).

    # <per-user data folder>/delivery.toml (DUALRGB_DATA_DIR moves it; --delivery-settings FILE names another)
    [delivery]
    spectral = true                          # the spectral cube and its rendering written with the masters at any
                                             # resolution; false: never (`dualrgb cube` makes them later); "auto"
                                             # (the default): at half resolution only
    render_illuminant = "D65"                # the light the rendering is seen under
    masters = ["eciRGB v2", "Adobe RGB (1998)"]   # other working spaces, each a 16-bit master with its ICC
    access = ["jp2", "pyramid"]              # access copies: JPEG 2000 (lossless) and a tiled pyramidal TIFF

    [institution]
    creator = ["Example Museum, Imaging Studio"]  # XMP dc:creator
    rights = "CC BY 4.0, Example Museum"           # XMP dc:rights and the TIFF Copyright tag

    [bag-info]                               # BagIt bag-info.txt fields of `dualrgb bag` (RFC 8493 section 2.2.2)
    Source-Organization = "Example Museum"
    Contact-Email = "imaging@example.org"

Every key is checked when the file is read: an unknown key, a value of the wrong type or an unknown choice is one
line naming the file and the key (before anything is captured). No file: the defaults below (masters ProPhoto,
sRGB, XYZ and the camera channels; the spectral products at half resolution only; no access copies).
"""
from __future__ import annotations

import logging
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

from dualrgb import resources

log = logging.getLogger(__name__)

SETTINGS_FILE = "delivery.toml"
# the extra masters by the name the settings use -> (colour-science's space, file key, file name part)
MASTERS = {"eciRGB v2": ("ECI RGB v2", "ecirgb", "ecirgb_v2"),
           "Adobe RGB (1998)": ("Adobe RGB (1998)", "adobergb", "adobergb")}
ACCESS = {"jp2": "JPEG 2000, lossless (OpenJPEG through imagecodecs)",
          "pyramid": "tiled pyramidal TIFF, 8-bit sRGB, JPEG tiles (IIIF image servers)"}
_KEYS = {"delivery": {"spectral", "render_illuminant", "masters", "access"}, "institution": {"creator", "rights"},
         "bag-info": None}


@dataclass(frozen=True)
class DeliverySettings:
    """The deliverables asked for beyond the default masters, and the institution's metadata."""

    spectral: bool | None = None                # None: "auto", written at half resolution only
    render_illuminant: str = ""                 # "": the default light (app.processing.render)
    masters: tuple[str, ...] = ()               # names of MASTERS
    access: tuple[str, ...] = ()                # names of ACCESS
    creator: tuple[str, ...] = ()
    rights: str = ""
    bag_info: dict[str, str] = field(default_factory=dict)
    source: str = ""                            # the file read ("" : defaults)

    def with_spectral(self, spectral: bool | None) -> DeliverySettings:
        """These settings with ``spectral`` as the command line says (None: as they are)."""
        return self if spectral is None else replace(self, spectral=bool(spectral))

    def writes_spectral(self, resolution: str) -> bool:
        """Whether the cube and its rendering are written with the masters at ``resolution``."""
        return self.spectral if self.spectral is not None else resolution == "half"

    def describe(self) -> dict:
        """For the sidecar: what was asked for (all :func:`from_record` needs to ask for it again)."""
        return {"spectral": "auto" if self.spectral is None else self.spectral, "masters": list(self.masters),
                "access": list(self.access), "render_illuminant": self.render_illuminant,
                "creator": list(self.creator), "rights": self.rights, "settings_file": self.source}


def from_record(record: dict, where: Path, fallback: DeliverySettings) -> DeliverySettings:
    """The settings a sidecar's ``delivery_settings`` (:meth:`DeliverySettings.describe`) record, checked as the
    file is (ValueError naming ``where`` and the key); what an older sidecar did not record (the institution, the
    rendering light) and the bag's fields come from ``fallback`` (the settings file's)."""
    asked = {k: record[k] for k in ("spectral", "render_illuminant", "masters", "access") if k in record}
    institution = {k: record[k] for k in ("creator", "rights") if k in record}
    got = _parse({"delivery": asked, "institution": institution}, where)
    return replace(got, render_illuminant=got.render_illuminant if "render_illuminant" in record
                   else fallback.render_illuminant, creator=got.creator if "creator" in record else fallback.creator,
                   rights=got.rights if "rights" in record else fallback.rights, bag_info=fallback.bag_info,
                   source=f"{where} (as delivered before)")


def check_render_request(settings: DeliverySettings, resolution: str, render_illuminant: str | None) -> None:
    """Before the light: a rendering asked for by name (``--render-illuminant``) must be one that is written."""
    if render_illuminant and not settings.writes_spectral(resolution):
        why = ("--no-spectral or spectral = false in the delivery settings" if settings.spectral is False else
               f"at {resolution} resolution the cube and its rendering are made on demand (dualrgb cube)")
        raise ValueError(f"--render-illuminant {render_illuminant}: no rendering would be written ({why}); add "
                         "--spectral to write the cube and its rendering with the masters, or leave the option out")


def default_path() -> Path:
    return resources.user_path(SETTINGS_FILE)


def load(path: Path | None = None) -> DeliverySettings:
    """The settings of ``path`` (None: the per-user file when there is one, else the defaults); ValueError (one
    line naming the file and key) for anything that is not understood."""
    explicit = path is not None
    path = default_path() if path is None else Path(path)
    if not path.is_file():
        if explicit:
            raise ValueError(f"{path}: no such delivery settings file")
        return DeliverySettings()
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: not a readable TOML file ({exc})") from None
    return _parse(doc, path)


def _parse(doc: dict, path: Path) -> DeliverySettings:
    for table, value in doc.items():
        if table not in _KEYS or not isinstance(value, dict):
            raise ValueError(f"{path}: [{table}]: unknown table (expected {', '.join(_KEYS)})")
        allowed = _KEYS[table]
        for key in value:
            if allowed is not None and key not in allowed:
                raise ValueError(f"{path}: [{table}] {key}: unknown key (expected {', '.join(sorted(allowed))})")
    d, inst = doc.get("delivery", {}), doc.get("institution", {})
    bag = {str(k): _text(path, "bag-info", k, v) for k, v in doc.get("bag-info", {}).items()}
    spectral = d.get("spectral", "auto")
    if not isinstance(spectral, bool) and spectral != "auto":
        raise ValueError(f"{path}: [delivery] spectral: {spectral!r}, expected true, false or \"auto\"")
    illuminant = _text(path, "delivery", "render_illuminant", d.get("render_illuminant", ""))
    if illuminant:
        from dualrgb.app.processing.render import check_illuminant

        try:
            illuminant = check_illuminant(illuminant)
        except ValueError as exc:
            raise ValueError(f"{path}: [delivery] render_illuminant: {exc}") from None
    return DeliverySettings(None if spectral == "auto" else spectral, illuminant,
                            _choices(path, "masters", d.get("masters", []), MASTERS),
                            _choices(path, "access", d.get("access", []), ACCESS),
                            tuple(_texts(path, "institution", "creator", inst.get("creator", []))),
                            _text(path, "institution", "rights", inst.get("rights", "")), bag, str(path))


def _text(path: Path, table: str, key: str, value: object) -> str:
    if not isinstance(value, str):
        raise ValueError(f"{path}: [{table}] {key}: {value!r}, expected text")
    return value.strip()


def _texts(path: Path, table: str, key: str, value: object) -> list[str]:
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list):
        raise ValueError(f"{path}: [{table}] {key}: {value!r}, expected text or a list of texts")
    return [t for t in (_text(path, table, key, v) for v in items) if t]


def _choices(path: Path, key: str, value: object, known: dict) -> tuple[str, ...]:
    out = _texts(path, "delivery", key, value)
    for name in out:
        if name not in known:
            raise ValueError(f"{path}: [delivery] {key}: {name!r}, expected one of {', '.join(map(repr, known))}")
    return tuple(dict.fromkeys(out))
