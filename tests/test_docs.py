"""The user docs: README stays short and links into the site, the site builds with warnings as errors (what
`make docs` runs inside `make test`), and its figures come from the committed JSON through docs/_ext/jsonfigures.py.
Skipped where the docs' tools are not installed (the wheel's venv): `make venv` installs the [docs] extra."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"


@pytest.fixture
def jsonfigures():
    """docs/_ext/jsonfigures.py, the Sphinx extension itself (not a package; it imports Sphinx)."""
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        return pytest.importorskip("jsonfigures", reason="the [docs] extra (Sphinx) is not installed")
    finally:
        sys.path.remove(str(DOCS / "_ext"))


def _links(text: str) -> list[str]:
    return re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)


def test_readme_is_short_and_links_into_the_site():
    text = README.read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= 250
    long = [i + 1 for i, line in enumerate(lines)
            if len(line) > 120 and not line.startswith("|") and "://" not in line]
    assert long == [], f"README lines over 120 characters (not a table or URL): {long}"
    headings = [line for line in lines if line.startswith("#")]
    assert not [h for h in headings if re.search(r"\bissue \d+", h, re.I)]
    assert "make run" in text and "make test" in text
    for link in _links(text):
        if "://" not in link:
            assert (ROOT / link).is_file(), f"README links to {link}, which does not exist"
    pages = {str(p.relative_to(ROOT)) for p in DOCS.rglob("*.md") if "notes" not in p.parts}
    assert {"docs/tutorial/first-day.md", "docs/reference/cli.md", "docs/explanation/architecture.md"} <= pages
    assert "docs/tutorial/first-day.md" in _links(text)


def test_the_layer_test_points_to_the_architecture_page():
    doc = (ROOT / "tests" / "test_layers.py").read_text(encoding="utf-8").split('"""')[1]
    assert "docs/explanation/architecture.md" in doc and (DOCS / "explanation" / "architecture.md").is_file()
    assert "tests/test_layers.py" in (DOCS / "explanation" / "architecture.md").read_text(encoding="utf-8")


CODE_REF = re.compile(r"`((?:dualrgb\.)?(?:app|drivers|simulation|common|resources)\.[A-Za-z_][\w.]*)")


