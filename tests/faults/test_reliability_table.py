"""The reliability-table plugin itself: counts per category, the README block between the markers."""
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
