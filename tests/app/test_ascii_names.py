"""Identifiers kept whole in file names (issue 42): where the deliverables folder's file system refuses Unicode names
(an old Samba share, ISO 9660, FAT mounted with a legacy code page), delivery names the folder and files by the
documented reversible ASCII form (``xn--`` + Punycode), says so in one log line, and keeps the exact identifier in
the sidecar and the XMP.

No file system that refuses Unicode names can be mounted here without root (a vfat image needs ``mount``), so the
probe (core.metadata.unicode_names_work, called by app.workflow.delivery.delivery_folder) is monkeypatched to
answer as such a file system would; the probe itself is tested on this machine's file system in test_metadata.py.
"""
from __future__ import annotations

import logging

import numpy as np
import pytest
from workflow_profiles import make_profile
from xmp_check import read_xmp

from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.delivery import delivery_folder
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, deliver, read_sidecar
from dualrgb.app.workflow.delivery.fixity import VerifyReport, verify_sidecar
from dualrgb.core.metadata import Original, ascii_stem, file_stem, stem_of_ascii

IDENT = "東博-A-1"


@pytest.fixture
def ascii_only(monkeypatch):
    """The deliverables folders' file system refuses Unicode names; returns the folders probed, one per call."""
    probed = []

    def probe(folder):
        probed.append(folder)
        return False

    monkeypatch.setattr(delivery_folder, "unicode_names_work", probe)
    monkeypatch.setattr(delivery_folder, "_UNICODE_NAMES", {})
    return probed


def run(prof, original, out):
    stack = ChannelStack(np.full((6, 8, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
    return deliver(stack, prof, original, out, camera=prof.camera, dose=LightDoseRecord(36.0, 0.5))


def test_where_unicode_names_are_refused_the_ascii_form_names_the_files(tmp_path, ascii_only, caplog):
    prof = make_profile(tmp_path / "cal")
    out = tmp_path / "out"
    caplog.set_level(logging.INFO)
    d = run(prof, Original(IDENT, title="富嶽三十六景"), out)
    name = d.sidecar.parent.name
    assert name == ascii_stem(file_stem(IDENT)) and name.startswith("xn--") and name.isascii()
    assert stem_of_ascii(name) == IDENT                                           # decodes back to the identifier
    assert [p.name for p in out.iterdir()] == [name] and d.sidecar.name == f"{name}.json"
    assert all(p.name.isascii() and p.name.startswith(f"{name}_") for p in d.files.values())
    side = read_sidecar(d.sidecar)
    assert side["original"]["identifier"] == IDENT and side["file_stem"] == name
    assert read_xmp(d.files["srgb"]).identifier == IDENT                          # the exact identifier kept
    report = VerifyReport()
    verify_sidecar(d.sidecar, report)                                             # the sidecar names its files
    assert not report.problems, report.problems
    said = [r.getMessage() for r in caplog.records if "refuses Unicode file names" in r.getMessage()]
    assert len(said) == 1 and "xn--" in said[0] and str(out) in said[0]


def test_the_folder_is_probed_once_and_a_redelivery_finds_its_folder(tmp_path, ascii_only):
    prof = make_profile(tmp_path / "cal")
    out = tmp_path / "out"
    first = run(prof, Original(IDENT), out)
    again = run(prof, Original(IDENT), out)                          # the same original again: previous kept
    assert again.sidecar == first.sidecar
    assert len(delivery_folder.previous_sets(out, Original(IDENT))) == 1
    plain = run(prof, Original("ACC-1"), out)                        # an ASCII identifier: its own name
    assert plain.sidecar.parent.name == "ACC-1"
    assert len(ascii_only) == 1                                      # one probe for the folder


def test_where_unicode_names_work_they_are_kept(tmp_path, monkeypatch):
    monkeypatch.setattr(delivery_folder, "_UNICODE_NAMES", {})
    prof = make_profile(tmp_path / "cal")
    d = run(prof, Original(IDENT), tmp_path / "out")
    assert d.sidecar.parent.name == IDENT and read_sidecar(d.sidecar)["file_stem"] == IDENT
