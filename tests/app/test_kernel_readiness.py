"""The first run of an installation compiles numba's kernels before anything is opened, saying so in one line
(issue 41): a group is ready once its stamp (keyed by its sources, the versions and the CPU) exists beside numba's
cache; a changed source makes it stale."""
from __future__ import annotations

import os

from dualrgb.app import warm_kernels


def test_a_group_without_its_stamp_is_warmed_once_with_a_line(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))        # the stamps live beside this cache
    warmed: list[str] = []
    monkeypatch.setitem(warm_kernels.GROUPS, warm_kernels.PROCESSING, lambda: warmed.append("processing"))
    said: list[str] = []
    assert not warm_kernels.ready(warm_kernels.PROCESSING)
    warm_kernels.ensure_ready([warm_kernels.PROCESSING], said.append)
    assert warmed == ["processing"] and said[0].startswith("first run of this installation: compiling 1 group")
    assert warm_kernels.ready(warm_kernels.PROCESSING)
    said.clear()
    warm_kernels.ensure_ready([warm_kernels.PROCESSING], said.append)   # ready: silent, nothing compiled
    assert warmed == ["processing"] and said == []


def test_a_changed_kernel_source_makes_the_stamp_stale(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    before = warm_kernels.stamp_path(warm_kernels.OPTIMISERS)
    processing = warm_kernels.stamp_path(warm_kernels.PROCESSING)
    source = next(p for p in sorted((warm_kernels.Path(warm_kernels.__file__).resolve().parents[1] / "simulation")
                                    .glob("*.py")))
    stat = source.stat()
    try:
        os.utime(source, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
        assert warm_kernels.stamp_path(warm_kernels.OPTIMISERS) != before
        assert warm_kernels.stamp_path(warm_kernels.PROCESSING) == processing     # other groups' keys stay
    finally:
        os.utime(source, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert warm_kernels.stamp_path(warm_kernels.OPTIMISERS) == before
