"""The spectral deliverables (issue 21): the streamed cube is the estimator applied per pixel (checked against
SpectralEstimator.apply), the rendering under another light is colour-science's (sd_to_XYZ + XYZ_to_RGB with
Bradford + ProPhoto's encoding), Spectral Python opens the ENVI cube with the right wavelengths and shape, the
rendering carries the TIFFs' metadata, the sidecar says how the cube was made, and a failed write leaves nothing."""
from __future__ import annotations

import errno
import json

import numpy as np
import pytest
import tifffile
from sidecar_schema import assert_valid_sidecar
from spectral_profiles import estimator, spectral_profile, stack
from workflow_profiles import make_profile
from xmp_check import read_xmp

from dualrgb.app.processing import tiff_stream
from dualrgb.app.processing.envi import IGNORE_VALUE, SCALE_FACTOR, open_cube, read_header
from dualrgb.app.processing.render import check_illuminant, rendering
from dualrgb.app.processing.spectral_cube import SpectralEncoder, encode_spectral
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver
from dualrgb.common.atomic_files import FileWriteError
from dualrgb.simulation.grid import DEFAULT_GRID
from dualrgb.simulation.other_lights import OTHER_LIGHTS, light_keys
from dualrgb.simulation.spectral_estimation import SpectralEstimator

WL = DEFAULT_GRID.wavelengths


def test_the_banded_cube_is_the_estimator_per_pixel():
    """Against SpectralEstimator.apply (float64), in bands of 5 rows over 2 threads: the stored integer is the
    factor x 10000 rounded (within 1: float32 against float64 at a half), the ignore value where a channel is NaN."""
    est, s = estimator(), stack()
    ref = est.apply(s.data.astype(np.float64))
    with SpectralEncoder(s.data, est.matrix, est.bounds, threads=2) as enc:
        cube = np.empty((23, len(WL), 31), np.uint16)
        for r0 in range(0, 23, 5):
            enc.encode(r0, cube[r0:r0 + 5])
    got = np.moveaxis(cube, 1, -1).astype(float)
    ok = ~np.isnan(s.data).any(-1)
    assert np.abs(got[ok] - np.round(ref[ok] * SCALE_FACTOR)).max() <= 1
    assert (got[~ok] == IGNORE_VALUE).all() and enc.invalid == 1
    assert got[ok].max() == SCALE_FACTOR and got[ok].min() == 0          # the clip to [0, 1] is exercised


def test_the_cube_carries_an_affine_estimators_offset():
    """An affine estimator (film: simulation.spectral_estimation's offset): the kernel adds the offset before the
    clip, as SpectralEstimator.apply does, in the cube and in the rendering; a wrong-sized offset is refused."""
    base = estimator()
    offset = np.linspace(-0.3, 0.4, len(WL))
    est = SpectralEstimator(base.matrix, base.wavelengths, base.channels, "pinv", {"offset": True}, offset=offset)
    s = stack(9, 13)
    ref = est.apply(s.data.astype(np.float64))
    assert not np.allclose(ref, base.apply(s.data.astype(np.float64)), atol=0.05, equal_nan=True)
    cube, rgb = encode_spectral(s.data, est.matrix, est.bounds, rendering("A", WL), offset=est.offset)
    _, rgb_linear = encode_spectral(s.data, base.matrix, base.bounds, rendering("A", WL))
    got = np.moveaxis(cube, 1, -1).astype(float)
    ok = ~np.isnan(s.data).any(-1)
    assert np.abs(got[ok] - np.round(ref[ok] * SCALE_FACTOR)).max() <= 1
    assert rgb is not None and rgb_linear is not None and np.abs(rgb.astype(int) - rgb_linear).max() > 1000
    with pytest.raises(ValueError, match="spectral offset"):
        SpectralEncoder(s.data, est.matrix, est.bounds, offset=offset[:-1])


