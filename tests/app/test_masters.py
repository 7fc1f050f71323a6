"""Full-resolution channels (app.processing.masters): band by band, the merged, flat-fielded, demosaiced channels
equal an independent formulation on the whole frame - the half-resolution path's own HdrMerge and FlatField
(frame-size numpy / kernels) followed by colour-demosaicing's Malvar-He-Cutler - for every band size, with
master-dark arrays, a black level instead of a dark, several frames of one exposure time, both HDR methods,
clipped and invalid pixels; the calibration's arrays give the same bands whether loaded or mapped from the file;
a delivery from raw files on disk has the raw frame's pixel size."""
from __future__ import annotations

import warnings
from contextlib import closing

import numpy as np
import pytest
import tifffile

from dualrgb.app.processing.calibration import DarkFrame, FlatField, MasterDark
from dualrgb.app.processing.hdr import HdrMerge
from dualrgb.app.processing.masters import band_of
from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef

colour_demosaicing = pytest.importorskip("colour_demosaicing")

H, W, BLACK, WHITE = 37, 52, 600, 15520
TIMES = (0.01, 0.02, 0.1)


def reference_demosaic(mosaic: np.ndarray, cfa: str) -> np.ndarray:
    padded = np.pad(mosaic.astype(np.float64), 2, mode="reflect")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return colour_demosaicing.demosaicing_CFA_Bayer_Malvar2004(padded, cfa)[2:-2, 2:-2]


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(3)
    dark = {t: (BLACK + rng.uniform(0, 3, (H, W))).astype(np.float32) for t in TIMES}

    def frame(rad, t):
        return np.clip(dark.get(t, BLACK) + rad * t + rng.normal(0, 2, (H, W)), 0, WHITE).astype(np.uint16)
    rad1 = rng.uniform(1e3, 2e5, (H, W))
    rad1[5, 6] = 5e6                                          # above the linear limit in every exposure: clipped
    rad2 = rng.uniform(10, 1e5, (H, W))
    frames = {"a": [(frame(rad1, 0.01), 0.01), (frame(rad1, 0.1), 0.1), (frame(rad1, 0.1), 0.1)],
              "b": [(frame(rad2, 0.02), 0.02), (frame(rad2, 0.05), 0.05)]}          # 0.05 s: no master dark
    white_a = np.full((H, W), 1.5e5, np.float32)
    white_a[3, 4] = 0.0                                       # no usable white: NaN, spread by the demosaic
    whites = {"a": FlatField(white_a), "b": FlatField(np.full((H, W), 1.2e5, np.float32))}
    return dark, frames, whites


def processor(dark, whites, method, cfa, darks=None):
    md = darks or MasterDark()
    if darks is None:
        for t, d in dark.items():
            md.put(DarkFrame(t, d, 10))
    proc = CaptureProcessor(darks=md, white_level=WHITE, black_level=BLACK, cfa=cfa, hdr_method=method)
    for name, ff in whites.items():
        proc.put_white(name, ff)
    return proc


def reference(dark, frames, whites, method, cfa):
    out = []
    for light, fs in frames.items():
        merge = HdrMerge(WHITE, black_level=BLACK, method=method)
        for m, t in fs:
            merge.add(m, t, dark.get(t))                      # no dark array: the black level
        flat = whites[light].apply(merge.result().radiance)
        out.append(reference_demosaic(flat, cfa))
    return np.concatenate(out, axis=2)


def master_bands(proc, frames, band_rows):
    builder = proc.begin_master(list(frames))
    for light, fs in frames.items():
        for m, t in fs:
            builder.add(light, ExposureRef(m, t))
    with builder.result() as stack:
        assert stack.shape == (H, W) and stack.channels == ["R1", "G1", "B1", "R2", "G2", "B2"]
        got = np.concatenate([stack.band(r0, min(band_rows, H - r0)).copy() for r0 in range(0, H, band_rows)])
        return got, stack.clipped_fraction, stack.underexposed_fraction


@pytest.mark.parametrize("method, cfa, band_rows", [("variance", "RGGB", 8), ("thesis", "GRBG", 5),
                                                    ("variance", "BGGR", 1), ("variance", "GBRG", H)])
def test_bands_equal_the_whole_frame_reference(scene, method, cfa, band_rows):
    dark, frames, whites = scene
    got, clipped, under = master_bands(processor(dark, whites, method, cfa), frames, band_rows)
    ref = reference(dark, frames, whites, method, cfa)
    assert np.array_equal(np.isnan(got), np.isnan(ref)) and np.isnan(got[3, 4, :3]).all()
    ok = np.isfinite(ref)
    np.testing.assert_allclose(got[ok], ref[ok], rtol=2e-5, atol=1e-6)
    assert clipped["a"] == pytest.approx(1 / (H * W)) and clipped["b"] == 0.0
    assert under == 0.0


