"""The pipelined full-resolution delivery (app.processing.band_pipeline): bands merged and encoded on several
threads in any order, sealed (hashed) in file order and written by I/O threads, give the same bytes and the same
SHA-256 as the in-order path (each band demosaiced, then encoded, then written and hashed in turn: the path
tests/app/test_masters.py checks against the whole-frame reference), for any number of workers, slots and band
sizes, with a linear and a root-polynomial model; the QA counts are the same; a failed write or a cancel leaves
nothing delivered; a cancel while the first band is encoded is the last band encoded."""
from __future__ import annotations

import hashlib
import threading
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime

import numpy as np
import pytest
import tifffile

from dualrgb.app.processing import tiff_stream
from dualrgb.app.processing.band_pipeline import BandPipeline, BandWork, close_all, encode_master, open_all
from dualrgb.app.processing.calibration import DarkFrame, FlatField, MasterDark
from dualrgb.app.processing.encode import DeliveryEncoder
from dualrgb.app.processing.outputs import TiffMetadata, open_tiff, rows_per_strip, tiff_kwargs
from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef
from dualrgb.common.atomic_files import FileWriteError
from dualrgb.common.progress import Cancelled, CancelToken

D65 = [95.047, 100.0, 108.883]
META = TiffMetadata("dualrgb 9.9", "ACC-1; test", "Nikon", "D610", 300.0, "2026:01:02 03:04:05", b"<x:xmpmeta/>" * 37)
H, W, BLACK, WHITE = 45, 61, 600, 15520        # a row of 366 bytes: every band's tail is carried to the next


def _master_stack(seed: int = 4, h: int = H):
    """Two lights, two exposures each (HDR), a dead white photosite (NaN) and a clipped one; ``h`` rows."""
    rng = np.random.default_rng(seed)
    darks = MasterDark()
    for t in (0.01, 0.04):
        darks.put(DarkFrame(t, np.full((h, W), BLACK, np.float32) + rng.uniform(0, 3, (h, W)).astype(np.float32), 10))
    proc = CaptureProcessor(darks=darks, white_level=WHITE, black_level=BLACK, cfa="GRBG")
    builder = None
    frames = {}
    for name in ("a", "b"):
        white = np.full((h, W), 1.5e5, np.float32)
        white[7, 9] = 0.0
        proc.put_white(name, FlatField(white))
        rad = rng.uniform(1e4, 8e5, (h, W))
        rad[3, 3] = 5e7
        frames[name] = [(np.clip(BLACK + rad * t + rng.normal(0, 2, (h, W)), 0, WHITE).astype(np.uint16), t)
                        for t in (0.01, 0.04)]
    builder = proc.begin_master(list(frames))
    for name, shots in frames.items():
        for m, t in shots:
            builder.add(name, ExposureRef(m, t))
    return builder.result(threads=2)


def _model(degree: int) -> np.ndarray:
    from dualrgb.simulation.colour_models import n_terms

    A = np.zeros((n_terms(6, degree), 3))
    A[:6] = np.random.default_rng(degree).uniform(0, 40, (6, 3))
    A[6:] = np.random.default_rng(degree + 1).uniform(-2, 2, (len(A) - 6, 3))
    return A


def _open(folder, band_rows: int, slots: int, direct: bool = True) -> list:
    return [open_tiff(folder / f"{i}.tif", (H, W, 3), META, band_rows=band_rows, digest="sha256", slots=slots,
                      direct=direct, photometric="rgb") for i in range(5)]


def _in_order(folder, degree: int, band_rows: int):
    """The in-order path: each band demosaiced (MasterStack.band), encoded (DeliveryEncoder.encode), written and
    hashed before the next; returns the streams (closed) and the stack's QA counts."""
    streams = _open(folder, band_rows, 2)
    with _master_stack() as stack, DeliveryEncoder((H, W, 6), _model(degree), D65, threads=1, degree=degree) as enc:
        for r0 in range(0, H, band_rows):
            rows = min(band_rows, H - r0)
            bands = [s.band(rows) for s in streams]
            enc.encode(r0, bands[0], bands[1:3], bands[3:], band=np.ascontiguousarray(stack.band(r0, rows)))
            for s in streams:
                s.commit()
        for s in streams:
            s.close()
        return streams, (stack.clipped_fraction, stack.underexposed_fraction, enc.invalid, enc.over_white)


@pytest.mark.parametrize("degree, band_rows, workers, slots", [(1, 8, 2, 4), (1, 1, 3, 2), (2, 5, 1, 3),
                                                               (2, 64, 2, 5), (1, 7, 3, 3)])
