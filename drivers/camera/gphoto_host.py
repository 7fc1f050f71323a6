"""What the gphoto2 driver's parts (:class:`GPhotoSettings`, :class:`GPhotoFiles`) use of the camera they are
mixed into (:class:`drivers.camera.gphoto.GPhotoCamera`), declared once so a type checker sees one interface.

Declarations only: at run time :class:`GPhotoHost` is an empty base class and GPhotoCamera provides all of it.
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

T = TypeVar("T")


class GPhotoHost:
    """The camera's settings, clock and libgphoto2 access, as its mixins see them."""

    call_timeout_s: float
    download_timeout_s: float
    pair_timeout_s: float
    bulb_limit_s: float
    busy_delay_s: float
    image_quality: str
    _lock: threading.RLock
    _sleep: Callable[[float], object]
    _clock: Callable[[], float]

    if TYPE_CHECKING:
        def _gp_module(self) -> Any: ...

        def _require_open(self) -> Any: ...

        def _call(self, action: str, fn: Callable[..., T], *args: Any, deadline_s: float | None = None,
                  retry: bool = True, opening_port: bool = False) -> T: ...

        @property
        def expects_raw(self) -> bool: ...

        @property
        def stores_pairs(self) -> bool: ...
