"""The spectral cube as a stated map of the delivered camera channels: what the sidecar documents so that anyone
can rebuild the cube without dualrgb, and the streamed rebuild ``dualrgb cube`` runs.

The cube is the 6-channel image through the calibration's spectral estimator (a linear map, plus an offset for
film, then a clip): six 16-bit channels hold all of its information. Per pixel, with ``code_k`` the k-th camera
channel (R1 G1 B1 R2 G2 B2 ..., from the per-light camera-RGB TIFFs, in that order)::

    c_k = code_k / 32768                                         (the channels' linear scale: 1.0 = the white)
    s_b = clip(offset_b + sum_k matrix[b][k] * c_k, lo, hi)      (the factor at wavelength b)
    cube_b = round(s_b * 10000)                                  (ENVI data, 16-bit, reflectance scale 10000)

:func:`spectral_map` writes exactly this into the sidecar (matrix, offset, bounds, scales, the channel files and
their order); :func:`materialise` applies it band by band with the delivery's own spectral kernel
(app.processing.spectral_cube) to the channel TIFFs and writes the ENVI cube, so a cube made on demand is the
cube a half-resolution delivery writes from the same channels (the tests rebuild it with plain numpy from the
sidecar and the TIFFs, to one code value: float32 against float64 rounding).
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.processing.encode import LINEAR_ONE
from dualrgb.app.processing.envi import DTYPE, IGNORE_VALUE, INTERLEAVE, SCALE_FACTOR
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.spectral_estimation import SpectralEstimator

log = logging.getLogger(__name__)

FORMULA = ("cube[b] = round(clip(offset[b] + sum_k matrix[b][k] * code_k / channel_scale, bounds[0], bounds[1])"
           " * cube_scale); code_k: the k-th channel of the channel files, in channel order")


def spectral_map(est: SpectralEstimator, channel_files: Sequence[str]) -> dict[str, Any]:
    """The sidecar's ``spectral.map``: everything needed to compute the cube from the delivered channel files."""
    return {"formula": FORMULA, "channels": list(est.channels), "channel_files": list(channel_files),
            "channel_scale": LINEAR_ONE, "matrix": [[float(v) for v in row] for row in est.matrix],
            "offset": [float(v) for v in (est.offset if est.offset is not None else np.zeros(est.n_wavelengths))],
            "bounds": [float(b) for b in est.bounds], "cube_scale": SCALE_FACTOR,
            "wavelengths_nm": [float(w) for w in est.wavelengths], "quantity": est.quantity, "method": est.method,
            "data_type": "uint16",
            "interleave": INTERLEAVE, "byte_order": "little-endian"}


