"""The streamed delivery: the banded encoder is bit for bit the numpy formulation of the encoding, the streamed
TIFF writer writes byte for byte what tifffile writes for the whole array (O_DIRECT or through the page cache,
any band size), a delivery's files are byte for byte the old path's (encode whole, ``tifffile.imwrite`` each
array), and a failed write leaves nothing half-written and names the file."""
from __future__ import annotations

import errno
import hashlib

import numpy as np
import pytest
import tifffile
from workflow_profiles import make_profile as _profile

from dualrgb.app.processing import tiff_stream
from dualrgb.app.processing.encode import LINEAR_ONE, RGB_SPACES, DeliveryEncoder, encode_deliverables, encoding_table
from dualrgb.app.processing.outputs import (
    TiffMetadata,
    icc_profile,
    open_tiff,
    rows_per_strip,
    tiff_kwargs,
    write_tiff,
    xyz_icc,
    xyz_to_rgb_matrix,
)
from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.delivery.deliverables import deliverable_files
from dualrgb.common.atomic_files import FileWriteError

D65 = [95.047, 100.0, 108.883]
META = TiffMetadata("dualrgb 9.9", "ACC-1; test", "Nikon", "D610", 300.0, "2026:01:02 03:04:05", b"<x:xmpmeta/>" * 37)


def _to16(q: np.ndarray) -> np.ndarray:
    return np.where(q <= 0.5, 0, np.where(q >= 65535.0, 65535, q)).astype(np.uint16)


def reference_encoding(stack: np.ndarray, matrix: np.ndarray, white: list[float]) -> dict[str, np.ndarray]:
    """The encoding as numpy operations, in the order the kernel performs them (float32, the table interpolation
    in float64): an independent formulation that must agree bit for bit."""
    nan = np.isnan(stack)
    v = np.where(nan, np.float32(0), stack).astype(np.float32)
    w = np.asarray(white, np.float64)
    A = (np.asarray(matrix, np.float64) / w).astype(np.float32)          # x, y, z: X / Xn, Y / Yn, Z / Zn
    xyz = [np.zeros(stack.shape[:2], np.float32) for _ in range(3)]
    for c in range(stack.shape[2]):
        for k in range(3):
            xyz[k] = xyz[k] + v[..., c] * A[c, k]
    scale = np.float32(65535.0)
    out = {"channels": _to16(v * np.float32(LINEAR_ONE) + np.float32(0.5)),
           "xyz": np.stack([_to16(x * scale + np.float32(0.5)) for x in xyz], -1)}
    for space in RGB_SPACES:
        M = (xyz_to_rgb_matrix(space, white) * (w / w[1])).astype(np.float32)
        lut = encoding_table(space)
        last = lut.size - 1
        planes = []
        for k in range(3):
            lin = M[k, 0] * xyz[0] + M[k, 1] * xyz[1] + M[k, 2] * xyz[2]
            lin = np.minimum(np.maximum(lin, np.float32(0)), np.float32(1)).astype(np.float64) * last
            i0 = np.minimum(lin.astype(np.int64), last - 1)
            e = lut[i0] + (lin - i0) * (lut[i0 + 1] - lut[i0]).astype(np.float64)
            planes.append((e + 0.5).astype(np.uint16))
        out[space] = np.stack(planes, -1)
    return out


