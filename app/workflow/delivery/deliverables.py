"""What an original's delivery holds: the files (:func:`deliverable_files`, the one place they are listed), how
each is laid out and tagged, and what they cost on disk (:func:`storage`).

Per original named ``<id>`` (core.metadata.file_stem), at the delivery's resolution (``full``: the
sensor's pixels, demosaiced; ``half``: one pixel per 2x2 Bayer cell):

===========================================  ==================================================================
``<id>_prophoto_16bit.tif``                  ProPhoto RGB (ROMM), 16-bit, display-encoded, ICC v2.4 embedded
``<id>_srgb_16bit.tif``                      sRGB, 16-bit, display-encoded, ICC v2.4 embedded
``<id>_XYZ_16bit.tif``                       CIE XYZ, linear, 32768 = the reference white's Y: an RGB TIFF whose
                                             R, G, B are X, Y, Z, with the ICC v2.4 profile that says so
                                             (app.processing.outputs.xyz_icc)
``<id>_light<n>_cameraRGB_16bit.tif``        per light n: the camera's flat-fielded R, G, B under it (channels
                                             R<n> G<n> B<n>), linear, 32768 = the white; a linear input ICC
                                             profile fitted to the calibration (app.workflow.delivery.camera_profiles)
``<id>_ecirgb_v2_16bit.tif``,                other working spaces when the delivery settings ask for them
``<id>_adobergb_16bit.tif``                  (app.workflow.delivery.delivery_settings): 16-bit, display-encoded, ICC
v2.4
``<id>_spectral.img`` / ``.hdr``             the spectral cube (ENVI, BIL, 16-bit x 10000), when asked for
``<id>_under_<light>_prophoto_16bit.tif``    the estimated spectra rendered under a chosen light, ProPhoto, ICC
``<id>_access.jp2``                          access copy: JPEG 2000, lossless, 16-bit sRGB (when asked for)
``<id>_access_pyramid.tif``                  access copy: tiled pyramidal TIFF, 8-bit sRGB (when asked for)
``<id>.json``                                the sidecar (app.workflow.delivery.delivery): fixity of every file above
===========================================  ==================================================================

The spectral products (the cube and its rendering) are written when the delivery settings or ``--spectral`` ask
for them, at either resolution; otherwise the sidecar states them and ``dualrgb cube`` makes them later
(app.processing.cube_map) from the camera-RGB TIFFs through the map the sidecar states: the cube is the channels
through one affine map and a clip, so six 16-bit channels hold all of its information, and a 38-band cube is 6.3x
their size (1.86 GB per 24 MP original, 11.5 GB at 150 MP, :func:`storage`); its rendering costs more processor
time than all the other deliverables' encoding together (0.9 CPU-s at 24 MP) and fixes one light at capture time.
docs/notes/issue-31.md has the figures.

Why the camera channels are one RGB TIFF per light, not one 6-sample TIFF. TIFF has no photometric for six
colour channels: a 6-sample file is MinIsBlack or RGB with "extra samples", and readers then take the second or
the fourth sample for alpha (ImageMagick 6: GrayscaleAlpha / TrueColorAlpha, the rest dropped), Pillow opens
none of them, and baseline validators refuse them. A dual-RGB capture *is* two camera-RGB images, one per light:
as two RGB TIFFs every reader (tifffile, ImageMagick, GDAL, Pillow, libtiff) reads all six channels as what they
are, with nothing mistaken for alpha or grey; a two-page TIFF would do too, but GDAL shows its second page only
as a subdataset, and its pages cannot be checksummed while they are streamed. The channels' order in the
spectral map is R1 G1 B1 R2 G2 B2 ... (the sidecar's ``encoding.channels``).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from dualrgb.app.processing.encode import LINEAR_ONE
from dualrgb.app.processing.envi import INTERLEAVE, SCALE_FACTOR
from dualrgb.app.processing.masters import FULL, check_resolution
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT, Rendering, rendering
from dualrgb.app.workflow.delivery.delivery_settings import ACCESS, MASTERS
from dualrgb.simulation.spectral_estimation import SpectralEstimator

log = logging.getLogger(__name__)

CUBE_FILE, CUBE_ON_DEMAND = "file", "on-demand"
TIFF_OVERHEAD_BYTES = 16_384          # tags, ICC, XMP of one deliverable TIFF (measured: 11-14 kB)


@dataclass
class Deliverable:
    """One deliverable file: its path, samples per pixel (the cube: wavelengths), ``kind`` (``rgb``: display-encoded
    in ``space``; ``xyz``; ``channels``: light ``light``'s camera RGB, named ``light_name``; ``cube``,
    ``cube_header``, ``render``; ``access``: an access copy made from the sRGB master, ``space`` its format key),
    TIFF photometric, the ICC profile it embeds (a space name, "XYZ", "camera" or None) and what it holds."""

    path: Path
    samples: int
    kind: str
    photometric: str = "rgb"
    space: str | None = None
    icc: str | None = None
    what: str = ""
    light: int = 0
    light_name: str = ""

    @property
    def streamed(self) -> bool:
        """Written band by band while the channels are encoded (the others: the cube's header, access copies)."""
        return self.kind not in ("cube_header", "access")

    @property
    def spectral(self) -> bool:
        """Made by the spectral encoder (app.processing.spectral_cube) rather than the colour one."""
        return self.kind in ("cube", "render")


@dataclass
class SpectralPlan:
    """The spectral deliverables of a delivery: the calibration's estimator, the rendering's light, and whether
    the cube and the rendering are written (``file``) or left to ``dualrgb cube`` (``on-demand``)."""

    estimator: SpectralEstimator
    rendering: Rendering
    cube: str = CUBE_FILE

    @classmethod
    def of(cls, profile, illuminant: str = DEFAULT_RENDER_ILLUMINANT, written: bool = False) -> SpectralPlan | None:
        """The plan for ``profile`` (None: it has no spectral estimator) rendering under ``illuminant``; the cube
        and its rendering are files when ``written`` (asked for), else made on demand (:func:`cube_delivery`)."""
        if profile.estimator is None:
            return None
        est = profile.spectral_estimator()
        return cls(est, rendering(illuminant, est.wavelengths), cube_delivery(written))


def cube_delivery(written: bool) -> str:
    """How the spectral cube and its rendering are delivered: files when asked for, else on demand."""
    return CUBE_FILE if written else CUBE_ON_DEMAND


def check_spectral_request(profile, spectral: bool) -> None:
    """Before the light: spectral products asked for need a calibration with a spectral estimator."""
    if spectral and profile is not None and profile.estimator is None:
        raise ValueError(f"the spectral cube was asked for (--spectral or the delivery settings), and calibration "
                         f"{profile.id} has no spectral estimator (its charts had no spectra): calibrate again with "
                         "spectral references, or deliver without --spectral")


def channel_groups(channels: list[str]) -> list[list[str]]:
    """The stack's channels (R1 G1 B1 R2 ...) in groups of three: one camera-RGB TIFF per light."""
    if len(channels) % 3:
        raise ValueError(f"{len(channels)} channels: expected three (R, G, B) per light")
    return [channels[i: i + 3] for i in range(0, len(channels), 3)]


def deliverable_files(folder: Path, stem: str, channels: list[str], spectral: SpectralPlan | None = None,
                      lights: list[str] | None = None, masters: tuple[str, ...] = (),
                      access: tuple[str, ...] = ()) -> dict[str, Deliverable]:
    """Every file of an original named ``stem`` with the stack's ``channels`` (and the spectral ones of
    ``spectral``, the extra ``masters`` and ``access`` copies of app.workflow.delivery.delivery_settings) but the
    sidecar,
    by key (the sidecar's); ``lights``: the lights' names."""
    files = {
        "prophoto": Deliverable(folder / f"{stem}_prophoto_16bit.tif", 3, "rgb", space="ProPhoto RGB",
                                icc="ProPhoto RGB", what="ProPhoto RGB (ROMM), 16-bit, ICC embedded"),
        "srgb": Deliverable(folder / f"{stem}_srgb_16bit.tif", 3, "rgb", space="sRGB", icc="sRGB",
                            what="sRGB, 16-bit, ICC embedded"),
        "xyz": Deliverable(folder / f"{stem}_XYZ_16bit.tif", 3, "xyz", icc="XYZ",
                           what="CIE XYZ (2 deg) as R, G, B: X/Xn, Y/Yn, Z/Zn, linear, 65535 = the reference white"),
    }
    for name in masters:
        space, key, part = MASTERS[name]
        files[key] = Deliverable(folder / f"{stem}_{part}_16bit.tif", 3, "rgb", space=space, icc=space,
                                 what=f"{name}, 16-bit, ICC embedded")
    for n, group in enumerate(channel_groups(channels), start=1):
        name = (lights or [])[n - 1] if lights and len(lights) >= n else f"light {n}"
        files[f"channels_{n}"] = Deliverable(
            folder / f"{stem}_light{n}_cameraRGB_16bit.tif", 3, "channels", icc="camera", light=n - 1,
            light_name=name, what=f"camera {' '.join(group)} under {name}, flat-fielded, linear, "
                                  f"{LINEAR_ONE:g} = white")
    if spectral is not None and spectral.cube == CUBE_FILE:
        files.update(spectral_files(folder, stem, spectral.estimator, spectral.rendering))
    for key in access:
        files[f"access_{key}"] = Deliverable(folder / f"{stem}_{ACCESS_NAMES[key]}", 3, "access", space=key,
                                             what=ACCESS[key])
    return files


ACCESS_NAMES = {"jp2": "access.jp2", "pyramid": "access_pyramid.tif"}


def spectral_files(folder: Path, stem: str, est: SpectralEstimator, r: Rendering | None) -> dict[str, Deliverable]:
    """The spectral cube's data and header files, and its rendering under ``r``'s light (None: none)."""
    files = {"spectral": Deliverable(folder / f"{stem}_spectral.img", est.n_wavelengths, "cube", "",
                                     what=f"{est.quantity} x {SCALE_FACTOR:g} at {est.n_wavelengths} wavelengths, "
                                          f"ENVI {INTERLEAVE}, 16-bit"),
             "spectral_header": Deliverable(folder / f"{stem}_spectral.hdr", 0, "cube_header", "",
                                            what="ENVI header of the spectral cube")}
    if r is not None:
        files["render"] = Deliverable(folder / render_name(stem, r.illuminant), 3, "render", space=r.space,
                                      icc=r.space, what=f"rendered under {r.light} from the estimated spectra, "
                                                        f"{r.space}, 16-bit, ICC embedded")
    return files


def render_name(stem: str, illuminant: str) -> str:
    """The rendering's file name under the light ``illuminant`` (its command-line name)."""
    return f"{stem}_under_{illuminant}_prophoto_16bit.tif"


def storage(width: int, height: int, n_lights: int = 2, n_wavelengths: int | None = 38,
            resolution: str = FULL, spectral: bool = False) -> dict[str, int]:
    """Bytes on disk of each deliverable of one original from a ``width`` x ``height`` sensor (16-bit samples
    plus :data:`TIFF_OVERHEAD_BYTES` per TIFF; the sidecar's few kB left out): what a day's storage is planned
    with. ``n_wavelengths`` None: no spectral estimator. The cube's key is there only when it is written
    (``spectral``); else ``spectral_on_demand`` / ``render_on_demand`` say what ``dualrgb cube`` writes."""
    w, h = (width, height) if check_resolution(resolution) == FULL else (width // 2, height // 2)
    tiff = w * h * 3 * 2 + TIFF_OVERHEAD_BYTES
    out = {"prophoto": tiff, "srgb": tiff, "xyz": tiff}
    out.update({f"channels_{n}": tiff for n in range(1, n_lights + 1)})
    if n_wavelengths:
        cube = w * h * n_wavelengths * 2
        if cube_delivery(spectral) == CUBE_FILE:
            out.update(spectral=cube, render=tiff)
        else:
            out.update(spectral_on_demand=cube, render_on_demand=tiff)
    return out
