"""Real catalogue data (issue 19): every field of an original validated and normalised in one place, German, French
and Japanese text delivered exactly (XMP, sidecar) with TIFF's ASCII tags transliterated, control characters never
reaching an XMP packet, file names that never collide (also by case), re-delivery keeping the previous set, and
identifiers that cannot reach into the session's step ids."""
from __future__ import annotations

import hashlib
import json
import re
import unicodedata
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import tifffile
from workflow_profiles import make_profile
from xmp_check import EXIFTOOL, NO_EXIFTOOL, exiftool_text, read_xmp

from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, deliver, read_sidecar
from dualrgb.app.workflow.delivery.delivery_folder import PREVIOUS, DeliveryFolderError, previous_sets
from dualrgb.core.metadata import (
    MetadataError,
    Original,
    ascii_stem,
    ascii_text,
    file_stem,
    stem_of_ascii,
    unicode_names_work,
    xmp_property,
)
from dualrgb.core.vocabulary import Role, Subject, split_take, step_id

# (identifier, title, operator, notes, ImageDescription's ASCII rendering of "<identifier> - <title>")
WORLD = [
    ("ACC-5", "Öl auf Holz", "Jürgen Weiß", "Rückseite: Stempel „Galerie Müller“", "ACC-5 - Ol auf Holz"),
    ("INV-é/12", "Étude pour « La Grève »", "Hélène Lefèvre", "Œuvre sur toile\nvernis jauni",
     "INV-e/12 - Etude pour \" La Greve \""),
    ("東博-A-1", "富嶽三十六景 神奈川沖浪裏", "山田 花子", "葛飾北斎\n木版画", "??-A-1 - ?????? ??????"),
]


def stack(h: int = 6, w: int = 8) -> ChannelStack:
    return ChannelStack(np.full((h, w, 3), 0.5, np.float32), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})


@pytest.fixture
def prof(tmp_path):
    return make_profile(tmp_path / "cal")


def run(prof, original: Original, out: Path):
    return deliver(stack(), prof, original, out, camera=prof.camera, dose=LightDoseRecord(36.0, 0.5))


