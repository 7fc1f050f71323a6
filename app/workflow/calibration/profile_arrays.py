"""A calibration profile's arrays (``<id>.npz``: master darks, HDR whites, stand observations), loaded into memory
or, for a large sensor, mapped from the file.

A 150 MP calibration holds 3.6 GB of float32 darks and whites (four exposure times and two lights); loaded, they
alone would exceed the memory a full-resolution delivery needs. Above :data:`RESIDENT_LIMIT_BYTES` the darks and
whites are therefore ``np.memmap`` views of their members in the .npz (``np.savez`` stores members uncompressed,
each a .npy file at a fixed offset): nothing is read until used, the full-resolution path reads them one row band
at a time (app.processing.masters.band_of: read into a band buffer, so the map's pages never count against the
process), and the half-resolution path reads them through the map as it would the array. Below the limit (a 24 MP
profile is 0.6 GB) they are loaded as before, so their first use costs no disk or page-cache reads.
"""
from __future__ import annotations

import logging
import os
import struct
import zipfile
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

RESIDENT_LIMIT_BYTES = int(os.environ.get("DUALRGB_RESIDENT_CALIBRATION_MB", "1024")) << 20
_LOCAL_HEADER = struct.Struct("<4s22sHH")          # signature ... file name length, extra field length


class ProfileArrays:
    """``arrays[name]``: the .npz member ``name`` as an array (loaded) or an np.memmap (large profiles)."""

    def __init__(self, npz: Path, resident_limit: int = RESIDENT_LIMIT_BYTES):
        self.path = Path(npz)
        self._npz = np.load(self.path)
        with zipfile.ZipFile(self.path) as zf:
            self._infos = {i.filename[:-4]: i for i in zf.infolist() if i.filename.endswith(".npy")}
        total = sum(i.file_size for i in self._infos.values())
        self.mapped = total > resident_limit and all(i.compress_type == zipfile.ZIP_STORED
                                                     for i in self._infos.values())
        if self.mapped:
            log.info("calibration arrays %s: %.0f MB, mapped from the file (read by row bands when used)",
                     self.path, total / 1e6)

    def __contains__(self, name: str) -> bool:
        return name in self._infos

    @property
    def files(self) -> list[str]:
        """The members' names (as np.load's NpzFile.files)."""
        return list(self._infos)

    def __getitem__(self, name: str) -> np.ndarray:
        if not self.mapped:
            return self._npz[name]
        return self._map(name)

    def _map(self, name: str) -> np.ndarray:
        info = self._infos[name]
        with open(self.path, "rb") as fh:
            fh.seek(info.header_offset)
            sig, _, n_name, n_extra = _LOCAL_HEADER.unpack(fh.read(_LOCAL_HEADER.size))
            if sig != b"PK\x03\x04":
                raise ValueError(f"{self.path}: member {name} has no zip local header")
            start = info.header_offset + _LOCAL_HEADER.size + n_name + n_extra
            fh.seek(start)
            version = np.lib.format.read_magic(fh)
            read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                    else np.lib.format.read_array_header_2_0)
            shape, fortran, dtype = read(fh)
            offset = fh.tell()
        if len(shape) < 2 or dtype.hasobject:     # small or odd arrays (stand observations): read as they are
            return self._npz[name]
        return np.memmap(self.path, dtype=dtype, mode="r", offset=offset, shape=shape,
                         order="F" if fortran else "C")
