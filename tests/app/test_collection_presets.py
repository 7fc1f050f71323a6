"""Metadata presets per collection (issue 42): a preset file written and read back, a bad file refused in one line
naming the file and the field, an original added under a collection delivering the preset's creator, rights, credit
line and source in its XMP (read back with expat and exiftool) and TIFF Copyright, the original's own values
winning, and a queue CSV's ``collection`` column picking the same preset by the same function."""
from __future__ import annotations

import json
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
import tifffile
from workflow_profiles import make_profile
from xmp_check import EXIFTOOL, NO_EXIFTOOL, exiftool_text, read_xmp, xmp_bytes

from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.day.collection_presets import (
    CollectionPreset,
    PresetError,
    apply_preset,
    collection_names,
    default_folder,
    find_preset,
    load_preset,
    save_preset,
    with_collection,
)
from dualrgb.app.workflow.day.queue_csv import read_queue_csv
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, deliver, read_sidecar
from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings
from dualrgb.core.metadata import Credits, Original

DC, PS = "http://purl.org/dc/elements/1.1/", "http://ns.adobe.com/photoshop/1.0/"
RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
GEM = CollectionPreset("GEM", Credits(("Example Museum, Imaging Studio", "J. Doe"), "CC BY 4.0, Example Museum",
                                      "Gemäldegalerie, Example Museum", "Example Museum"),
                       {"collection": "Gemäldegalerie", "department": "Paintings"}, "GEM-{date}-{counter:04}")


def write(folder: Path, name: str, doc: object) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.json"
    path.write_text(json.dumps(doc, ensure_ascii=False) if not isinstance(doc, str) else doc, encoding="utf-8")
    return path


def test_a_preset_round_trips(tmp_path):
    path = save_preset(GEM)
    assert path == default_folder() / "GEM.json" and path.parent == Path(str(default_folder()))
    assert json.loads(path.read_text(encoding="utf-8"))["format"] == "dualrgb-collection/1"
    back = load_preset(path)
    assert (back.name, back.credits, dict(back.extra), back.identifier_template) == \
        (GEM.name, GEM.credits, dict(GEM.extra), GEM.identifier_template)
    assert find_preset("gem") == back and collection_names() == ["GEM"]        # matched ignoring case
    assert find_preset("OTHER") is None and find_preset("") is None and find_preset("a/b") is None


BAD = [
    ({"format": "dualrgb-collection/1", "rights": 5}, "rights: 5 is not of type 'string'"),
    ({"format": "dualrgb-collection/1", "colour": "x"}, "colour: unknown field"),
    ({"rights": "x"}, "the file: 'format' is a required property"),
    ({"format": "dualrgb-collection/1", "extra": {"department": 3}}, "extra.department: 3 is not of type"),
    ({"format": "dualrgb-collection/1", "rights": "CC BY\x01"}, "rights: control character U+0001 at character 6"),
    ({"format": "dualrgb-collection/1", "creator": ["A", "B\x0b\x00"]}, "creator: control character U+0000"),
    ({"format": "dualrgb-collection/1", "identifier_template": "{room}-{counter}"}, r"unknown token {room}"),
    ("{not json", "not a readable JSON file"),
]


@pytest.mark.parametrize("doc, says", BAD, ids=[s.split(":")[0] for _, s in BAD])
def test_a_bad_preset_is_refused_in_one_line_naming_the_file_and_field(doc, says):
    path = write(default_folder(), "GEM", doc)
    with pytest.raises(PresetError) as caught:
        find_preset("GEM")
    text = str(caught.value)
    assert text.startswith(f"{path}: ") and says in text and "\n" not in text, text


def test_the_originals_own_values_win():
    own = Original("ACC-1", extra={"department": "Prints", "box": "7"}, credits=Credits(rights="Public domain"))
    under = apply_preset(own, GEM)
    assert under.extra == {"collection": "Gemäldegalerie", "department": "Prints", "box": "7"}
    assert under.credits == Credits(GEM.credits.creator, "Public domain", GEM.credits.credit, GEM.credits.source)
    assert under.collection == "GEM" and Original.from_dict(under.to_dict()) == under      # sidecar / session
    assert with_collection(own, "NONE") == own                         # a collection without a preset: as it is