def digests(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# ---------------------------------------------------------------- Unicode delivered faithfully
@pytest.mark.parametrize("ident, title, operator, notes, described", WORLD, ids=["de", "fr", "ja"])
def test_world_text_delivers_and_reads_back_exactly(prof, tmp_path, ident, title, operator, notes, described):
    original = Original(ident, title, operator, notes, extra={"Standort": "Depot 3 – Regal 7"})
    d = run(prof, original, tmp_path / "out")
    for key, path in d.files.items():
        xmp = read_xmp(path)
        assert (xmp.identifier, xmp.title, xmp.dualrgb["Operator"], xmp.dualrgb["Notes"]) == \
            (ident, title, operator, notes), key
        assert xmp.extra == {"Standort": "Depot 3 – Regal 7"}
        with tifffile.TiffFile(path) as t:
            desc = t.pages[0].tags["ImageDescription"].value
        assert desc.startswith(described + "; ") and desc.isascii(), desc       # the stated transliteration
    side = read_sidecar(d.sidecar)
    assert side["original"] == {"identifier": ident, "title": title, "operator": operator, "notes": notes,
                                "mode": "reflective", "extra": {"Standort": "Depot 3 – Regal 7"}}
    raw = d.sidecar.read_bytes().decode("utf-8")
    assert title in raw and "\\u" not in raw                                       # UTF-8, not \\u escapes
    stem = file_stem(ident)                                                  # the identifier's letters kept (#42)
    assert d.sidecar.parent.name == stem and all(p.name.startswith(stem + "_") for p in d.files.values())
    assert unicodedata.normalize("NFC", stem) == stem and stem.split("_")[0] == ident.split("/")[0].split(" ")[0]


@pytest.mark.parametrize("ident, title, operator, notes, described", WORLD, ids=["de", "fr", "ja"])
def test_exiftool_reads_the_same_text(prof, tmp_path, ident, title, operator, notes, described):
    if EXIFTOOL is None:
        pytest.skip(NO_EXIFTOOL)
    d = run(prof, Original(ident, title, operator, notes), tmp_path / "out")
    path = d.files["srgb"]
    assert exiftool_text(path, "XMP-dc:Identifier") == ident
    assert exiftool_text(path, "XMP-dc:Title") == title
    assert exiftool_text(path, "XMP-dualrgb:Operator") == operator
    assert exiftool_text(path, "XMP-dualrgb:Notes") == notes
    assert exiftool_text(path, "IFD0:ImageDescription").startswith(described + "; ")


def test_ascii_rendering_policy():
    """Hand-written expectations: NFKD without marks, a few letters spelled out, typographic marks as ASCII."""
    assert ascii_text("Öl auf Holz") == "Ol auf Holz"
    assert ascii_text("Straße, Æble, Ørsted, Łódź, Þór, Œuvre") == "Strasse, AEble, Orsted, Lodz, Thor, OEuvre"
    assert ascii_text("„Zitat“ – ‘quote’ — x") == "\"Zitat\" - 'quote' - x"
    assert ascii_text("ﬁn Ｖｅｒｓｏ ½") == "fin Verso 1?2"
    assert ascii_text("東京 2") == "?? 2" and ascii_text("a\nb\tc") == "a\nb\tc"


# ---------------------------------------------------------------- validation and normalisation
@pytest.mark.parametrize("field, given, kept", [
    ("identifier", "  ACC-1 ", "ACC-1"),
    ("identifier", "ACC\u00a01", "ACC 1"),                       # other spaces -> U+0020
    ("identifier", "Cafe\u0301-1", "Café-1"),                    # NFC
    ("title", "Portrait\x0bof a lady", "Portrait of a lady"),     # FileMaker's in-field line break
    ("title", "a \r\n\r\n b\tc", "a b c"),
    ("title", "line\u2028sep", "line sep"),
    ("operator", "J.\nDoe", "J. Doe"),
    ("notes", "one\r\ntwo\rthree\x0bfour\u2029five\tsix", "one\ntwo\nthree\nfour\nfive\tsix"),
    ("notes", "\n  trimmed  \n", "trimmed"),
])
def test_fields_are_normalised_per_field(field, given, kept):
    args = {"identifier": "ACC-1", field: given}
    assert getattr(Original(**args), field) == kept
    assert getattr(Original(**{**args, field: kept}), field) == kept          # idempotent


@pytest.mark.fault("input")
@pytest.mark.parametrize("field, given, says", [
    ("identifier", "ACC\x001", "identifier: control character U+0000 at character 4 is not allowed"),
    ("identifier", "ACC\n1", "identifier: line break U+000A at character 4 is not allowed (one line, no tabs)"),
    ("identifier", "ACC\t1", "identifier: tab U+0009 at character 4"),
    ("identifier", "ACC\x0b1", "identifier: line break U+000B at character 4"),
    ("identifier", "AC\u200bC", "identifier: invisible format character U+200B at character 3"),
    ("identifier", "", "identifier: required"),
    ("identifier", " -- ", "identifier: '--' needs at least one letter or digit"),
    ("identifier", "A" * 101, "identifier: 101 characters, at most 100"),
    ("title", "ab\x01", "title: control character U+0001 at character 3 is not allowed"),
    ("title", "x\x7f", "title: control character U+007F at character 2"),
    ("title", "x\x85", "title: control character U+0085 at character 2"),
    ("title", "t" * 501, "title: 501 characters, at most 500"),
    ("operator", "\x1b[31m", "operator: control character U+001B at character 1"),
    ("notes", "ok\ufffe", "notes: noncharacter U+FFFE at character 3"),
    ("notes", "\U0001ffff", "notes: noncharacter U+1FFFF at character 1"),
    ("notes", "\ufdd0", "notes: noncharacter U+FDD0"),
    ("notes", "a\ud800b", "notes: lone surrogate U+D800 at character 2"),
    ("notes", "\x0c", "notes: control character U+000C"),
    ("mode", "film", "mode: 'film': expected reflective or transmissive"),
])
def test_refused_in_one_line_naming_field_and_position(field, given, says):
    with pytest.raises(MetadataError) as info:
        Original(**{"identifier": "ACC-1", field: given})
    assert says in str(info.value) and "\n" not in str(info.value), str(info.value)
    assert str(info.value).startswith(f"{field}: ")


@pytest.mark.parametrize("char", [chr(c) for c in (*range(0x20), 0x7F, 0x85, 0xFFFE, 0xFFFF)],
                         ids=lambda c: f"U+{ord(c):04X}")
def test_control_characters_never_give_an_ill_formed_xmp(prof, tmp_path, char):
    """Every C0 control, DEL, NEL and U+FFFE/FFFF in a title and in notes: refused before delivery, or mapped
    and delivered with an XMP packet that a strict parser reads back."""
    for field in ("title", "notes"):
        try:
            original = Original("ACC-1", **{field: f"a{char}b"})
        except MetadataError as exc:
            assert str(exc).startswith(f"{field}: ") and "at character 2" in str(exc)
            continue
        d = run(prof, original, tmp_path / f"out-{field}")
        xmp = read_xmp(d.files["xyz"])                                       # expat: well-formed or it raises
        got = xmp.title if field == "title" else xmp.dualrgb["Notes"]
        assert got == getattr(original, field) == ("a b" if field == "title" else f"a{char}b".replace("\r", "\n")
                                                   .replace("\x0b", "\n")), repr(got)


def test_extra_fields_keep_exact_names_and_get_deterministic_xml_names():
    o = Original("ACC-1", extra={"Accession No.": "1987/12", "Datum": "März 1987", "leer": "  "})
    assert o.extra == {"Accession No.": "1987/12", "Datum": "März 1987"}      # empty values dropped
    assert xmp_property("Datum") == "Extra_Datum"
    assert xmp_property("Accession No.") == "Extra_Accession_No_" + hashlib.sha256(b"Accession No.").hexdigest()[:8]
    names = [xmp_property(c) for c in ("Date", "date", "Date ", "Dáte", "Date_" + "a" * 8, "日付", "1st")]
    assert len(set(names)) == len(names)
    assert all(re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", n) for n in names)
    with pytest.raises(MetadataError, match=r"column name: line break U\+000A"):
        Original("ACC-1", extra={"a\nb": "x"})


# ---------------------------------------------------------------- file names
HARD_IDENTIFIERS = ["ACC-1", "acc-1", "Acc-1", "ACC 1", "ACC/1", "ACC\\1", "ACC_1", "ACC:1", "ACC*1", "ACC?1",
                    "ACC-1.", "ACC-1 .", ".ACC-1", "CON", "con", "Con.txt", "NUL", "COM1", "LPT9", "COM¹", "AUX.tif",
                    "ACC-é", "ACC-e", "ACC-É", "東京-1", "東京", "1987.12.3", "1987.12.3a", "X" * 48, "X" * 49,
                    "X" * 100, "ACC_1_DEADBEEF", "ACC_1_deadbeef", "a<b>c|d\"e"]


def test_file_stems_are_portable_and_deterministic():
    for ident in HARD_IDENTIFIERS:
        stem = file_stem(ident)
        assert re.fullmatch(r"[^\W_][\w.-]*", stem) and stem == unicodedata.normalize("NFC", stem), (ident, stem)
        assert not set(stem) & set('<>:"/\\|?* '), (ident, stem)              # nothing a file system refuses
        assert not stem.endswith((".", " ")) and len(stem) <= 57, (ident, stem)
        base = unicodedata.normalize("NFKC", stem.partition(".")[0]).upper()
        assert base not in {"CON", "PRN", "AUX", "NUL", "COM1", "LPT9"}, (ident, stem)
        assert file_stem(ident) == stem                                        # from the identifier alone
    assert file_stem("ACC-123") == "ACC-123" and file_stem("1987.12.3") == "1987.12.3"     # faithful: unchanged
    assert file_stem("ACC 1") == "ACC_1_" + hashlib.sha256(b"ACC 1").hexdigest()[:8]
    assert file_stem("東博-A-1") == "東博-A-1" and file_stem("ACC-É") == "ACC-É"          # any script, kept whole
    assert file_stem("Öl auf Holz") == "Öl_auf_Holz_" + hashlib.sha256("Öl auf Holz".encode()).hexdigest()[:8]


def test_the_ascii_transliteration_is_reversible():
    for ident in [*HARD_IDENTIFIERS, "東博-A-1", "Öl auf Holz", "INV-é/12"]:
        stem = file_stem(ident)
        name = ascii_stem(stem)
        assert name.isascii() and re.fullmatch(r"[A-Za-z0-9._-]+", name), (ident, name)
        assert stem_of_ascii(name) == stem
    assert ascii_stem("ACC-1") == "ACC-1" and ascii_stem("東博-A-1").startswith("xn--")


def test_this_file_system_takes_unicode_names(tmp_path):
    assert unicode_names_work(tmp_path)                  # ext4, tmpfs, APFS, NTFS: yes
    assert not unicode_names_work(tmp_path / "missing")  # a folder gone: no (nothing made)


def test_a_delivery_of_a_japanese_identifier_keeps_its_characters(prof, tmp_path):
    d = run(prof, Original("東博-A-1", title="富嶽三十六景"), tmp_path / "out")
    assert d.sidecar.parent.name == "東博-A-1" and d.sidecar.name == "東博-A-1.json"
    assert all(p.name.startswith("東博-A-1_") for p in d.files.values()), sorted(p.name for p in d.files.values())
    assert read_xmp(d.files["srgb"]).identifier == "東博-A-1"


def test_distinct_identifiers_never_share_a_name_even_ignoring_case():
    stems = [file_stem(i) for i in HARD_IDENTIFIERS]
    assert len({s.casefold() for s in stems}) == len(HARD_IDENTIFIERS), sorted(stems)


@pytest.mark.parametrize("first, second", [("ACC 1", "ACC/1"), ("acc-1", "ACC-1")])
def test_colliding_identifiers_never_overwrite(prof, tmp_path, first, second):
    out = tmp_path / "out"
    a = run(prof, Original(first, title="first"), out)
    before = digests(a.sidecar.parent)
    b = run(prof, Original(second, title="second"), out)
    assert a.sidecar.parent.name.casefold() != b.sidecar.parent.name.casefold()
    assert not ({p.name.casefold() for p in a.files.values()} & {p.name.casefold() for p in b.files.values()})
    assert digests(a.sidecar.parent) == before                                # the first original's files untouched
    assert read_xmp(a.files["srgb"]).identifier == first and read_xmp(b.files["srgb"]).identifier == second


@pytest.mark.fault("session integrity")
def test_a_folder_of_another_identifier_is_never_written_into(prof, tmp_path):
    out = tmp_path / "out"
    a = run(prof, Original("ACC-1"), out)
    doc = json.loads(a.sidecar.read_text())
    doc["original"]["identifier"] = "ACC-1 (other)"                          # as if a hash had collided
    a.sidecar.write_text(json.dumps(doc))
    before = digests(a.sidecar.parent)
    with pytest.raises(DeliveryFolderError, match=r"holds the deliverables of 'ACC-1 \(other\)'.*'ACC-1' is not"):
        run(prof, Original("ACC-1"), out)
    assert digests(a.sidecar.parent) == before and sorted(p.name for p in out.iterdir()) == ["ACC-1"]
    (out / "ACC-2").mkdir()
    (out / "ACC-2" / "notes.txt").write_text("someone else's")
    with pytest.raises(DeliveryFolderError, match="holds files but no sidecar ACC-2.json"):
        run(prof, Original("ACC-2"), out)


def test_redelivery_replaces_its_own_set_and_keeps_the_previous(prof, tmp_path):
    out = tmp_path / "out"
    first = run(prof, Original("ACC-1", title="first"), out)
    old = digests(first.sidecar.parent)
    second = run(prof, Original("ACC-1", title="second"), out)
    assert second.sidecar == first.sidecar and read_xmp(second.files["srgb"]).title == "second"
    kept = previous_sets(out, Original("ACC-1"))
    assert len(kept) == 1 and digests(kept[0]) == old                         # the previous set, byte for byte
    assert re.fullmatch(r"\d{8}T\d{6}Z", kept[0].name)
    run(prof, Original("ACC-1", title="third"), out)
    assert len(previous_sets(out, Original("ACC-1"))) == 2
    assert sorted(p.name for p in out.iterdir()) == ["ACC-1"]                  # no staging folder left
    assert {p.name for p in (out / "ACC-1").iterdir()} == {*(p.name for p in first.files.values()),
                                                          "ACC-1.json", PREVIOUS}


# ---------------------------------------------------------------- step ids and subject keys
@pytest.mark.parametrize("ident", ["ACC/1", "ACC 1", "ACC", "A:B", "X#take2", "Y+nd", "50%", "50%2F", "東京/1"])
def test_identifiers_cannot_break_step_ids_or_subject_keys(ident):
    subject = Subject.original(ident)
    assert Subject.parse(subject.key) == subject
    assert "/" not in subject.key and "#" not in subject.key and subject.key.count(":") == 1
    sid = step_id(Role.ORIGINAL, subject=subject, light="p light 1", exposure_s=0.01, frame=1, take=3)
    base, take = split_take(sid)
    assert take == 3 and base.split("/")[1] == subject.key and len(base.split("/")) == 5


def test_frames_of_acc_and_acc_slash_1_are_not_mixed():
    from dualrgb.app.workflow.stand.copystand import original_dose

    def dose(ident, on_s):
        sid = step_id(Role.ORIGINAL, subject=Subject.original(ident), light="L light 1", exposure_s=0.5)
        return SimpleNamespace(step_id=sid, light={"leds": [1], "levels": [1.0]}, on_s=on_s)
    session = SimpleNamespace(settings={}, doses=lambda: [dose("ACC", 1.0), dose("ACC/1", 2.0), dose("ACC 1", 4.0)])
    got = {i: original_dose(session, Subject.original(i)).on_s for i in ("ACC", "ACC/1", "ACC 1")}
    assert got == {"ACC": 1.0, "ACC/1": 2.0, "ACC 1": 4.0}
