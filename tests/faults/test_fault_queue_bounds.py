"""Every input's memory bounded (issue 38 item 7): a 1e6-row queue under the 16 MiB cap (13.9 MB) made
`capture --check` run for minutes and grow past 790 MB; the queue is now read as a stream, its originals counted
first, and one over :data:`MAX_QUEUE_ROWS` is refused in one line before any row is checked."""
from __future__ import annotations

import tracemalloc

import pytest
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.app.workflow.day import queue_csv
from dualrgb.app.workflow.day.queue_csv import MAX_QUEUE_BYTES, MAX_QUEUE_ROWS, read_queue_csv


@pytest.mark.fault("input")
def test_a_million_row_queue_is_refused_in_one_line_before_any_row_is_checked(tmp_path, capsys, monkeypatch):
    queue = tmp_path / "q.csv"
    with open(queue, "w", encoding="utf-8") as fh:
        fh.write("identifier,title\n")
        fh.writelines(f"ACC-{i:07d},T\n" for i in range(1_000_000))
    assert 13_000_000 < queue.stat().st_size < MAX_QUEUE_BYTES          # under the size cap, as in the issue
    checked = []
    real_row = queue_csv._row
    monkeypatch.setattr(queue_csv, "_row", lambda *a: checked.append(a[0]) or real_row(*a))
    opened = []
    monkeypatch.setattr("dualrgb.drivers.virtual.lab.VirtualLab.start", lambda self: opened.append(self))
    rc = main(["capture", "--virtual-lab", "--calibration", str(make_profile(tmp_path / "cal").path), "--queue",
               str(queue), "--check", "--session", str(tmp_path / "session")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(lines) == 1, lines[-3:]
    assert lines[0] == (f"dualrgb: error: {queue}: more than {MAX_QUEUE_ROWS} originals (row {MAX_QUEUE_ROWS + 2} "
                        f"is the {MAX_QUEUE_ROWS + 1}th): a day's queue holds at most {MAX_QUEUE_ROWS}; split it")
    assert checked == [] and opened == []
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match="more than"):
            read_queue_csv(queue)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    print(f"[input] 1e6-row queue ({queue.stat().st_size / 1e6:.1f} MB): refused; reading it took at most "
          f"{peak / 2 ** 20:.2f} MiB of Python memory")
    assert peak < 2 ** 20                  # a stream: a few rows at a time, not the file nor a million rows


@pytest.mark.parametrize("rows, refused", [(3, False), (4, True)])
def test_the_row_limit_counts_originals_not_empty_lines(tmp_path, monkeypatch, rows, refused):
    monkeypatch.setattr(queue_csv, "MAX_QUEUE_ROWS", 3)
    queue = tmp_path / "q.csv"
    queue.write_text("identifier\n\n" + "".join(f"A-{i}\n\n" for i in range(rows)))
    if refused:
        with pytest.raises(ValueError, match=r"more than 3 originals \(row 9 is the 4th\)"):
            read_queue_csv(queue)
    else:
        assert [e.row for e in read_queue_csv(queue).entries] == [3, 5, 7]