def test_pipelined_bands_are_the_in_order_paths_byte_for_byte(tmp_path, degree, band_rows, workers, slots):
    (tmp_path / "ref").mkdir()
    (tmp_path / "new").mkdir()
    ref, ref_qa = _in_order(tmp_path / "ref", degree, band_rows)
    streams = _open(tmp_path / "new", band_rows, slots)
    with _master_stack() as stack, DeliveryEncoder((H, W, 6), _model(degree), D65, degree=degree) as enc, \
            ThreadPoolExecutor(2) as io:
        encode_master(stack, enc, streams[0], streams[1:3], streams[3:], io=io, workers=workers)
        qa = (stack.clipped_fraction, stack.underexposed_fraction, enc.invalid, enc.over_white)
    assert qa == ref_qa and qa[1] > 0 and qa[2] > 0 and max(qa[0].values()) > 0
    for a, b in zip(ref, streams, strict=True):
        data = b.path.read_bytes()
        assert data == a.path.read_bytes(), b.path.name
        assert b.sha256 == a.sha256 == hashlib.sha256(data).hexdigest() and b.size == len(data)
    assert not [p for p in (tmp_path / "new").iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("direct", [True, False])
@pytest.mark.parametrize("shape, band_rows, slots", [((61, 83, 3), 7, 3), ((40, 33, 6), 1, 2), ((300, 517, 3), 64, 5)])
def test_ring_mode_is_byte_for_byte_tifffiles(tmp_path, direct, shape, band_rows, slots):
    """Bands filled by 3 threads in whatever order they come, sealed in file order: tifffile's bytes, and the
    SHA-256 of the file read back."""
    img = np.random.default_rng(7).integers(0, 65536, shape, dtype=np.uint16)
    out = open_tiff(tmp_path / "s.tif", shape, META, band_rows=band_rows, direct=direct, digest="sha256",
                    slots=slots, photometric="rgb")
    filled = []

    def fill(k: int, _prepared) -> None:
        band = out.ring_band(k)
        band[...] = img[k * band_rows: k * band_rows + len(band)]
        filled.append(k)
    n = -(-shape[0] // band_rows)
    with ThreadPoolExecutor(2) as io:
        BandPipeline(n, [out], BandWork(lambda k, s: None, fill), io=io, workers=3).run()
        close_all([out], io)
    with open(tmp_path / "t.tif", "wb") as fh:
        tifffile.imwrite(fh, img, **tiff_kwargs(META, photometric="rgb", rowsperstrip=rows_per_strip(shape, 2)))
    written = (tmp_path / "s.tif").read_bytes()
    assert written == (tmp_path / "t.tif").read_bytes()
    assert out.sha256 == hashlib.sha256(written).hexdigest() and out.size == len(written)
    assert sorted(filled) == list(range(n))


def _profile(folder, h: int):
    """A saved two-light calibration of an ``h``-row stack (lights a and b, 0.01 and 0.04 s)."""
    from dualrgb.app.workflow.calibration.profile import CalibrationProfile, CameraIdentity, SphereIdentity
    from dualrgb.core.vocabulary import NamedLight
    from dualrgb.simulation.lightsource import LightSource
    from dualrgb.simulation.matrix_fit import CharacterisationMatrix

    darks = MasterDark()
    for t in (0.01, 0.04):
        darks.put(DarkFrame(t, np.full((h, W), BLACK, np.float32), 5))
    prof = CalibrationProfile(
        id="cal-test", created_at="2026-01-01T00:00:00+00:00", mode="reflective",
        camera=CameraIdentity("Nikon D610", "3012345", "60 mm", 50, 8.0), sphere=SphereIdentity("S", "1", "S-1", 25.0),
        preset="P", lights=[NamedLight(n, LightSource((1, 6, 7), (0.0, 0.42, 1.0), n)) for n in ("a", "b")],
        exposures={"a": [0.01, 0.04], "b": [0.01, 0.04]}, base_exposures={"a": 0.01, "b": 0.01},
        matrix=CharacterisationMatrix(_model(1), [f"{c}{i}" for i in (1, 2) for c in "RGB"]),
        statistics={"best": "least-squares", "methods": {"least-squares": {"train": {"mean": 0.4}}}},
        white_xyz=D65, raw={"white_level": WHITE, "black_level": BLACK, "cfa": "GRBG", "linear_limit": 11000,
             "shape": [h, W]},
        sources={}, ppi=300.0, darks=darks, whites={n: FlatField(np.full((h, W), 1.5e5, np.float32)) for n in "ab"})
    prof.save(folder)
    return prof


def _deliver(tmp_path, name: str, in_order: bool, cancel: CancelToken | None = None):
    """deliver() of a two-light stack of 300 rows: 5 bands (the in-order path for a ChannelSource that is not a
    MasterStack)."""
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver

    prof = _profile(tmp_path / f"cal-{name}", 300)
    stack = _master_stack(h=300)
    with stack:
        return deliver(InOrder(stack) if in_order else stack, prof, Original("ACC-7"), tmp_path / name,
                       camera=prof.camera, dose=LightDoseRecord(), now=datetime(2026, 1, 2, tzinfo=UTC),
                       cancel=cancel)


class InOrder:
    """A MasterStack seen only as a ChannelSource: write_images takes its demosaiced bands in order."""

    def __init__(self, stack):
        self._stack = stack
        self.resolution, self.channels, self.lights = stack.resolution, stack.channels, stack.lights

    @property
    def shape(self):
        return self._stack.shape

    @property
    def clipped_fraction(self):
        return self._stack.clipped_fraction

    @property
    def underexposed_fraction(self):
        return self._stack.underexposed_fraction

    def band(self, r0, rows):
        return self._stack.band(r0, rows)

    def close(self):
        self._stack.close()


def test_a_pipelined_delivery_is_the_in_order_ones_file_for_file(tmp_path, monkeypatch):
    """Every deliverable's SHA-256 (read back), the sidecar's fixity of it and its QA line: as the in-order path's."""
    import json

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")          # the ICC profiles' creation time too

    got = {}
    for in_order in (False, True):
        d = _deliver(tmp_path, f"out-{in_order}", in_order)
        side = json.loads(d.sidecar.read_text())
        digests = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in d.files.values()}
        assert {n: v["sha256"] for n, v in side["fixity"]["files"].items()} == digests
        got[in_order] = digests, d.qa.text()
    assert got[False] == got[True] and len(got[False][0]) == 5


@pytest.mark.fault("session integrity")
def test_a_write_failing_in_the_pipeline_names_the_file_and_delivers_nothing(tmp_path, monkeypatch):
    calls = {"n": 0}
    real = tiff_stream._Output.pwrite

    def pwrite(self, data, pos):
        calls["n"] += 1
        if calls["n"] > 6:
            raise OSError(28, "No space left on device")
        return real(self, data, pos)
    monkeypatch.setattr(tiff_stream._Output, "pwrite", pwrite)
    with pytest.raises(FileWriteError, match=r"ACC-7_.*16bit\.tif: disk full"):
        _deliver(tmp_path, "out", False)
    assert list((tmp_path / "out").iterdir()) == []


def test_a_cancel_while_the_first_band_is_encoded_stops_the_pipeline_after_it(tmp_path, monkeypatch):
    """The other worker merges the next band meanwhile, but begins no encoding before the first band's has ended,
    so none after the cancel; nothing is delivered."""
    token = CancelToken()
    events, lock = [], threading.Lock()
    real = DeliveryEncoder.encode_mosaic

    def encode_mosaic(self, r0, *args, **kwargs):
        with lock:
            first = not events
            events.append(("begin", r0, token.cancelled))
        if first:
            token.cancel()
            threading.Event().wait(0.05)              # the other worker has time to reach its band's encoding
        out = real(self, r0, *args, **kwargs)
        with lock:
            events.append(("end", r0, token.cancelled))
        return out
    monkeypatch.setattr(DeliveryEncoder, "encode_mosaic", encode_mosaic)
    with pytest.raises(Cancelled):
        _deliver(tmp_path, "out", False, cancel=token)
    assert events == [("begin", 0, False), ("end", 0, True)]
    assert list((tmp_path / "out").iterdir()) == []


class HeldWrites(ThreadPoolExecutor):
    """An executor whose tasks (the pipeline's writes) wait until ``go`` is set, then a little more; it keeps
    their futures."""

    def __init__(self, workers: int):
        super().__init__(workers)
        self.futures: list = []
        self.go = threading.Event()

    def submit(self, fn, /, *args, **kwargs):
        def held():
            self.go.wait()
            threading.Event().wait(0.05)
            return fn(*args, **kwargs)
        self.futures.append(super().submit(held))
        return self.futures[-1]


def test_an_error_in_a_band_is_raised_once_every_write_has_ended(tmp_path):
    """A band failing while earlier bands' writes are in flight: the error is raised after they have ended (their
    buffers are not freed under them), and the files abort cleanly."""
    streams = _open(tmp_path, 16, 3)                  # band 0 holds whole blocks: written before band 1

    def encode(k, _prepared):
        if k == 1:
            io.go.set()
            raise ValueError("band 1 is broken")
        for s in streams:
            s.ring_band(k)[...] = k
    with HeldWrites(2) as io:
        with pytest.raises(ValueError, match="band 1 is broken"):
            BandPipeline(-(-H // 16), streams, BandWork(lambda k, s: None, encode), io=io, workers=1).run()
        assert io.futures and all(f.done() for f in io.futures)
    for s in streams:
        s.abort()
    assert list(tmp_path.iterdir()) == []


def test_a_stream_that_cannot_be_opened_leaves_no_other_behind(tmp_path):
    from contextlib import ExitStack

    def broken():
        raise OSError(13, "Permission denied")
    openers = {f"f{i}": (lambda i=i: open_tiff(tmp_path / f"{i}.tif", (H, W, 3), META, slots=3)) for i in range(3)}
    with pytest.raises(OSError, match="Permission denied"), ThreadPoolExecutor(2) as io:
        with ExitStack() as opened:
            open_all({**openers, "bad": broken}, io, opened)
    assert list(tmp_path.iterdir()) == []