@pytest.mark.parametrize("light", list(OTHER_LIGHTS))
def test_rendering_is_colour_sciences(light):
    """XYZ by colour.sd_to_XYZ (integration on the 10 nm grid), adapted (Bradford) from the light's white to
    ProPhoto's D50 and encoded by colour-science: the kernel's 16-bit values within 12 of 65535 (float32, the white
    normalised to exactly 1, as the other RGB deliverables: tests/app/test_workflow.py)."""
    import colour

    est, s = estimator(), stack(12, 9)
    key = light_keys_by_name()[light]
    r = rendering(key, WL)
    _, rgb = encode_spectral(s.data, est.matrix, est.bounds, r)
    spectra = est.apply(s.data.astype(np.float64))
    shape = colour.SpectralShape(WL[0], WL[-1], 10)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    kind, name = OTHER_LIGHTS[light]
    with colour.utilities.suppress_warnings(colour_runtime_warnings=True):
        sd_light = (colour.SDS_ILLUMINANTS if kind == "illuminant" else colour.SDS_LIGHT_SOURCES)[name].copy()
        sd_light = sd_light.align(shape)
    white = colour.sd_to_XYZ(colour.sd_ones(shape), cmfs, sd_light, method="Integration")
    prophoto = colour.RGB_COLOURSPACES["ProPhoto RGB"]
    ok = ~np.isnan(s.data).any(-1)
    for (i, j) in zip(*np.nonzero(ok), strict=True):
        sd = colour.SpectralDistribution(dict(zip(WL, spectra[i, j], strict=True)))
        xyz = colour.sd_to_XYZ(sd, cmfs, sd_light, method="Integration")
        ref = colour.XYZ_to_RGB(xyz / white[1], prophoto, illuminant=colour.XYZ_to_xy(white / white[1]),
                                chromatic_adaptation_transform="Bradford", apply_cctf_encoding=False)
        ref16 = np.clip(prophoto.cctf_encoding(np.clip(ref, 0, 1)), 0, 1) * 65535
        assert np.abs(rgb[i, j].astype(float) - ref16).max() <= 12, (light, i, j)
    assert (rgb[4, 7] == 0).all()


def light_keys_by_name() -> dict[str, str]:
    return {v: k for k, v in light_keys().items()}


def test_illuminant_names_are_checked_in_one_line():
    assert check_illuminant("a") == "A" and check_illuminant("LED 2880 K") == "LED"
    assert check_illuminant("fl11") == "FL11"
    with pytest.raises(ValueError) as info:
        check_illuminant("F2")
    assert "'F2'" in str(info.value) and "D65" in str(info.value) and "\n" not in str(info.value)