def stack(h: int = 6, w: int = 8) -> ChannelStack:
    return ChannelStack(np.full((h, w, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})


def dc_values(path: Path) -> dict[str, list[str]]:
    desc = ET.fromstring(xmp_bytes(path)).find(f".//{{{RDF}}}Description")
    assert desc is not None
    out = {}
    for tag, ns in (("creator", DC), ("rights", DC), ("Credit", PS), ("Source", PS)):
        elem = desc.find(f"{{{ns}}}{tag}")
        out[tag] = [] if elem is None else [t.strip() for t in elem.itertext() if t.strip()]
    return out


def test_an_original_added_under_a_collection_delivers_its_credits(tmp_path):
    save_preset(GEM)
    prof = make_profile(tmp_path / "cal")
    settings = DeliverySettings(creator=("Settings Studio",), rights="settings rights")
    original = with_collection(Original("東博-A-1", title="富嶽三十六景", extra={"department": "Prints"}), "GEM")
    d = deliver(stack(), prof, original, tmp_path / "out", camera=prof.camera, dose=LightDoseRecord(36.0, 0.5),
                settings=settings)
    for path in d.files.values():
        if path.suffix != ".tif":
            continue
        assert dc_values(path) == {"creator": list(GEM.credits.creator), "rights": [GEM.credits.rights],
                                   "Credit": [GEM.credits.credit], "Source": [GEM.credits.source]}, path.name
        assert read_xmp(path).extra == {"collection": "Gemäldegalerie", "department": "Prints"}   # the row's wins
        with tifffile.TiffFile(path) as t:
            assert t.pages[0].tags[33432].value == GEM.credits.rights                           # TIFF Copyright
    side = read_sidecar(d.sidecar)["original"]
    assert side["collection"] == "GEM" and side["credits"]["rights"] == GEM.credits.rights
    plain = deliver(stack(), prof, Original("ACC-2"), tmp_path / "out", camera=prof.camera,
                    dose=LightDoseRecord(36.0, 0.5), settings=settings)
    assert dc_values(plain.files["srgb"])["rights"] == ["settings rights"]                 # no preset: the settings'


@pytest.mark.skipif(EXIFTOOL is None, reason=NO_EXIFTOOL)
def test_exiftool_reads_the_presets_credits(tmp_path):
    save_preset(GEM)
    prof = make_profile(tmp_path / "cal")
    d = deliver(stack(), prof, with_collection(Original("ACC-1"), "GEM"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord(36.0, 0.5))
    path = d.files["srgb"]
    assert exiftool_text(path, "XMP-dc:Rights") == GEM.credits.rights
    assert exiftool_text(path, "XMP-photoshop:Credit") == GEM.credits.credit
    assert exiftool_text(path, "XMP-photoshop:Source") == GEM.credits.source
    assert GEM.credits.creator[0] in exiftool_text(path, "XMP-dc:Creator")


def test_a_queue_csvs_collection_column_picks_the_same_preset(tmp_path):
    save_preset(GEM)
    write(default_folder(), "FILM", {"format": "dualrgb-collection/1", "rights": "film rights"})
    csv = tmp_path / "q.csv"
    csv.write_text("identifier,collection,department\nACC-1,GEM,Prints\nACC-2,,\nACC-3,film,\nACC-4,NONE,\n",
                   encoding="utf-8")
    got = {o.identifier: o for o in read_queue_csv(csv, collection="GEM").originals}
    assert got["ACC-1"] == with_collection(Original("ACC-1", extra={"collection": "GEM", "department": "Prints"}),
                                           "GEM")
    assert got["ACC-1"].extra["department"] == "Prints" and got["ACC-1"].extra["collection"] == "GEM"    # row's
    assert got["ACC-2"].collection == "GEM" and got["ACC-2"].extra["department"] == "Paintings"   # the default
    assert got["ACC-3"].collection == "FILM" and got["ACC-3"].credits.rights == "film rights"
    assert got["ACC-4"].collection == "" and not got["ACC-4"].credits                # no preset: nothing added
    write(default_folder(), "FILM", {"format": "dualrgb-collection/1", "rights": ["x"]})
    with pytest.raises(ValueError, match=r"^.*q\.csv: collection 'film': .*FILM\.json: rights: \['x'\] is not"):
        read_queue_csv(csv)


def test_the_docs_example_preset_is_a_valid_preset():
    """docs/gui.md's example file, as written, is read as the preset it describes."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "gui.md").read_text(encoding="utf-8")
    block = text.split("<!-- collection-preset-example -->\n```json\n", 1)[1].split("```", 1)[0]
    preset = load_preset(write(default_folder(), "GEM", block))
    assert (preset.credits.rights, preset.credits.credit, dict(preset.extra), preset.identifier_template) == \
        ("CC BY 4.0, Example Museum", "Gemäldegalerie, Example Museum",
         {"collection": "Gemäldegalerie", "department": "Paintings"}, "GEM-{date}-{counter:04}")


def test_make_preset_checks_as_a_file_is_read_and_save_writes_nothing_bad():
    """The editor's and the CLI's preset (make_preset) is the one a file with those fields reads as; a bad field
    is a PresetError naming it (its .field for the window's focus and the CLI's option); save_preset checks before
    it writes."""
    from dualrgb.app.workflow.day.collection_presets import make_preset

    made = make_preset("GEM", creator=list(GEM.credits.creator), rights=GEM.credits.rights, credit=GEM.credits.credit,
                       source=GEM.credits.source, extra=list(GEM.extra.items()) + [("empty", "")],
                       identifier_template=GEM.identifier_template)
    assert made == GEM
    for kw, field, says in ((dict(rights="CC\x01"), "rights", "rights: control character U+0001"),
                            (dict(creator=["A", "B\x00"]), "creator", "creator: control character U+0000"),
                            (dict(extra=[("a", "1"), ("a", "2")]), "extra", "extra.a: named twice"),
                            (dict(extra=[("", "x")]), "extra", "extra: field name: empty"),
                            (dict(extra=[("box", "\x02")]), "extra", "extra.box: control character U+0002"),
                            (dict(identifier_template="{room}"), "identifier_template", "identifier template: "
                                                                                        "unknown token {room}")):
        with pytest.raises(PresetError) as caught:
            make_preset("GEM", **kw)
        assert caught.value.field == field and str(caught.value).startswith(says), str(caught.value)
    with pytest.raises(PresetError) as caught:
        make_preset("a/b")
    assert caught.value.field == "name"
    with pytest.raises(PresetError, match=r"^identifier template: unknown token \{room\}"):
        save_preset(CollectionPreset("GEM", identifier_template="{room}"))
    assert not default_folder().exists()                                    # nothing written