def _resolves(ref: str) -> bool:
    """Whether ``ref`` (``core.engine.RunEngine``, with or without ``dualrgb.``) names a module of the
    package or an attribute of one."""
    import importlib

    parts = ("dualrgb." + ref.removeprefix("dualrgb.")).rstrip(".").split(".")
    for i in range(len(parts), 1, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for name in parts[i:]:
            if not hasattr(obj, name):
                return False
            obj = getattr(obj, name)
        return True
    return False


def test_the_code_the_docs_name_exists():
    """Every module, class or function the user docs and README name in backticks (``core.engine``,
    ``dualrgb.app.processing.encode.DeliveryEncoder``) is importable on main: a renamed or removed one is found
    here, not by a reader (the developer notes under docs/notes are a record and are left out)."""
    pages = [p for p in DOCS.rglob("*.md") if "notes" not in p.parts] + [README]
    stale = sorted({f"{p.relative_to(ROOT)}: {m}" for p in pages for m in CODE_REF.findall(p.read_text("utf-8"))
                    if not _resolves(m)})
    assert stale == []
    assert not _resolves("app.workflow.runs.StandRun") and _resolves("core.engine.RunEngine")


def test_the_json_role_reads_the_value_and_names_what_is_missing(tmp_path, jsonfigures):
    (tmp_path / "r.json").write_text(json.dumps({"a": {"b": [0.1234, {"c": 7}]}}))
    assert jsonfigures.render("r.json#a.b.0:.2f", tmp_path)[0] == "0.12"
    assert jsonfigures.render("r.json#a.b.1.c", tmp_path)[0] == "7"
    (tmp_path / "k.json").write_text(json.dumps({"re-optimised: world": {"t": 0.31234, "r": 0.0704}}))
    assert jsonfigures.render("k.json#re-optimised: world.t:.3f", tmp_path)[0] == "0.312"   # a key with ':'
    assert jsonfigures.render("k.json#re-optimised: world.r:+.1%", tmp_path)[0] == "+7.0%"
    assert jsonfigures.render("k.json#re-optimised: world.t", tmp_path)[0] == "0.31234"
    for bad, said in (("r.json#a.x", "'x'"), ("nothere.json#a", "nothere.json"), ("r.json#a.b.0:d", "r.json#a.b.0")):
        with pytest.raises(ValueError, match=re.escape(said)):
            jsonfigures.render(bad, tmp_path)


def test_the_json_role_picks_a_list_element_by_its_fields(tmp_path, jsonfigures):
    rows = [{"mode": "reflective", "method": "pso", "t": 1.0}, {"mode": "transmissive", "method": "pso", "t": 2.0},
            {"mode": "transmissive", "method": "exhaustive", "t": 3.0}]
    (tmp_path / "s.json").write_text(json.dumps({"rows": rows}))
    assert jsonfigures.render("s.json#rows.mode=reflective.t:.1f", tmp_path)[0] == "1.0"
    assert jsonfigures.render("s.json#rows.mode=transmissive&method=exhaustive.t", tmp_path)[0] == "3.0"
    for bad, said in (("s.json#rows.mode=transmissive.t", "2 elements match"), ("s.json#rows.mode=film.t", "0 elem"),
                      ("s.json#rows.nokey=pso.t", "0 elements")):
        with pytest.raises(ValueError, match=said):
            jsonfigures.render(bad, tmp_path)


# The pages whose measured figures (dE00, RMSE, seconds, percentages a study or bench measured) come from committed
# JSON, and per page the figures typed by hand that are not results: parameters, targets, equation and table numbers.
FIGURE_PAGES = {
    "studies.md": {"1 %", "-3 %", "8x", "1x", "100x", "1 s", "0.01 s", "0.01 %", "0.03", "0.05", "2.0", "8.9",
                   "5.1", "6.1", "6.2", "7.1", "7.2", "8.1", "8.2", "9.1", "9.2"},
    "explanation/spectral.md": {"1 %", "38 x", "240 x", "600 x", "1.5x", "0.01", "0.03", "2.0", "4.2"},
}
FIGURE = re.compile(r"(?<![\w.\-/])[+\-~]?\d+(?:\.\d+)?\s?(?:%|s\b|x\b|µs|us\b|MB|M\b|k\b)|(?<![\w.])\d+\.\d+")
EARLIER_RUN = re.compile(r"\bcommit [0-9a-f]{7}\b")


def hand_typed_figures(text: str, allowed: set[str]) -> list[str]:
    """The figures of ``text`` typed by hand: outside {json} roles, generated sections and code blocks, not in
    ``allowed``, and not in a paragraph that names the earlier run (a commit) they come from, nor in a table right
    after one."""
    text = re.sub(r"<!-- ([\w-]+):start -->.*?<!-- \1:end -->", "", text, flags=re.S)
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    text = re.sub(r"\{json\}`[^`]*`", "{json}", text)
    found, named = [], False
    for block in text.split("\n\n"):
        table = block.lstrip().startswith("|")
        named = bool(EARLIER_RUN.search(block)) or (table and named)
        if not named:
            found += [f for f in FIGURE.findall(block) if f.strip() not in allowed]
    return found


@pytest.mark.parametrize("page", sorted(FIGURE_PAGES))
def test_the_figure_pages_type_no_result_by_hand(page):
    assert hand_typed_figures((DOCS / page).read_text(encoding="utf-8"), FIGURE_PAGES[page]) == []


def test_a_hand_typed_figure_is_found():
    allowed = {"0.05"}
    assert hand_typed_figures("reaches 0.399 in 1.8 s, 31 % off (tolerance 0.05)", allowed) == ["0.399", "1.8 s",
                                                                                                  "31 %"]
    assert hand_typed_figures("reaches {json}`d.json#a:.3f` in {json}`d.json#s` s", allowed) == []
    assert hand_typed_figures("<!-- t:start -->\n| 0.399 |\n<!-- t:end -->", allowed) == []
    assert hand_typed_figures("0.40 in the run of commit 0123abc:\n\n| 0.399 |\n\nthen 0.41", allowed) == ["0.41"]


@pytest.mark.parametrize("page", sorted({*FIGURE_PAGES, "explanation/figures.md", "explanation/stand-model.md"}))
def test_every_figure_role_of_a_page_resolves(page, jsonfigures):
    """What `make docs` fails on, without Sphinx's build: each {json} role names a committed file, key and format."""
    roles = re.findall(r"\{json\}`([^`]*)`", (DOCS / page).read_text(encoding="utf-8"))
    assert roles
    for role in roles:
        jsonfigures.render(role, DOCS)                       # ValueError naming the file and key


def test_the_demo_table_is_the_reports(jsonfigures):
    report = json.loads((DOCS / "notes" / "issue-31" / "demo-reflective-report.json").read_text(encoding="utf-8"))
    rows = jsonfigures.demo_rows(report)
    assert len(rows) == 2 + len(report["conditions"])
    pso = next(r for r in rows if r.startswith("| dual_rgb_pso |"))
    assert f"| {report['dual_rgb_pso']['train']['mean']:.3f} |" in pso and "(1, 6, 7) @ (0.01001, 0.1685, 1)" in pso
    assert f"| {report['dual_rgb_pso']['simulated']['train']:.3f} |" in pso
    hdr = jsonfigures.demo_rows({"conditions": ["hdr_dual_rgb"], "hdr_dual_rgb": report["dual_rgb_pso"]})[2]
    assert hdr.endswith("|  |  |  |  |")                  # no prediction for the ND-covered scene


def test_the_site_builds_with_warnings_as_errors(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    pytest.importorskip("sphinxarg")
    pytest.importorskip("furo")
    r = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS),
                        str(tmp_path / "html")], capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-4000:]
    html = tmp_path / "html"
    cli = (html / "reference" / "cli.html").read_text(encoding="utf-8")
    for command in ("calibrate", "capture", "process", "verify", "bag", "study", "measure"):
        assert f">{command}<" in cli or f"dualrgb {command}" in cli, command        # every command documented
    assert "--method pso --objective noise-free" in cli and "\u2013method" not in cli      # options keep their --
    for page in ("tutorial/first-day", "how-to/queue", "reference/schemas", "explanation/architecture", "gui"):
        assert (html / f"{page}.html").is_file(), page
    assert "dualrgb-session" in (html / "reference" / "schemas.html").read_text(encoding="utf-8")