def test_spectral_python_opens_the_delivered_cube(tmp_path):
    """The cube as delivered (ENVI, BIL, uint16, little-endian, scale 10000): Spectral Python reads its shape,
    wavelengths and scale; its values are the estimator's; the header names the original and the calibration."""
    spy = pytest.importorskip("spectral")
    prof, s = spectral_profile(tmp_path), stack()
    d = deliver(s, prof, Original("ACC-7", title="Öl auf Holz"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord(1.0, 0.1), render_illuminant="A")
    img = spy.envi.open(str(d.files["spectral_header"]), str(d.files["spectral"]))
    assert img.shape == (23, 31, len(WL)) and np.allclose(img.bands.centers, WL)
    assert img.metadata["wavelength units"] == "Nanometers" and img.metadata["interleave"] == "bil"
    assert img.metadata["byte order"] == "0" and img.metadata["data type"] == "12"
    assert img.scale_factor == SCALE_FACTOR and img.metadata["header offset"] == "0"
    loaded = np.asarray(img.load(), dtype=float)                           # divided by the scale factor
    ref = prof.estimator.apply(s.data.astype(np.float64))
    ok = ~np.isnan(s.data).any(-1)
    assert np.abs(loaded[ok] - ref[ok]).max() <= 1.01 / SCALE_FACTOR
    assert np.allclose(img.read_pixel(4, 7), IGNORE_VALUE / SCALE_FACTOR)   # the ignore value, scaled too
    desc = img.metadata["description"]
    assert "ACC-7" in desc and "Ol auf Holz" in desc and "cal-test" in desc
    mine = open_cube(d.files["spectral_header"])                            # the app's own reader (GUI)
    assert np.allclose(mine.pixel(2, 3), ref[2, 3], atol=1e-4) and np.isnan(mine.pixel(4, 7)).all()


def test_rendering_and_sidecar(tmp_path):
    """The rendering under A: a ProPhoto TIFF with the ICC profile and the same tags and XMP as the other TIFFs;
    the sidecar names the cube's files, format, wavelengths, scale, method and calibration."""
    prof, s = spectral_profile(tmp_path), stack()
    d = deliver(s, prof, Original("ACC-8", operator="J. Doe"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord(36.0, 0.5), render_illuminant="A")
    render = d.files["render"]
    assert render.name == "ACC-8_under_A_prophoto_16bit.tif"
    with tifffile.TiffFile(render) as t:
        page = t.pages[0]
        assert page.dtype == np.uint16 and page.shape == (23, 31, 3) and 34675 in page.tags
        assert page.tags["XResolution"].value == (300, 1) and page.tags["Software"].value.startswith("dualrgb ")
        assert page.tags["ImageDescription"].value.startswith("ACC-8; rendered under A")
    xmp = read_xmp(render)
    assert xmp.identifier == "ACC-8" and xmp.dualrgb["Operator"] == "J. Doe"
    assert xmp.dualrgb["CalibrationID"] == "cal-test"
    assert "rendered under A" in xmp.dualrgb["Content"]
    side = assert_valid_sidecar(d.sidecar)                 # the sidecar's JSON Schema (resources/schemas)
    sp = side["spectral"]
    assert sp["cube"]["data"] == "ACC-8_spectral.img" and sp["cube"]["header"] == "ACC-8_spectral.hdr"
    assert sp["cube"]["delivery"] == "file" and side["resolution"]["mode"] == "half"
    assert sp["cube"]["wavelengths_nm"] == [float(w) for w in WL] and sp["cube"]["reflectance_scale_factor"] == 10000
    assert sp["estimator"]["method"] == "wiener" and sp["estimator"]["calibration"] == "cal-test"
    assert sp["estimator"]["calibration_test"]["rmse_mean"] == 0.042
    assert sp["rendering"]["illuminant"] == "A" and sp["rendering"]["space"] == "ProPhoto RGB"
    assert set(side["files"]) == {"prophoto", "srgb", "xyz", "channels_1", "spectral",
                                  "spectral_header", "render"}
    assert set(side["fixity"]["files"]) == {p.name for p in d.files.values()}
    assert "spectral RMSE test 0.042" in d.qa.text() and d.qa.to_dict()["calibration_test_spectral_rmse"] == 0.042
    assert read_header(d.files["spectral_header"])["dualrgb calibration"] == "cal-test"


def test_a_profile_without_an_estimator_delivers_colour_and_says_so(tmp_path):
    prof = make_profile(tmp_path)
    d = deliver(stack(), prof, Original("ACC-9"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord())
    assert "spectral" not in d.files and "no spectral cube" in d.qa.text()
    assert "spectral" not in json.loads(d.sidecar.read_text())


def test_redelivery_keeps_the_previous_cube(tmp_path):
    """The cube and rendering are deliverables like the TIFFs: a re-delivery moves the whole previous set, cube
    included, to previous/ (app.workflow.delivery.delivery_folder)."""
    prof = spectral_profile(tmp_path)
    first = deliver(stack(), prof, Original("ACC-1"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord())
    old = first.files["spectral"].read_bytes()
    deliver(stack(seed=6), prof, Original("ACC-1"), tmp_path / "out", camera=prof.camera, dose=LightDoseRecord(),
            render_illuminant="FL11")
    kept = list((tmp_path / "out" / "ACC-1" / "previous").glob("*/ACC-1_spectral.img"))
    assert len(kept) == 1 and kept[0].read_bytes() == old
    assert first.files["spectral"].read_bytes() != old
    assert (tmp_path / "out" / "ACC-1" / "ACC-1_under_FL11_prophoto_16bit.tif").exists()


@pytest.mark.fault("session integrity")
def test_a_disk_full_while_the_cube_is_written_leaves_no_delivery(tmp_path, monkeypatch):
    """ENOSPC on a write of the cube's bands (after the TIFFs' first bands are out): one line naming a file, no
    deliverables folder, no staging folder."""
    prof = spectral_profile(tmp_path)
    real = tiff_stream._Output.pwrite

    def pwrite(self, data, pos):
        if self.tmp.name.endswith(".img.tmp") or "_spectral.img" in self.tmp.name:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, data, pos)
    monkeypatch.setattr(tiff_stream._Output, "pwrite", pwrite)
    with pytest.raises(FileWriteError) as info:
        deliver(stack(300, 200), prof, Original("ACC-2"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord())
    assert "ACC-2_spectral.img" in str(info.value) and "\n" not in str(info.value)
    assert list((tmp_path / "out").iterdir()) == []


@pytest.mark.fault("input")
@pytest.mark.parametrize("command", ["capture", "process"])
def test_an_unknown_rendering_light_is_refused_before_anything_runs(command, tmp_path):
    import subprocess
    import sys

    args = (["capture", "--calibration", __file__, "--session", str(tmp_path / "s"), "--id", "X-1", "--virtual-lab"]
            if command == "capture" else ["process", str(tmp_path)])
    r = subprocess.run([sys.executable, "-m", "dualrgb", *args, "--render-illuminant", "F2"], capture_output=True,
                       text=True, timeout=60)
    line = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 2 and "--render-illuminant" in line and "'F2'" in line and "LED (LED 2880 K)" in line
    assert not any(tmp_path.iterdir())
