"""Fixity, the cube made on demand and the BagIt bag (issue 31):

* a full-resolution delivery lists the size and SHA-256 of every file (hashlib over the files read back), its sidecar
  follows the JSON Schema; ``dualrgb verify`` passes it, and names a flipped byte, a missing file and a file the
  sidecar does not list, one line each, exit 1;
* ``dualrgb cube`` makes the cube the sidecar states: plain numpy, from the sidecar's map and the channel TIFFs
  read by tifffile, gives the same values to one code; the cube a half-resolution delivery writes from the same
  channels is the same to one code; Spectral Python opens it; ``--render`` tags the rendering as a delivery's;
* ``dualrgb bag`` makes a bag the bagit package validates, whose manifest holds the sidecars' digests; a damaged
  delivery is not bagged, the previous sets a re-delivery kept are left out.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np
import pytest
import tifffile
from sidecar_schema import assert_valid_sidecar
from spectral_profiles import spectral_profile, stack

from dualrgb.app.cli import main
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver
from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings


def full(s):
    """A stack delivered as a full-resolution one (the same channels; resolution decides the files)."""
    return replace(s, resolution="full")


@pytest.fixture
def delivered(tmp_path):
    prof = spectral_profile(tmp_path / "cal")
    d = deliver(full(stack()), prof, Original("ACC-1", title="Stillleben"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord(3.0, 0.2))
    return prof, d


def test_full_resolution_delivery_lists_every_files_size_and_sha256(delivered):
    _, d = delivered
    assert set(d.files) == {"prophoto", "srgb", "xyz", "channels_1"}           # spectral products: on demand
    doc = assert_valid_sidecar(d.sidecar)
    assert doc["resolution"]["mode"] == "full" and doc["spectral"]["cube"]["delivery"] == "on-demand"
    assert doc["spectral"]["rendering"]["delivery"] == "on-demand" and "file" not in doc["spectral"]["rendering"]
    fixity = doc["fixity"]
    assert fixity["algorithm"] == "sha256" and set(fixity["files"]) == {p.name for p in d.files.values()}
    for path in d.files.values():
        data = path.read_bytes()
        assert fixity["files"][path.name] == {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def test_verify_passes_a_delivery_and_names_each_problem(delivered, capsys):
    _, d = delivered
    folder = d.sidecar.parent
    assert main(["verify", str(folder)]) == 0
    assert "1 delivery, 4 files match their sidecars; all match" in capsys.readouterr().out
    xyz = d.files["xyz"]
    data = bytearray(xyz.read_bytes())
    data[len(data) // 2] ^= 0x01                                  # one bit of one pixel
    xyz.write_bytes(bytes(data))
    d.files["channels_1"].unlink()
    (folder / "notes.txt").write_text("left here by hand")
    assert main(["verify", str(folder.parent)]) == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 4 and lines[-1].endswith("2 files match their sidecars; 3 problems")
    assert any(str(xyz) in line and "differs from the sidecar's" in line for line in lines)
    assert any(line == f"{d.files['channels_1']}: missing" for line in lines)
    assert any(str(folder / "notes.txt") in line and "not listed" in line for line in lines)


def test_verify_reads_the_schema_and_refuses_a_delivery_without_fixity(delivered, tmp_path, capsys):
    _, d = delivered
    doc = json.loads(d.sidecar.read_text())
    del doc["fixity"]
    doc["resolution"]["mode"] = "quarter"
    d.sidecar.write_text(json.dumps(doc))
    assert main(["verify", str(d.sidecar), "--json", str(tmp_path / "v.json")]) == 1
    out = capsys.readouterr().out
    assert "resolution/mode: 'quarter' is not one of ['full', 'half']" in out
    assert "no sha256 fixity recorded" in out
    report = json.loads((tmp_path / "v.json").read_text())
    assert report["format"] == "dualrgb-verify/1" and not report["ok"] and len(report["problems"]) == 3
    assert main(["verify", str(tmp_path / "nothing-here")]) == 1


def numpy_cube(doc: dict, folder) -> np.ndarray:
    """The cube as the sidecar documents it, with numpy and tifffile only: (lines, bands, samples) uint16."""
    m = doc["spectral"]["map"]
    codes = np.concatenate([tifffile.imread(folder / name) for name in m["channel_files"]], axis=-1)
    c = codes.astype(np.float64) / m["channel_scale"]
    s = np.clip(np.asarray(m["offset"]) + c @ np.asarray(m["matrix"]).T, *m["bounds"])
    return np.moveaxis(np.round(s * m["cube_scale"]).astype(np.uint16), -1, 1)


def test_cube_on_demand_is_the_stated_map_to_one_code(delivered, tmp_path, capsys):
    spy = pytest.importorskip("spectral")
    prof, d = delivered
    folder = d.sidecar.parent
    doc = json.loads(d.sidecar.read_text())
    assert main(["cube", str(folder), "--render", "A"]) == 0
    made = folder / "ACC-1_spectral.img"
    img = spy.envi.open(str(folder / "ACC-1_spectral.hdr"), str(made))
    assert img.shape == (23, 31, 38) and np.allclose(img.bands.centers, doc["spectral"]["map"]["wavelengths_nm"])
    cube = np.fromfile(made, "<u2").reshape(23, 38, 31)
    assert np.abs(cube.astype(int) - numpy_cube(doc, folder)).max() <= 1
    half = deliver(stack(), prof, Original("ACC-1H"), tmp_path / "half", camera=prof.camera, dose=LightDoseRecord(),
                   settings=DeliverySettings(spectral=True))
    delivered_cube = np.fromfile(half.files["spectral"], "<u2").reshape(23, 38, 31)
    data = stack().data                  # where the 16-bit channels hold the float ones (not NaN, in [0, 2))
    valid = ((data >= 0) & (data < 65535 / 32768)).all(-1)
    assert np.abs(cube.astype(int) - delivered_cube)[valid[:, None, :].repeat(38, 1)].max() <= 1
    render = folder / "ACC-1_under_A_prophoto_16bit.tif"
    with tifffile.TiffFile(render) as t:
        assert t.pages[0].shape == (23, 31, 3) and 34675 in t.pages[0].tags
        assert t.pages[0].tags["ImageDescription"].value.startswith("ACC-1 - Stillleben; rendered under A")
    assert main(["verify", str(folder)]) == 0                    # the cube made on demand: in the fixity now
    assert "1 delivery, 7 files match their sidecars; all match" in capsys.readouterr().out
    side = assert_valid_sidecar(d.sidecar)
    for name in ("ACC-1_spectral.img", "ACC-1_spectral.hdr", "ACC-1_under_A_prophoto_16bit.tif"):
        data = (folder / name).read_bytes()
        assert side["fixity"]["files"][name] == {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    assert side["spectral"]["cube"]["made_on_demand"]["data"] == "ACC-1_spectral.img"
    with pytest.raises(SystemExit):
        main(["cube", str(folder), "--render", "candle"])
    assert main(["cube", str(half.sidecar.parent)]) == 1           # a delivered cube is not written over
    assert "its cube is a delivered file" in capsys.readouterr().err


def test_bag_of_a_days_deliveries(tmp_path, capsys):
    bagit = pytest.importorskip("bagit")
    prof = spectral_profile(tmp_path / "cal")
    out = tmp_path / "deliverables"
    for ident in ("ACC-1", "ACC-2"):
        deliver(full(stack()), prof, Original(ident), out, camera=prof.camera, dose=LightDoseRecord())
    deliver(full(stack(seed=9)), prof, Original("ACC-2"), out, camera=prof.camera, dose=LightDoseRecord())
    assert main(["bag", str(out), "--out", str(tmp_path / "bag"), "--organization", "Museum X", "--info",
                 "Contact-Name=J. Doe"]) == 0
    bag = bagit.Bag(str(tmp_path / "bag"))
    bag.validate()
    assert bag.info["Source-Organization"] == "Museum X" and bag.info["Contact-Name"] == "J. Doe"
    payload = sorted(bag.payload_files())
    assert len(payload) == 2 * 5 and not any("previous" in p for p in payload)    # 4 TIFFs + sidecar each
    for ident in ("ACC-1", "ACC-2"):
        doc = json.loads((out / ident / f"{ident}.json").read_text())
        for name, fix in doc["fixity"]["files"].items():
            assert bag.entries[f"data/{ident}/{name}"]["sha256"] == fix["sha256"]
    xyz = out / "ACC-1" / "ACC-1_XYZ_16bit.tif"
    data = bytearray(xyz.read_bytes())
    data[len(data) // 2] ^= 0x01                                   # a pixel's bit (the file ends with its EXIF)
    xyz.write_bytes(bytes(data))
    assert main(["bag", str(out), "--out", str(tmp_path / "bag2")]) == 1
    err = capsys.readouterr().err
    assert "not bagged" in err and "ACC-1_XYZ_16bit.tif" in err and not (tmp_path / "bag2").exists()
    assert main(["bag", str(out / "ACC-2"), "--out", str(tmp_path / "bag")]) == 1        # not an empty folder


@pytest.mark.fault("input")
def test_cube_refuses_a_tampered_channel_file_naming_it(delivered, capsys):
    """Issue 38: a changed byte in a channel TIFF: dualrgb cube exits 1 naming the file; nothing is made."""
    _, d = delivered
    folder = d.sidecar.parent
    ch = d.files["channels_1"]
    data = bytearray(ch.read_bytes())
    data[len(data) // 2] ^= 0x40
    ch.write_bytes(bytes(data))
    assert main(["cube", str(folder)]) == 1
    err = capsys.readouterr().err
    assert "not made" in err and str(ch) in err and "differs from the sidecar's" in err
    assert not (folder / "ACC-1_spectral.img").exists()


@pytest.mark.fault("edited files")
@pytest.mark.parametrize("damage", ["map edited", "truncated"])
def test_cube_refuses_an_edited_or_damaged_sidecar_naming_it(delivered, capsys, damage):
    """Issue 38: the sidecar is checked against its schema before its map is used: an edited spectral section or a
    truncated sidecar gives one line naming the sidecar (not a crash), exit 1; nothing is made."""
    _, d = delivered
    folder = d.sidecar.parent
    if damage == "map edited":
        doc = json.loads(d.sidecar.read_text(encoding="utf-8"))
        doc["spectral"] = {"map": [[1]]}
        d.sidecar.write_text(json.dumps(doc), encoding="utf-8")
    else:
        d.sidecar.write_bytes(d.sidecar.read_bytes()[:40])
    assert main(["cube", str(d.sidecar)]) == 1
    err = capsys.readouterr().err
    assert f"not made: {d.sidecar}" in err and "a bug in dualrgb" not in err and len(err.strip().splitlines()) == 1
    assert not (folder / "ACC-1_spectral.img").exists()


@pytest.mark.fault("edited files")
@pytest.mark.parametrize("damage", ["deleted", "truncated"])
def test_a_delivery_whose_sidecar_is_gone_is_named_not_dropped(tmp_path, capsys, damage):
    """A deleted or damaged sidecar does not make its delivery drop out unsaid: verify names the folder (exit 1),
    bag refuses and leaves nothing, the session report lists it with the problem."""
    prof = spectral_profile(tmp_path / "cal")
    out = tmp_path / "deliverables"
    for ident in ("ACC-1", "ACC-2"):
        deliver(full(stack()), prof, Original(ident), out, camera=prof.camera, dose=LightDoseRecord())
    sidecar = out / "ACC-1" / "ACC-1.json"
    if damage == "deleted":
        sidecar.unlink()
    else:
        sidecar.write_text('{"format": ', encoding="utf-8")
    assert main(["verify", str(out)]) == 1
    said = capsys.readouterr().out
    assert f"{out / 'ACC-1'}: " in said and "no readable dualrgb sidecar" in said
    assert main(["bag", str(out), "--out", str(tmp_path / "bag")]) == 1
    err = capsys.readouterr().err
    assert "not bagged" in err and str(out / "ACC-1") in err and not (tmp_path / "bag").exists()
    assert main(["report", str(out), "--out", str(tmp_path / "qa.html")]) == 1
    assert "no readable dualrgb sidecar" in (tmp_path / "qa.html").read_text(encoding="utf-8")


def test_verify_names_debris_and_bag_leaves_it_out(delivered, tmp_path, capsys):
    """Issue 39: files GDAL, the Finder and Explorer leave beside a delivery are named as such, not problems; the
    bag leaves them out with a line."""
    _, d = delivered
    folder = d.sidecar.parent
    for name in ("ACC-1_XYZ_16bit.tif.aux.xml", ".DS_Store", "Thumbs.db"):
        (folder / name).write_text("left by another program")
    assert main(["verify", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "ACC-1_XYZ_16bit.tif.aux.xml: left by GDAL" in out and ".DS_Store: left by the macOS Finder" in out
    assert "Thumbs.db: left by Windows Explorer" in out and "all match" in out
    assert main(["bag", str(folder.parent), "--out", str(tmp_path / "bag")]) == 0
    assert capsys.readouterr().err.count("left out ") == 3
    assert not list((tmp_path / "bag").rglob("*.aux.xml")) and not list((tmp_path / "bag").rglob("Thumbs.db"))


def test_a_bag_is_its_own_copy_and_bagit_1_0(delivered, tmp_path, capsys):
    """Issue 39: an edit inside the bag leaves the session's delivery as it was (dualrgb verify passes); the bag
    says BagIt-Version 1.0, has tag manifests, and bag-info takes the delivery settings' fields."""
    bagit = pytest.importorskip("bagit")
    _, d = delivered
    settings = tmp_path / "delivery.toml"
    settings.write_text('[bag-info]\nSource-Organization = "Museum Y"\nContact-Email = "imaging@example.org"\n')
    assert main(["bag", str(d.sidecar.parent.parent), "--out", str(tmp_path / "bag"),
                 "--delivery-settings", str(settings)]) == 0
    assert "BagIt 1.0 bag of 1 original" in capsys.readouterr().out
    root = tmp_path / "bag"
    assert (root / "bagit.txt").read_text().startswith("BagIt-Version: 1.0\n")
    assert (root / "tagmanifest-sha256.txt").is_file() and (root / "manifest-sha256.txt").is_file()
    bag = bagit.Bag(str(root))
    bag.validate()
    assert bag.version_info == (1, 0) and bag.info["Source-Organization"] == "Museum Y"
    assert bag.info["Contact-Email"] == "imaging@example.org"
    inside = root / "data" / "ACC-1" / "ACC-1_XYZ_16bit.tif"
    assert inside.stat().st_ino != d.files["xyz"].stat().st_ino             # not a hard link
    with open(inside, "r+b") as fh:                                         # an edit inside the bag
        fh.seek(100)
        fh.write(b"rights metadata")
    assert main(["verify", str(d.sidecar.parent)]) == 0


@pytest.mark.fault("session integrity")
def test_a_full_disk_while_bagging_leaves_nothing_and_says_so(delivered, tmp_path, capsys, monkeypatch):
    """Issue 38: ENOSPC in the middle of the copies: exit 1, one line, no bag and no partial folder."""
    import errno

    from dualrgb.app.workflow.delivery import bagging

    _, d = delivered
    calls = {"n": 0}
    real = bagging.place

    def place(src, dst, link=False):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(dst))
        return real(src, dst, link)
    monkeypatch.setattr(bagging, "place", place)
    assert main(["bag", str(d.sidecar.parent.parent), "--out", str(tmp_path / "bag")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no space left on the device" in err[0] and "nothing was left" in err[0]
    assert not (tmp_path / "bag").exists() and [p.name for p in tmp_path.iterdir() if "partial" in p.name] == []
