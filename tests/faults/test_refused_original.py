"""What cannot be delivered is refused before the light goes on (issue 19): an original whose metadata do not
validate, or whose deliverables folder holds another original's files (or is a file), is refused in one line by
CopyStand.capture / capture_queue, and the sphere emulator's own record shows no lit period at all. Without the
preflight the same calls meter the original under the light first (the calibration is forced onto the stand)."""
from __future__ import annotations

import json

import pytest
from light_record import lit_spans
from workflow_profiles import make_profile

from dualrgb.app.session.capture_session import CaptureSession
from dualrgb.app.workflow.copystand import CopyStand, StandSettings
from dualrgb.app.workflow.delivery_folder import DeliveryFolderError
from dualrgb.app.workflow.metadata import MetadataError, Original
from dualrgb.app.workflow.queue_run import capture_queue


@pytest.fixture
def stand(lab, tmp_path):
    session = CaptureSession.create(tmp_path / "session", {"test": "refused originals"})

    def place(what: str, nd: bool = False):          # every original stands in as the virtual painting
        return lab.place("original:painting" if what.startswith("original:") else what, nd)
    stand = CopyStand(lab.camera, lab.sphere, session, stand=place,
                      settings=StandSettings(settle_s=0.0, force=True))        # the calibration is not checked
    yield stand, make_profile(tmp_path / "cal")
    session.close()


def _changed(original: Original, **fields) -> Original:
    for k, v in fields.items():
        object.__setattr__(original, k, v)        # past the constructor, as a buggy caller could
    return original


def _foreign_folder(stand: CopyStand) -> Original:
    original = Original("ACC-1")
    folder = stand.deliverables() / original.file_stem
    folder.mkdir(parents=True)
    (folder / "ACC-1.json").write_text(json.dumps({"format": "dualrgb-delivery/1",
                                                   "original": {"identifier": "ACC-1 (another)"}}))
    return original


def _file_in_the_way(stand: CopyStand) -> Original:
    stand.deliverables().mkdir(parents=True)
    (stand.deliverables() / "ACC-2").write_text("a file, not a folder")
    return Original("ACC-2")


CASES = {
    "title with U+0001": (lambda s: _changed(Original("ACC-5"), title="Öl\x01"), MetadataError,
                          "title: control character U+0001 at character 3"),
    "identifier with a line break": (lambda s: _changed(Original("ACC-5"), identifier="ACC\n5"), MetadataError,
                                     "identifier: line break U+000A at character 4"),
    "folder of another identifier": (_foreign_folder, DeliveryFolderError,
                                     "holds the deliverables of 'ACC-1 (another)'"),
    "a file where the folder goes": (_file_in_the_way, DeliveryFolderError, "is a file where 'ACC-2'"),
}


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("case", list(CASES))
def test_a_refused_original_never_lights_the_sphere(lab, stand, case):
    copy_stand, profile = stand
    make, error, says = CASES[case]
    since = lab.emulator.clock()
    with pytest.raises(error) as info:
        copy_stand.capture(make(copy_stand), profile)
    assert says in str(info.value) and "\n" not in str(info.value), str(info.value)
    assert lit_spans(lab.emulator, since) == [] and copy_stand.session.entries() == []


@pytest.mark.fault("light safety")
def test_one_bad_original_in_a_queue_stops_it_before_the_first_is_lit(lab, stand):
    copy_stand, profile = stand
    since = lab.emulator.clock()
    originals = [Original("ACC-7"), _changed(Original("ACC-8"), notes="\ufffe")]
    with pytest.raises(MetadataError, match="notes: noncharacter U\\+FFFE at character 1"):
        capture_queue(copy_stand, originals, profile)
    assert lit_spans(lab.emulator, since) == [] and copy_stand.session.entries() == []
