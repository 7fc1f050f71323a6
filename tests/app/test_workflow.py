"""The workflow layer without devices: vocabulary (and old sessions' strings), calibration profile and its reuse
checks, the delivery encoding (checked against colour-science) and TIFF metadata, coverage."""
from __future__ import annotations

import hashlib
from datetime import UTC, datetime, timedelta
from types import SimpleNamespace

import numpy as np
import pytest
import tifffile
from sidecar_schema import assert_valid_sidecar
from workflow_profiles import make_profile as _profile
from xmp_check import read_xmp

from dualrgb.app.processing.encode import LINEAR_ONE, encode_deliverables
from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.calibration.coverage import coverage
from dualrgb.app.workflow.calibration.profile import (
    CameraIdentity,
    ProfileError,
    ReuseLimits,
    SphereIdentity,
    check_reuse,
    load_profile,
)
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver, read_sidecar
from dualrgb.core.vocabulary import (
    NamedLight,
    Role,
    Subject,
    latest_takes,
    light_name,
    light_of,
    read_light_name,
    read_role,
    step_id,
    subject_of,
)
from dualrgb.simulation.lightsource import LightSource

D65 = [95.047, 100.0, 108.883]


def entry(seq, role, step=None, **meta):
    return SimpleNamespace(seq=seq, role=role, step_id=step, meta=meta, light_name=meta.pop("light", ""), file=f"{seq}")


def test_vocabulary_one_form_each():
    s = Subject.target("test", nd=True)
    assert s.key == "target:test+nd" and Subject.parse(s.key) == s and s.role is Role.TARGET
    assert Subject.parse("original:ACC 7").place == "original:ACC 7"
    assert light_name("dual-RGB reflective", 2) == "dual-RGB reflective light 2"
    assert step_id(Role.DARK, exposure_s=1 / 60, frame=3) == "dark/0.0166667/3"        # the format sessions hold
    assert step_id(Role.FLAT, light="L light 1", exposure_s=0.5, frame=0) == "flat/L light 1/0.5/0"
    assert step_id(Role.ORIGINAL, subject=Subject.original("A1"), light="x", exposure_s=2, take=2) == \
        "original/original:A1/x/2#take2"
    with pytest.raises(ValueError, match="needs a name"):
        Subject.original("  ")
    with pytest.raises(ValueError, match="expected one of train, test"):
        Subject.target("side")


def test_old_session_strings_are_read():
    assert read_role("hdr-nd") == (Role.TARGET, True) and read_role("object") == (Role.ORIGINAL, False)
    assert read_role("hdr-meter")[0] is Role.METERING
    assert read_light_name("dual-RGB-reflective-LS1") == "dual-RGB-reflective light 1"
    assert read_light_name("dual_rgb_pso-LS2") == "dual_rgb_pso light 2"
    old = entry(1, "hdr-nd", "hdr/hdr/test/nd/p-LS1/0.1", target="test", nd=True, light_name="p-LS1")
    assert subject_of(old) == Subject.target("test", nd=True) and light_of(old) == "p light 1"
    assert subject_of(entry(2, "object", subject="folio 3")) == Subject.original("folio 3")
    with pytest.raises(ValueError, match="role 'smear'"):
        read_role("smear")


def test_latest_take_wins():
    es = [entry(1, "original", "original/original:A/x/1"), entry(2, "original", "original/original:A/x/1#take2"),
          entry(3, "original", "original/original:A/y/1")]
    assert [e.seq for e in latest_takes(es)] == [2, 3]


def test_profile_round_trip_and_damage(tmp_path):
    prof = _profile(tmp_path)
    back = load_profile(tmp_path / "cal-test.json")
    assert back.to_dict() == prof.to_dict() and back.to_dict()["software"]["dualrgb"]
    assert np.array_equal(back.darks.get(0.01), prof.darks.get(0.01))
    assert back.whites["P light 1"].threshold == prof.whites["P light 1"].threshold
    npz = tmp_path / "cal-test.npz"
    npz.write_bytes(npz.read_bytes()[:-10] + b"0123456789")
    with pytest.raises(ProfileError, match="damaged"):
        load_profile(tmp_path / "cal-test.json")
    (tmp_path / "x.json").write_text('{"format": "something else"}')
    with pytest.raises(ProfileError, match="not a dualrgb calibration"):
        load_profile(tmp_path / "x.json")


