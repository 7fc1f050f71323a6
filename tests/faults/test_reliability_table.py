"""The reliability-table plugin itself: counts per category, the docs page's block between the markers."""
from collections import Counter

import pytest
from faults.plugin import END, START, render_table, replace_between_markers


def test_table_lists_known_categories_first_and_a_total():
    table = render_table(Counter({"input": 3, "light safety": 2, "other": 1}), Counter({"input": 3, "light safety": 1}))
    rows = table.splitlines()
    assert rows[2] == "| light safety | 2 | 1 |" and rows[3] == "| input | 3 | 3 |" and rows[4] == "| other | 1 | 0 |"
    assert rows[-1] == "| **all** | **6** | **4** |"


def test_only_the_block_between_the_markers_is_replaced():
    text = f"intro\n{START}\nold table\n{END}\nrest\n"
    out = replace_between_markers(text, "| new |")
    assert out.startswith(f"intro\n{START}\n| new |\n") and out.endswith(f"{END}\nrest\n") and "old" not in out
    assert replace_between_markers(out, "| new |") == out                  # idempotent
    with pytest.raises(pytest.UsageError):
        replace_between_markers("no markers here", "| t |")


def test_the_page_holds_one_table_block_with_the_note_the_plugin_writes():
    """`make reliability` writes into docs/explanation/reliability.md: the block is there once, and rewriting it with
    its own table changes nothing (the note names the page)."""
    from pathlib import Path

    from faults.plugin import PAGE

    page = Path(__file__).resolve().parents[2] / PAGE
    if not page.is_file():
        pytest.skip(f"{PAGE} is not beside the tests")
    text = page.read_text(encoding="utf-8")
    assert text.count(START) == 1 and text.count(END) == 1
    table = text.split(START)[1].split(END)[0].strip().split("\n\n")[0]
    assert table.startswith("| Category | Cases tried | Clean |")
    assert replace_between_markers(text, table) == text