# ---------------------------------------------------------------------------------- blocks that run as written
SHELL_FENCE = re.compile(r"^```(sh|bash|shell|console)\s*$")
PLACEHOLDER = re.compile(r"--[\w-]+ (?:[A-Z]|[A-Z]{2,}[A-Z_]*)(?:\s|$)")     # --world W, --out DIR
# the command blocks no test runs, and why (a block is otherwise marked <!-- test: NAME --> and run by a test)
NOT_RUN = {
    ("README.md", "make run"): "the whole set-up and the GUI: `make test` itself runs it",
    ("README.md", "dualrgb calibrate --session day1 --virtual-lab"): "its lines are the tutorial's "
                                                                       "(test_readmes_first_day_is_the_tutorials)",
    ("docs/how-to/install.md", "make run"): "the whole set-up and the GUI: `make test` itself runs it",
    ("docs/how-to/install.md", "# Debian / Ubuntu"): "system packages: needs root on the user's machine",
    ("docs/first-session-d610.md", "sudo apt-get install libgphoto2-6"): "udev rules: needs root and a USB camera",
    ("docs/first-session-d610.md", "gio mount -s gphoto2"): "a desktop's gvfs: nothing to stop on a test machine",
    ("docs/first-session-d610.md", "killall -9 ptpcamerad"): "macOS only",
    ("docs/how-to/measure-stand.md", "dualrgb measure csrf --virtual-lab --start 380 --end 780 --step 10 --out "
                                     "d610_csrf.csv"):
        "a monochromator and a camera on their ports (lines 2 and 3); line 1 is the measure-stand block's step 2",
}


def shell_blocks() -> list[tuple[str, int, str, str | None]]:
    """Every shell code block of README and the docs site (not docs/notes): (page, line, text, its test name)."""
    out = []
    for page in [README, *sorted(p for p in DOCS.rglob("*.md") if "notes" not in p.relative_to(DOCS).parts)]:
        lines = page.read_text(encoding="utf-8").splitlines()
        for i, line in enumerate(lines):
            if not SHELL_FENCE.match(line):
                continue
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            before = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            marker = re.fullmatch(r"<!-- test: ([\w.-]+) -->", before.strip())
            out.append((str(page.relative_to(ROOT)), i + 1, "\n".join(lines[i + 1:end]),
                        marker.group(1) if marker else None))
    return out


def _first(block: str) -> str:
    """A block's first line without its comment (the key of NOT_RUN)."""
    line = block.splitlines()[0] if block.strip() else ""
    return line.strip() if line.strip().startswith("#") else line.split("#", 1)[0].strip()


def test_every_command_block_is_run_by_a_test_or_says_why_not():
    tests = "\n".join(p.read_text(encoding="utf-8") for p in (ROOT / "tests").rglob("*.py"))
    unaccounted, unrun = [], []
    for page, line, text, name in shell_blocks():
        if name is None and (page, _first(text)) not in NOT_RUN:
            unaccounted.append(f"{page}:{line}")
        if name is not None and f'"{name}"' not in tests:
            unrun.append(f"{page}:{line} ({name})")
    assert unaccounted == [], "shell blocks neither marked <!-- test: NAME --> nor in NOT_RUN"
    assert unrun == [], "marked blocks no test names"
    firsts = {(page, _first(text)) for page, _, text, _ in shell_blocks()}
    assert [k for k in NOT_RUN if k not in firsts] == []              # no stale exemption


def test_no_command_block_has_a_glob_that_can_match_two_files_or_a_placeholder():
    """A command as written must be the command to type: no `cal-*.json` (two calibrations: two arguments), no
    `--world W` / `--out DIR` typed literally."""
    found = []
    for page, line, text, _ in shell_blocks():
        for k, command in enumerate(text.splitlines()):
            words = command.split("#", 1)[0].split()
            if not words or words[0] != "dualrgb":
                continue
            if any(c in w for w in words for c in "*?"):
                found.append(f"{page}:{line + k + 1}: a glob: {command.strip()}")
            if PLACEHOLDER.search(command.split("#", 1)[0].replace("--render-illuminant A", "")):
                found.append(f"{page}:{line + k + 1}: a placeholder: {command.strip()}")
    assert found == []


def test_a_glob_or_a_placeholder_is_found():
    assert PLACEHOLDER.search("dualrgb demo --world W --out x") and PLACEHOLDER.search("dualrgb x --out DIR")
    assert not PLACEHOLDER.search("dualrgb capture --id ACC-123 --session d --operator \"J. Doe\"")