@pytest.mark.parametrize("channels", [3, 6])
def test_banded_encoding_is_bit_for_bit_the_numpy_formulation(channels):
    rng = np.random.default_rng(channels)
    stack = rng.uniform(-0.3, 2.4, (37, 29, channels)).astype(np.float32)   # below 0, above the 2x headroom
    stack[rng.random((37, 29)) < 0.05, channels - 1] = np.nan
    A = rng.uniform(0, 60, (channels, 3))
    ref = reference_encoding(stack, A, D65)
    whole = encode_deliverables(stack, A, D65)
    lights = channels // 3
    for given in ("stack", "bands"):        # the whole stack at construction, or each band with its call
        source = stack if given == "stack" else stack.shape
        with DeliveryEncoder(source, A, D65, threads=2) as enc:     # bands of 5 rows, each split over 2 threads
            got = {k: np.empty_like(v) for k, v in ref.items()}
            for r0 in range(0, 37, 5):
                r1 = min(r0 + 5, 37)
                bands = {k: np.empty((r1 - r0,) + v.shape[1:], np.uint16) for k, v in ref.items() if k != "channels"}
                per_light = [np.empty((r1 - r0, 29, 3), np.uint16) for _ in range(lights)]   # one TIFF per light
                enc.encode(r0, bands["xyz"], [bands[s] for s in RGB_SPACES], per_light,
                           band=None if given == "stack" else np.ascontiguousarray(stack[r0:r1]))
                bands["channels"] = np.concatenate(per_light, axis=2)
                for k in ref:
                    got[k][r0:r1] = bands[k]
        for k in ref:
            assert np.array_equal(got[k], ref[k]), (given, k)
    assert np.array_equal(whole.xyz, ref["xyz"]) and np.array_equal(whole.channels, ref["channels"])
    assert all(np.array_equal(whole.rgb[s], ref[s]) for s in RGB_SPACES)
    assert enc.invalid == np.isnan(stack).any(-1).sum() and whole.invalid_fraction == enc.invalid_fraction


@pytest.mark.parametrize("direct", [True, False])
@pytest.mark.parametrize("shape, band_rows, space", [((61, 83, 3), 7, "ProPhoto RGB"), ((40, 33, 6), 1, None),
                                                      ((300, 517, 3), 64, "sRGB"), ((5, 3, 3), 64, None)])
