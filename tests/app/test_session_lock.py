"""The session lock (core.session.lock) through filelock: shared within a process, released by the last holder,
and safe against a CaptureSession's finaliser run by a garbage collection inside the lock's own bookkeeping."""
from __future__ import annotations

import threading

from dualrgb.core.session import lock


def test_shared_within_the_process_and_released_by_the_last(tmp_path):
    first = lock.acquire(tmp_path)
    assert lock.acquire(tmp_path) == first
    assert lock.read_holder(tmp_path)["pid"] and (tmp_path / lock.HOLDER_NAME).is_file()
    lock.release(first)
    assert first in lock._registry                  # one reference left
    lock.release(first)
    assert first not in lock._registry and not (tmp_path / lock.HOLDER_NAME).exists()


def test_released_from_another_thread(tmp_path):
    key = lock.acquire(tmp_path)
    t = threading.Thread(target=lock.release, args=(key,))
    t.start()
    t.join(10)
    assert key not in lock._registry
    lock.release(lock.acquire(tmp_path))            # and it can be taken again


def test_a_finaliser_inside_acquire_is_deferred_not_deadlocked(tmp_path):
    """A collection can start inside acquire() (filelock allocates); a session's finaliser then calls release()
    on a thread that holds the registry's guard: it must not wait for it (the test suite hung there once)."""
    key = lock.acquire(tmp_path)
    done = threading.Event()

    def inside() -> None:
        with lock._guarded():                       # as acquire() does
            lock.release(key)                       # as the finaliser does, on the same thread
            assert key in lock._registry            # deferred ...
        done.set()

    t = threading.Thread(target=inside, daemon=True)
    t.start()
    t.join(30)
    assert done.is_set(), "release() waited for the guard its own thread holds"
    assert key not in lock._registry                # ... and done on the way out