@pytest.mark.parametrize("change, words", [
    ({"serial": "3099999"}, "camera serial 3099999 differs from the calibration's 3012345"),
    ({"iso": 100}, "ISO 100 differs from the calibration's 50"),
    ({"aperture": 11.0}, "aperture f/11.0 differs"),
])
def test_reuse_refuses_a_different_camera(tmp_path, change, words):
    prof = _profile(tmp_path)
    cam = CameraIdentity(**{**vars(prof.camera), **change})
    check = check_reuse(prof, cam, prof.sphere, prof.lights)
    assert not check.ok and check.refusals == [pytest.approx(check.refusals[0])] and words in check.message()


def test_reuse_refuses_other_levels_and_a_warm_sphere_and_warns_when_old(tmp_path):
    prof = _profile(tmp_path, created=datetime.now(UTC) - timedelta(hours=9))
    other = [NamedLight("P light 1", LightSource((1, 6, 7), (0.0, 0.5, 1.0)))]
    warm = SphereIdentity("S", "1", "S-1", 31.0)
    check = check_reuse(prof, prof.camera, warm, other, ReuseLimits(temperature_drift_c=5.0))
    assert len(check.refusals) == 2
    assert "sphere temperature 31.0 C is +6.0 C" in check.refusals[0] and "levels" in check.refusals[1]
    assert check.warnings and "9.0 h old" in check.warnings[0]
    assert check_reuse(prof, prof.camera, SphereIdentity("S", "1", "S-1", 29.0), prof.lights).ok


def test_encoding_matches_colour_science():
    import colour

    rng = np.random.default_rng(3)
    stack = rng.uniform(0, 1.1, (6, 7, 6)).astype(np.float32)
    stack[0, 0, 2] = np.nan
    A = rng.uniform(0, 25, (6, 3))
    enc = encode_deliverables(stack, A, D65)
    xyz = np.nan_to_num(stack).astype(np.float64) @ A
    for space in ("sRGB", "ProPhoto RGB"):
        ref = colour.XYZ_to_RGB(xyz / 100.0, space, illuminant=colour.XYZ_to_xy(np.array(D65) / 100),
                                chromatic_adaptation_transform="Bradford", apply_cctf_encoding=True)
        ref16 = np.round(np.clip(ref, 0, 1) * 65535)
        # within 10 of 65535 (0.015 %): float32, and the white normalised to exactly 1 (outputs.xyz_to_rgb_matrix;
        # the published matrices map it to 1 +- 1e-4)
        assert np.abs(enc.rgb[space].astype(float) - ref16).max() <= 10, space
    # the XYZ master: X / Xn, Y / Yn, Z / Zn with 65535 = 1 (app.processing.outputs.xyz_icc says why)
    assert np.abs(enc.xyz - np.clip(np.round(xyz / np.array(D65) * 65535), 0, 65535)).max() <= 1
    white = encode_deliverables(np.ones((1, 1, 3), np.float32), np.diag(D65), D65)
    assert (white.rgb["sRGB"] == 65535).all() and (white.rgb["ProPhoto RGB"] == 65535).all()
    assert (white.xyz[0, 0] == 65535).all() and white.channels[0, 0, 0] == LINEAR_ONE
    assert enc.invalid_fraction == pytest.approx(1 / 42)