def estimator_of_map(section: dict[str, Any]) -> SpectralEstimator:
    """The estimator a sidecar's ``spectral.map`` states (ValueError naming what is wrong)."""
    try:
        M = np.asarray(section["matrix"], dtype=float)
        offset = np.asarray(section["offset"], dtype=float)
        wl = np.asarray(section["wavelengths_nm"], dtype=float)
        lo, hi = (float(b) for b in section["bounds"])
        channels = [str(c) for c in section["channels"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the sidecar's spectral map is incomplete ({type(exc).__name__}: {exc})") from None
    if M.shape != (wl.size, len(channels)) or offset.shape != (wl.size,):
        raise ValueError(f"the sidecar's spectral map: matrix {M.shape}, offset {offset.shape} for {wl.size} "
                         f"wavelengths and {len(channels)} channels")
    return SpectralEstimator(M, wl, channels, str(section.get("method", "")), {}, (lo, hi),
                             str(section.get("quantity", "")), offset)


def open_channels(paths: Sequence[Path]) -> list[np.ndarray]:
    """The camera-RGB TIFFs as read-only maps of their pixels ((H, W, 3) uint16 each), all of one size."""
    import tifffile

    arrays: list[np.ndarray] = []
    for p in paths:
        try:
            arr = tifffile.memmap(p, mode="r")
        except (OSError, ValueError) as exc:
            raise ValueError(f"{p}: cannot read the channels ({exc})") from None
        if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint16:
            raise ValueError(f"{p}: {arr.shape} {arr.dtype}, expected an (H, W, 3) 16-bit RGB image")
        if arrays and arr.shape != arrays[0].shape:
            raise ValueError(f"{p}: {arr.shape[1]}x{arr.shape[0]}, the first channel file "
                             f"{arrays[0].shape[1]}x{arrays[0].shape[0]}")
        arrays.append(arr)
    return arrays


def channels_band(arrays: Sequence[np.ndarray], r0: int, r1: int, out: np.ndarray | None = None) -> np.ndarray:
    """Rows r0 .. r1 of the channel files as the (rows, W, N) float32 channels (code / 32768)."""
    rows, W = r1 - r0, arrays[0].shape[1]
    if out is None or out.shape != (rows, W, 3 * len(arrays)):
        out = np.empty((rows, W, 3 * len(arrays)), np.float32)
    for i, arr in enumerate(arrays):
        np.multiply(arr[r0:r1], np.float32(1.0 / LINEAR_ONE), out=out[..., 3 * i: 3 * i + 3], casting="unsafe")
    return out


class MappedCube:
    """The cube of a delivery made on demand, read like a delivered ENVI cube (app.processing.envi.CubeFile:
    ``shape``, ``wavelengths``, ``pixel``, ``rows``): each asked-for pixel or row computed from the channel files
    through the sidecar's map (the GUI's delivered view, the virtual lab's truth figures)."""

    def __init__(self, channel_paths: Sequence[Path], est: SpectralEstimator):
        self.arrays = open_channels(channel_paths)
        if 3 * len(self.arrays) != est.n_channels:
            raise ValueError(f"{len(self.arrays)} channel files hold {3 * len(self.arrays)} channels, the map takes "
                             f"{est.n_channels}")
        self.estimator = est
        self.wavelengths = np.asarray(est.wavelengths, dtype=float)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(lines, samples, bands)."""
        return self.arrays[0].shape[0], self.arrays[0].shape[1], self.estimator.n_wavelengths

    def pixel(self, row: int, col: int) -> np.ndarray:
        """The factor spectrum (bands,) of one pixel."""
        if not (0 <= row < self.shape[0] and 0 <= col < self.shape[1]):
            raise ValueError(f"pixel ({row}, {col}) outside {self.shape[1]} x {self.shape[0]}")
        return self.rows(row, row + 1)[0, col]

    def rows(self, r0: int, r1: int, step: int = 1) -> np.ndarray:
        """Factor spectra (rows, samples / step, bands) of rows r0 .. r1 (every ``step``-th row and column), as the
        cube's 16-bit values hold them (rounded to 1 / the cube's scale)."""
        chans = np.concatenate([np.asarray(a[r0:r1:step, ::step]) for a in self.arrays], axis=-1)
        spectra = self.estimator.apply(chans.astype(np.float32) * np.float32(1.0 / LINEAR_ONE))
        return np.round(spectra * np.float32(SCALE_FACTOR)) / np.float32(SCALE_FACTOR)


def materialise(channel_paths: Sequence[Path], est: SpectralEstimator, data_path: Path, *, band_rows: int = 64,
                progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> tuple[int, int]:
    """Write the ENVI data of the cube of ``channel_paths`` (the sidecar's channel files, in order) through
    ``est`` to ``data_path``, streamed and atomic (app.processing.tiff_stream.RawStream); returns (lines,
    samples). The header is the caller's (it knows the original)."""
    from dualrgb.app.processing.spectral_cube import SpectralEncoder
    from dualrgb.app.processing.tiff_stream import RawStream

    arrays = open_channels(channel_paths)
    H, W, _ = arrays[0].shape
    if 3 * len(arrays) != est.n_channels:
        raise ValueError(f"{len(arrays)} channel files hold {3 * len(arrays)} channels, the map takes "
                         f"{est.n_channels}")
    band = None
    with SpectralEncoder((H, W, est.n_channels), est.matrix, est.bounds, None, offset=est.offset) as enc, \
            RawStream(data_path, (H, est.n_wavelengths, W), DTYPE, band_rows=band_rows) as out:
        for r0 in range(0, H, out.band_rows):
            check(cancel)
            r1 = min(r0 + out.band_rows, H)
            band = channels_band(arrays, r0, r1, band)
            enc.encode(r0, out.band(r1 - r0), band=band)
            out.commit()
            report(progress, r1 / H, f"cube rows {r1} of {H}")
    return H, W


__all__ = ["FORMULA", "IGNORE_VALUE", "MappedCube", "channels_band", "estimator_of_map", "materialise",
           "open_channels", "spectral_map"]