def test_the_fused_variance_kernel_is_the_general_one_bit_for_bit(scene):
    """Exposures of distinct times merged by variance take the fused kernel (master_kernels.flat_rows_variance):
    the same bits as the general slots + kernels._merge_row path, clipped and under-exposed counts included."""
    dark, frames, whites = scene
    frames = {"a": [frames["a"][0], frames["a"][1]], "b": frames["b"]}          # one frame per exposure time
    got = {}
    for fused in (True, False):
        builder = processor(dark, whites, "variance", "GRBG").begin_master(list(frames))
        for light, fs in frames.items():
            for m, t in fs:
                builder.add(light, ExposureRef(m, t))
        with builder.result() as stack:
            stack._fused = fused
            bands = np.concatenate([stack.band(r0, min(6, H - r0)).copy() for r0 in range(0, H, 6)])
            got[fused] = (bands, stack.clipped_fraction, stack.underexposed_fraction)
    assert np.array_equal(got[True][0], got[False][0], equal_nan=True)
    assert got[True][1:] == got[False][1:] and got[True][1]["a"] > 0


def _encoded(stack, enc, band_rows, fused):
    """The five 16-bit images of ``stack`` encoded band by band: demosaiced as encoded (``fused``:
    DeliveryEncoder.encode_mosaic) or from the demosaiced bands (DeliveryEncoder.encode)."""
    from dualrgb.app.processing.demosaic import HALO

    out = [np.empty((H, W, 3), np.uint16) for _ in range(5)]
    for r0 in range(0, H, band_rows):
        rows = min(band_rows, H - r0)
        bands = (out[0][r0:r0 + rows], [o[r0:r0 + rows] for o in out[1:3]], [o[r0:r0 + rows] for o in out[3:]])
        if fused:
            enc.encode_mosaic(r0, *bands, mosaic=stack.mosaic_band(r0, rows), p0=HALO, cfa=stack.cfa_index)
        else:
            enc.encode(r0, *bands, band=np.ascontiguousarray(stack.band(r0, rows)))
    return out


@pytest.mark.parametrize("cfa, band_rows, threads", [("RGGB", 8, 2), ("GRBG", 1, 1), ("BGGR", 5, 3),
                                                     ("GBRG", H, 2)])
def test_demosaicing_while_encoding_is_the_banded_path_bit_for_bit(scene, cfa, band_rows, threads):
    """The delivery of a full-resolution original demosaics each row as it encodes it (encode_mosaic: no N-channel
    float band): the same bits as demosaicing the band first and encoding it, and within one code value of the
    independent reference (HdrMerge + FlatField + colour-demosaicing, encoded whole), NaN pixels included."""
    from dualrgb.app.processing.encode import RGB_SPACES, DeliveryEncoder, encode_deliverables

    dark, frames, whites = scene
    matrix = np.random.default_rng(5).uniform(0, 60, (6, 3))
    white = [95.047, 100.0, 108.883]
    got = {}
    for fused in (True, False):
        builder = processor(dark, whites, "variance", cfa).begin_master(list(frames))
        for light, fs in frames.items():
            for m, t in fs:
                builder.add(light, ExposureRef(m, t))
        with builder.result(threads=threads) as stack, \
                DeliveryEncoder((H, W, 6), matrix, white, threads=threads) as enc:
            got[fused] = (_encoded(stack, enc, band_rows, fused), enc.invalid, enc.over_white, enc.lit)
    assert all(np.array_equal(a, b) for a, b in zip(got[True][0], got[False][0], strict=True))
    assert got[True][1:] == got[False][1:] and got[True][1] > 0
    ref = encode_deliverables(reference(dark, frames, whites, "variance", cfa).astype(np.float32), matrix, white)
    expected = [ref.xyz, *(ref.rgb[s] for s in RGB_SPACES), ref.channels[..., :3], ref.channels[..., 3:]]
    for image, want in zip(got[True][0], expected, strict=True):
        assert np.abs(image.astype(np.int32) - want).max() <= 1
    assert got[True][1] == round(ref.invalid_fraction * H * W)


