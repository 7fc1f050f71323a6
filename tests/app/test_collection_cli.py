"""``dualrgb collection list / show / set`` (issue 42): a collection's metadata preset made and changed from the
command line by the window's functions (make_preset, save_preset) - set, show and list round trip, a bad value is
one line naming the option and the problem with the file left as it was, and docs/gui.md's commands run as
written."""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from doc_blocks import dualrgb_prelude, run_block

from dualrgb.app import cli
from dualrgb.app.workflow.day.collection_presets import default_folder, find_preset, load_preset
from dualrgb.core.metadata import Credits

ROOT = Path(__file__).resolve().parents[2]
GEM_ARGS = ["collection", "set", "GEM", "--creator", "Example Museum, Imaging Studio", "--creator", "J. Doe",
            "--rights", "CC BY 4.0, Example Museum", "--credit", "Gemäldegalerie, Example Museum",
            "--source", "Example Museum", "--extra", "collection=Gemäldegalerie", "--extra", "department=Paintings",
            "--template", "GEM-{date}-{counter:04}"]


def run(capsys, *argv: str) -> tuple[int, str, str]:
    rc = cli.main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return rc, out, err


def test_set_show_and_list_round_trip(capsys):
    rc, out, _ = run(capsys, *GEM_ARGS)
    path = default_folder() / "GEM.json"
    assert rc == 0 and out.splitlines()[0] == f"saved {path}"
    gem = load_preset(path)
    assert gem.credits == Credits(("Example Museum, Imaging Studio", "J. Doe"), "CC BY 4.0, Example Museum",
                                  "Gemäldegalerie, Example Museum", "Example Museum")
    assert dict(gem.extra) == {"collection": "Gemäldegalerie", "department": "Paintings"}
    assert gem.identifier_template == "GEM-{date}-{counter:04}" and out.splitlines()[1] == gem.summary()
    rc, out, _ = run(capsys, "collection", "show", "gem")                  # matched ignoring case
    assert rc == 0 and out.splitlines() == [
        f"collection  GEM  ({path})", "creator     Example Museum, Imaging Studio", "creator     J. Doe",
        "rights      CC BY 4.0, Example Museum", "credit      Gemäldegalerie, Example Museum",
        "source      Example Museum", "extra       collection = Gemäldegalerie", "extra       department = Paintings",
        "template    GEM-{date}-{counter:04}"]
    rc, out, err = run(capsys, "collection", "show", "GEM", "--json", "-")
    doc = json.loads(out)
    assert rc == 0 and doc["format"] == "dualrgb-collection/1" and doc["creator"] == list(gem.credits.creator)
    assert doc["extra"] == dict(gem.extra) and err.startswith("collection  GEM")
    rc, out, _ = run(capsys, "collection", "list")
    assert rc == 0 and out.splitlines() == [gem.summary()]


def test_set_changes_the_fields_given_and_keeps_the_others(capsys):
    run(capsys, *GEM_ARGS)
    rc, _, _ = run(capsys, "collection", "set", "gem", "--rights", "Public domain", "--extra", "department=",
                   "--extra", "box=7", "--template", "")
    back = find_preset("GEM")
    assert rc == 0 and back is not None and back.path == default_folder() / "GEM.json"
    assert back.credits.rights == "Public domain" and back.credits.creator == ("Example Museum, Imaging Studio",
                                                                               "J. Doe")
    assert dict(back.extra) == {"collection": "Gemäldegalerie", "box": "7"} and back.identifier_template == ""
    rc, _, _ = run(capsys, "collection", "set", "GEM", "--replace", "--source", "Another Museum")
    again = find_preset("GEM")
    assert rc == 0 and again is not None and again.credits == Credits(source="Another Museum") and not again.extra


REFUSED = [
    (["--rights", "CC BY\x01"], "dualrgb: error: --rights 'CC BY\\x01': rights: control character U+0001"),
    (["--template", "{room}-{counter}"], "dualrgb: error: --template '{room}-{counter}': identifier template: "
                                         "unknown token {room}"),
    (["--creator", "A", "--creator", "B\x00"], "dualrgb: error: --creator 'A, B\\x00': creator: control "
                                               "character U+0000"),
    (["--extra", "a=1", "--extra", "a=2"], "dualrgb: error: --extra: extra.a: named twice"),
    (["--extra", "=x"], "argument --extra: '=x': expected FIELD=VALUE, e.g. department=Paintings"),
    (["--extra", "department"], "argument --extra: 'department': expected FIELD=VALUE"),
]


@pytest.mark.parametrize("given, says", REFUSED, ids=[g[0] + str(i) for i, (g, _) in enumerate(REFUSED)])
def test_a_bad_value_is_one_line_and_nothing_is_written(capsys, given, says):
    run(capsys, *GEM_ARGS)
    path = default_folder() / "GEM.json"
    before = path.read_bytes()
    try:
        rc, _, err = run(capsys, "collection", "set", "GEM", *given)
    except SystemExit as exc:                                       # argparse: its usage, then the one line
        rc, err = int(exc.code or 0), capsys.readouterr().err
        err = err.splitlines()[-1]
    assert rc in (1, 2) and says in err and len(err.strip().splitlines()) == 1, err
    assert path.read_bytes() == before and sorted(p.name for p in default_folder().iterdir()) == ["GEM.json"]


def test_refusals_name_the_collection_or_the_file(capsys):
    rc, _, err = run(capsys, "collection", "show", "NONE")
    assert rc == 1 and err == f"dualrgb: error: collection NONE: no preset file {default_folder() / 'NONE.json'}\n"
    rc, _, err = run(capsys, "collection", "set", "a/b", "--rights", "x")
    assert rc == 1 and err.startswith("dualrgb: error: collection 'a/b': '/' cannot be in a file name")
    assert not default_folder().exists()                                    # nothing written
    bad = default_folder() / "FILM.json"
    bad.parent.mkdir(parents=True)
    bad.write_text('{"format": "dualrgb-collection/1", "rights": 5}', encoding="utf-8")
    rc, out, _ = run(capsys, "collection", "list")
    assert rc == 1 and out.startswith(f"preset FILM: not used: {bad}: rights: 5 is not of type 'string'")
    rc, _, err = run(capsys, "collection", "set", "film", "--source", "X")
    assert rc == 1 and err.startswith(f"dualrgb: error: {bad}: rights: 5") and "--replace" in err
    assert json.loads(bad.read_text(encoding="utf-8"))["rights"] == 5                    # left as it was
    rc, out, _ = run(capsys, "collection", "set", "film", "--source", "X", "--replace")
    assert rc == 0 and load_preset(bad).credits == Credits(source="X") and "preset FILM: source X" in out


def test_the_docs_collection_commands_run_as_written(tmp_path):
    env = {**os.environ, "DUALRGB_DATA_DIR": str(tmp_path / "data")}
    ran = run_block(ROOT / "docs" / "gui.md", "collection-preset-cli", tmp_path, env=env, prelude=dualrgb_prelude())
    folder = tmp_path / "data" / "presets" / "collections"
    assert [p.name for p in folder.iterdir()] == ["GEM.json"]
    gem = load_preset(folder / "GEM.json")
    assert gem.credits.rights and gem.identifier_template and gem.extra
    assert any(r.stdout.startswith("collection  GEM") for r in ran)