def test_deliverables_carry_their_metadata(tmp_path):
    prof = _profile(tmp_path)
    stack = ChannelStack(np.full((10, 14, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
    original = Original("ACC 12/3", title="Portrait", operator="J. Doe", notes="frame A")
    d = deliver(stack, prof, original, tmp_path / "out", camera=prof.camera, dose=LightDoseRecord(36.0, 0.5))
    stem = "ACC_12_3_" + hashlib.sha256(b"ACC 12/3").hexdigest()[:8]      # not a faithful name: hashed
    assert d.sidecar == tmp_path / "out" / stem / f"{stem}.json"
    assert {p.name for p in d.files.values()} == {f"{stem}_prophoto_16bit.tif", f"{stem}_srgb_16bit.tif",
                                                  f"{stem}_XYZ_16bit.tif", f"{stem}_light1_cameraRGB_16bit.tif"}
    for key, path in d.files.items():
        with tifffile.TiffFile(path) as t:
            page = t.pages[0]
            assert page.dtype == np.uint16 and page.shape == (10, 14, 3)
            assert page.photometric == tifffile.PHOTOMETRIC.RGB and page.extrasamples == ()   # no alpha, not grey
            assert page.tags["XResolution"].value == (300, 1) and page.tags["ResolutionUnit"].value == 2
            assert page.tags["Software"].value.startswith("dualrgb ")
            assert page.tags["Make"].value == "Nikon" and page.tags["Model"].value == "D610"
            description = page.tags["ImageDescription"].value
            assert "ACC 12/3" in description
            assert 34675 in page.tags and 285 not in page.tags          # an ICC profile in every TIFF, no PageName
            assert page.tags["DocumentName"].value == "ACC 12/3 - Portrait"
        xmp = read_xmp(path)
        assert (xmp.identifier, xmp.title, xmp.dualrgb["Operator"]) == ("ACC 12/3", "Portrait", "J. Doe"), key
        assert xmp.description == description                 # dc:description: the exact text (ASCII here)
        assert xmp.dualrgb["CalibrationID"] == "cal-test" and xmp.dualrgb["LightDoseLuxHours"] == "0.01"
    assert read_xmp(d.files["channels_1"]).dualrgb["Content"].startswith("camera R1 G1 B1 under P light 1")
    side = read_sidecar(d.sidecar)
    assert assert_valid_sidecar(d.sidecar) == side                     # the sidecar's JSON Schema
    assert set(side["software"]) >= {"dualrgb", "numpy", "colour-science", "rawpy", "libraw"}
    assert side["light_dose"]["lux_h"] == pytest.approx(0.01) and "lux.h" in d.qa.text()


def test_coverage_counts_darks_and_flats():
    def e(seq, role, t, light=""):
        return SimpleNamespace(seq=seq, role=role, step_id=f"{role}/{light}/{t}/{seq}", meta={"light_name": light},
                               light_name=light, exposure_s=t, file=str(seq))
    session = SimpleNamespace(entries=lambda: [e(1, "dark", 0.01), e(2, "flat", 0.01, "L light 1"),
                                               e(3, "flat", 0.5, "L light 2")])
    cov = coverage(session, {"L light 1": [0.01, 0.5], "L light 2": [0.5]})
    assert cov.summary() == "darks 1/2 exposures, flats 2/3 light exposures"
    assert not cov.complete and "darks at 0.5 s" in cov.missing() and "flats of L light 1 at 0.5 s" in cov.missing()


def test_streamed_stack_equals_the_batch_stack():
    """StackBuilder (frames merged as they land, as CopyStand.capture does) = CaptureProcessor.stack."""
    from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef

    rng = np.random.default_rng(5)
    h, w = 16, 20
    scene = rng.uniform(0.05, 1.0, (h, w)).astype(np.float32)

    def frame(t, gain):
        return np.clip(600 + gain * scene * t + rng.normal(0, 2, (h, w)), 0, 15520).astype(np.uint16)

    darks = [ExposureRef(np.full((h, w), 600, np.uint16), t) for t in (0.01, 0.1) for _ in range(3)]
    refs = {"a": [ExposureRef(frame(t, 8e4), t) for t in (0.01, 0.1)],
            "b": [ExposureRef(frame(t, 5e4), t) for t in (0.01, 0.1)]}

    def processor():
        p = CaptureProcessor(dark_frames=darks, white_level=15520, black_level=600, cfa="RGGB")
        for name in refs:
            p.set_white(name, [ExposureRef(np.full((h, w), 9000, np.uint16), 0.01)])
        return p
    batch = processor().stack(refs)
    builder = processor().begin_stack(list(refs))
    for name, rs in refs.items():
        for r in rs:
            builder.add(name, r)
    streamed = builder.result()
    assert np.allclose(streamed.data, batch.data, equal_nan=True) and streamed.channels == batch.channels
    assert 0.0 <= streamed.underexposed_fraction <= 1.0
    with pytest.raises(ValueError, match="already flat-fielded"):
        builder.add("a", refs["a"][0])