def test_calibration_arrays_mapped_from_a_file_give_the_same_bands(scene, tmp_path):
    """A large calibration's darks and whites are np.memmap views of the .npz
    (app.workflow.calibration.profile_arrays): the
    bands read from the file equal the bands of the arrays in memory."""
    dark, frames, whites = scene
    maps, mapped_whites = {}, {}
    for i, (t, d) in enumerate(dark.items()):
        np.save(tmp_path / f"d{i}.npy", d)
        maps[t] = np.load(tmp_path / f"d{i}.npy", mmap_mode="r")
    for name, ff in whites.items():
        np.save(tmp_path / f"w{name}.npy", ff.white)
        mapped = FlatField.__new__(FlatField)
        mapped.white, mapped.threshold, mapped.n_invalid = (np.load(tmp_path / f"w{name}.npy", mmap_mode="r"),
                                                            ff.threshold, 0)
        mapped_whites[name] = mapped
    md = MasterDark()
    for t, m in maps.items():
        md.put(DarkFrame(t, m, 10))
    in_memory, _, _ = master_bands(processor(dark, whites, "variance", "RGGB"), frames, 7)
    from_file, _, _ = master_bands(processor(dark, mapped_whites, "variance", "RGGB", md), frames, 7)
    assert np.array_equal(in_memory, from_file, equal_nan=True)
    buffers: dict = {}
    band = band_of(maps[0.1], 11, 20, buffers, "k")
    assert not isinstance(band, np.memmap) and np.array_equal(band, dark[0.1][11:20])


def test_underexposed_photosites_are_counted_under_every_light():
    rng = np.random.default_rng(8)
    dark = {0.01: np.full((8, 10), BLACK, np.float32)}
    faint = np.clip(BLACK + rng.uniform(0, 50, (8, 10)), 0, WHITE).astype(np.uint16)   # < 100 DN of signal
    bright = faint.copy()
    bright[:4] += 2000                                        # the top half is well exposed under light b
    whites = {"a": FlatField(np.full((8, 10), 1e5, np.float32)), "b": FlatField(np.full((8, 10), 1e5, np.float32))}
    frames = {"a": [(faint, 0.01)], "b": [(bright, 0.01)]}
    proc = processor(dark, whites, "variance", "RGGB")
    builder = proc.begin_master(["a", "b"])
    for light, fs in frames.items():
        for m, t in fs:
            builder.add(light, ExposureRef(m, t))
    with builder.result() as stack:
        for r0 in range(0, 8, 3):
            stack.band(r0, min(3, 8 - r0))
        assert stack.underexposed_fraction == pytest.approx(0.5)


def test_a_missing_light_or_a_frame_of_another_size_is_one_line(scene):
    dark, frames, whites = scene
    builder = processor(dark, whites, "variance", "RGGB").begin_master(["a", "b"])
    builder.add("a", ExposureRef(frames["a"][0][0], 0.01))
    with pytest.raises(ValueError, match="frame 10x8, the original's earlier frames 52x37"):
        builder.add("a", ExposureRef(np.zeros((8, 10), np.uint16), 0.01))
    with pytest.raises(ValueError, match="no exposures of b were added"):
        builder.result()
    with pytest.raises(ValueError, match="'c' is not one of this original's lights"):
        builder.add("c", ExposureRef(frames["a"][0][0], 0.01))


def test_a_full_resolution_delivery_has_the_raw_frames_size(tmp_path):
    """From DNGs on disk (LibRaw's buffers held, not copied) to TIFFs of the raw frame's size: the sensor's pixels,
    not the 2x2 cells' (half resolution gives half of each side)."""
    from synthetic_frames import write_dng
    from workflow_profiles import make_profile

    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver
    from dualrgb.app.workflow.stand.copystand import channels_of, profile_processor

    prof = make_profile(tmp_path / "cal", shape=(24, 36))      # one light
    rng = np.random.default_rng(4)
    paths = [write_dng(tmp_path / f"f{i}.dng", np.clip(600 + rng.uniform(100, 9000, (24, 36)), 0, 15520))
             for i in range(2)]
    refs = {"P light 1": [ExposureRef(paths[0], 0.01), ExposureRef(paths[1], 0.01)]}
    sizes = {}
    for resolution in ("full", "half"):
        source = channels_of(profile_processor(prof), refs, resolution)
        with closing(source):
            d = deliver(source, prof, Original(f"ACC-{resolution}"), tmp_path / "out", camera=prof.camera,
                        dose=LightDoseRecord())
        sizes[resolution] = {k: tifffile.imread(p).shape for k, p in d.files.items()}
    assert set(sizes["full"].values()) == {(24, 36, 3)} and set(sizes["half"].values()) == {(12, 18, 3)}
