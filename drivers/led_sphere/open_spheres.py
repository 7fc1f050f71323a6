"""The LED spheres this process has open: a :class:`~drivers.led_sphere.driver.LedSphere` joins when its port opens
and leaves when it closes, wherever it was opened (a real stand's ``open_sphere``, the virtual lab's client, the
``sphere`` command). A signal handler (app.interrupts) switches every one of them off before the process ends.

No lock: a signal handler runs on the main thread between two bytecodes, possibly while that thread is inside
:func:`register`; a lock held there would never be released. A ``WeakSet`` copied with ``tuple()`` is safe enough
for that (the copy is retried if another thread changed the set meanwhile), and a sphere that was dropped without
being closed leaves by itself.
"""
from __future__ import annotations

import weakref
from typing import Protocol


class Closable(Protocol):
    """What a registered sphere offers the handler (LedSphere's switch-off, read back; never raises)."""

    @property
    def port(self) -> str: ...

    def ensure_off(self) -> object: ...


_OPEN: weakref.WeakSet[Closable] = weakref.WeakSet()


def register(sphere: Closable) -> None:
    """``sphere``'s port is open."""
    _OPEN.add(sphere)


def unregister(sphere: Closable) -> None:
    """``sphere``'s port is closed."""
    _OPEN.discard(sphere)


def open_spheres() -> tuple[Closable, ...]:
    """Every sphere whose port is open now."""
    for _ in range(4):
        try:
            return tuple(_OPEN)
        except RuntimeError:            # another thread opened or closed one while copying: copy again
            continue
    return tuple(_OPEN)