def test_streamed_tiff_is_byte_for_byte_tifffiles(tmp_path, direct, shape, band_rows, space):
    """... and the SHA-256 computed while streaming is the written file's (hashlib over the file read back)."""
    img = np.random.default_rng(7).integers(0, 65536, shape, dtype=np.uint16)
    kw = dict(photometric="rgb" if space else "minisblack", icc=icc_profile(space) if space else None)
    with open_tiff(tmp_path / "s.tif", shape, META, band_rows=band_rows, direct=direct, digest="sha256", **kw) as out:
        assert out.direct == (direct and bool(tiff_stream.O_DIRECT))
        for r0 in range(0, shape[0], out.band_rows):
            rows = min(out.band_rows, shape[0] - r0)
            out.band(rows)[...] = img[r0:r0 + rows]
            out.commit()
    with open(tmp_path / "t.tif", "wb") as fh:
        tifffile.imwrite(fh, img, **tiff_kwargs(META, rowsperstrip=rows_per_strip(shape, 2), **kw))
    written = (tmp_path / "s.tif").read_bytes()
    assert written == (tmp_path / "t.tif").read_bytes()
    assert out.sha256 == hashlib.sha256(written).hexdigest() and out.size == len(written)
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def test_delivered_files_are_the_old_paths_byte_for_byte(tmp_path):
    """Before streaming, deliver encoded whole arrays and wrote each with tifffile.imwrite (outputs.tiff_kwargs
    holds those arguments): same pixels, tags, XMP and ICC (no EXIF here: it follows the pixels, tested apart)."""
    from dualrgb.app.workflow.delivery import delivery
    from dualrgb.app.workflow.delivery.camera_profiles import camera_rgb_icc

    prof = _profile(tmp_path)
    iccs = {s: icc_profile(s) for s in RGB_SPACES}                  # the profiles carry their creation time
    iccs.update(XYZ=xyz_icc(prof.white_xyz), camera=camera_rgb_icc(prof, 0, "P light 1"))

    class Context:                          # what app.workflow.delivery.master_metadata.MasterContext gives the writer
        def meta(self, im):
            return META

        def icc(self, im):
            return iccs[im.icc]
    rng = np.random.default_rng(11)
    data = rng.uniform(0, 1.3, (70, 45, 3)).astype(np.float32)
    data[3, 4, 1] = np.nan
    stack = ChannelStack(data, ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
    images = deliverable_files(tmp_path / "out", "ACC-1", stack.channels)
    (tmp_path / "out").mkdir()
    written = delivery.write_images(stack, prof, images, Context(), band_rows=16)
    enc = encode_deliverables(data, prof.matrix.matrix, prof.white_xyz)
    arrays = {"prophoto": enc.rgb["ProPhoto RGB"], "srgb": enc.rgb["sRGB"], "xyz": enc.xyz,
              "channels_1": enc.channels}
    for key, im in images.items():
        ref = tmp_path / f"ref_{key}.tif"
        with open(ref, "wb") as fh:
            tifffile.imwrite(fh, arrays[key], **tiff_kwargs(META, photometric=im.photometric, icc=iccs[im.icc],
                                                           rowsperstrip=rows_per_strip(arrays[key].shape, 2)))
        assert written.files[key].read_bytes() == ref.read_bytes(), key
        data = ref.read_bytes()
        assert written.fixity[key] == {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    assert written.invalid == pytest.approx(1 / (70 * 45))


def _failing_pwrite(monkeypatch, after: int) -> None:
    calls = {"n": 0}
    real = tiff_stream._Output.pwrite

    def pwrite(self, data, pos):
        calls["n"] += 1
        if calls["n"] > after:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, data, pos)
    monkeypatch.setattr(tiff_stream._Output, "pwrite", pwrite)


@pytest.mark.fault("session integrity")
def test_a_write_failing_mid_stream_keeps_the_previous_file_and_names_it(tmp_path, monkeypatch):
    target = tmp_path / "img.tif"
    target.write_bytes(b"previous version\n")
    _failing_pwrite(monkeypatch, after=2)
    with pytest.raises(FileWriteError) as info:
        write_tiff(target, np.ones((400, 300, 3), np.uint16), META, band_rows=8)
    assert str(target) in str(info.value) and "disk full" in str(info.value) and "\n" not in str(info.value)
    assert target.read_bytes() == b"previous version\n"
    assert [p.name for p in tmp_path.iterdir()] == ["img.tif"]


@pytest.mark.fault("session integrity")
def test_a_failed_delivery_leaves_no_partial_deliverable(tmp_path, monkeypatch):
    """The files of a delivery are written into a fresh folder and swapped in only when all are complete: a disk
    filling up mid-delivery leaves no folder for the original (and no staging folder) behind."""
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver

    prof = _profile(tmp_path)
    stack = ChannelStack(np.full((300, 200, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
    _failing_pwrite(monkeypatch, after=5)
    with pytest.raises(FileWriteError, match="ACC-9_.*16bit.tif: disk full"):
        deliver(stack, prof, Original("ACC-9"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord())
    assert list((tmp_path / "out").iterdir()) == []


@pytest.mark.fault("session integrity")
def test_a_failed_redelivery_keeps_the_previous_set_untouched(tmp_path, monkeypatch):
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver

    prof = _profile(tmp_path)
    stack = ChannelStack(np.full((300, 200, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
    first = deliver(stack, prof, Original("ACC-9"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord())
    folder = first.sidecar.parent
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    _failing_pwrite(monkeypatch, after=5)
    with pytest.raises(FileWriteError, match="disk full"):
        deliver(stack, prof, Original("ACC-9"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord())
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["ACC-9"]


def test_a_stream_closed_early_is_refused_and_removed(tmp_path):
    with pytest.raises(ValueError, match="3 of 10 rows written"):
        with open_tiff(tmp_path / "x.tif", (10, 4, 3), META, band_rows=3) as out:
            out.band(3)[...] = 1
            out.commit()
    assert list(tmp_path.iterdir()) == []
    out = open_tiff(tmp_path / "y.tif", (4, 4, 3), META, band_rows=3)
    with pytest.raises(ValueError, match="at most 3 per band"):
        out.band(4)
    out.abort()
    assert list(tmp_path.iterdir()) == []
