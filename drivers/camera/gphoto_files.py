"""The gphoto2 camera's files: the events that announce them, the raw file picked among them, downloads.

A capture can store more than one file (NEF+JPEG when the quality could not be set to raw only), and the second
file of a pair can be announced after the first was taken, even during the next capture. The raw file is picked
by its extension among the files a capture announced, the pair's other file is waited for briefly and drained,
and files announced before a capture begins are set aside as an earlier capture's, so a late JPEG is never taken
for the next frame. Reading libgphoto2's FILE_ADDED event for a file in Internal RAM downloads it (camlibs/ptp2
library.c, ``camera_wait_for_event``): :meth:`GPhotoFiles._wait_for_raw` runs in ``fetch()``, with the light off.

:class:`GPhotoFiles` is a mixin of :class:`drivers.camera.gphoto.GPhotoCamera`.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from dualrgb.drivers.camera.base import CameraError
from dualrgb.drivers.camera.gphoto_errors import GP_ERROR_TIMEOUT
from dualrgb.drivers.camera.gphoto_host import GPhotoHost
from dualrgb.drivers.camera.gphoto_settings import RAW_QUALITY

log = logging.getLogger(__name__)

RAW_EXTENSIONS = (".nef", ".nrw", ".dng", ".cr2", ".cr3", ".arw", ".raf", ".orf", ".rw2", ".pef")


def is_raw_name(name: str) -> bool:
    return name.lower().endswith(RAW_EXTENSIONS)


@dataclass
class CapturedFiles:
    """The gphoto2 camera's :attr:`Exposure.handle`: files the camera announced while the exposure ended."""

    files: list[tuple[str, str]] = field(default_factory=list)


class GPhotoFiles(GPhotoHost):
    """Events, the raw file of a capture and downloads (mixin of GPhotoCamera)."""

    def _event(self, action: str, timeout_s: float) -> tuple[int, Any]:
        cam = self._require_open()
        ms = max(1, int(timeout_s * 1000))
        return self._call(action, cam.wait_for_event, ms, deadline_s=timeout_s + self.call_timeout_s)

    def _drain_events(self, max_events: int = 50) -> list[tuple[str, str]]:
        """Read queued events without waiting; returns files that were added meanwhile."""
        gp = self._gp_module()
        added = []
        for _ in range(max_events):
            kind, data = self._event("read camera events", 0.01)
            if kind == gp.GP_EVENT_TIMEOUT:
                break
            if kind == gp.GP_EVENT_FILE_ADDED:
                added.append((data.folder, data.name))
        return added

    def _discard_queued_files(self) -> None:
        """Before a capture: files still announced by an earlier one (a late JPEG of a pair) are not this one's."""
        late = self._drain_events()
        if late:
            log.warning("ignored %s: stored by an earlier capture and announced late", ", ".join(n for _, n in late))

    def _wait_until(self, want: Callable[[int, Any], bool], timeout_s: float, action: str, failure: str) -> None:
        """Read events until ``want(kind, data)`` is true; after ``timeout_s`` a one-line CameraError
        ``failure`` (formatted with ``s``, the timeout)."""
        deadline = self._clock() + timeout_s
        while True:
            left = deadline - self._clock()
            if left <= 0:
                raise CameraError(f"capture: {failure.format(s=timeout_s)} (check the card/Internal RAM and the "
                                  "camera's display)", GP_ERROR_TIMEOUT)
            if want(*self._event(action, min(left, 1.0))):
                return

    def _pick(self, files: list[tuple[str, str]]) -> tuple[str, str] | None:
        if not self.expects_raw:
            return files[0] if files else None
        return next((f for f in files if is_raw_name(f[1])), None)

    def _wait_for_raw(self, seen: list[tuple[str, str]], timeout_s: float) -> tuple[str, str]:
        """The raw file of this capture among those announced, waiting for FILE_ADDED events as they come."""
        gp = self._gp_module()

        def added(kind: int, data: Any) -> bool:
            if kind == gp.GP_EVENT_FILE_ADDED:
                seen.append((data.folder, data.name))
            return self._pick(seen) is not None

        picked = self._pick(seen)
        while picked is None:                       # _wait_until returns once one arrived, or raises
            kind = "raw file" if self.expects_raw else "file"
            self._wait_until(added, timeout_s, "capture: wait for the captured file",
                             f"no {kind} arrived within {{s:.0f}} s after the exposure ended" +
                             (f" (only {', '.join(n for _, n in seen)})" if seen else ""))
            picked = self._pick(seen)
        return picked

    def _rest_of_capture(self, seen: list[tuple[str, str]], taken: tuple[str, str]) -> list[tuple[str, str]]:
        """The capture's other files (the JPEG of a NEF+JPEG pair): waited for briefly, drained, reported."""
        others = [f for f in seen if f != taken]
        gp = self._gp_module()

        def partner(kind: int, data: Any) -> bool:
            if kind == gp.GP_EVENT_FILE_ADDED:
                others.append((data.folder, data.name))
            return bool(others)

        if self.stores_pairs and not others:
            try:
                self._wait_until(partner, self.pair_timeout_s, "capture: wait for the pair's second file",
                                 "the second file of the raw+JPEG pair did not arrive within {s:g} s")
            except CameraError as exc:
                log.info("%s", exc)
        others += [f for f in self._drain_events() if f != taken]
        if others:
            log.warning("the camera also stored %s (image quality %s; set %s only)",
                        ", ".join(n for _, n in others), self.image_quality or "?", RAW_QUALITY)
        return others

    def download(self, folder: str, name: str) -> tuple[bytes, str]:
        """One file from the camera into memory: (bytes, MIME type)."""
        cam = self._require_open()
        gp = self._gp_module()
        cfile = self._call(f"download {folder}/{name}", cam.file_get, folder, name, gp.GP_FILE_TYPE_NORMAL,
                           deadline_s=self.download_timeout_s)
        data = bytes(memoryview(cfile.get_data_and_size()))
        return data, cfile.get_mime_type()

    def list_files(self, folder: str = "/") -> list[str]:
        """Paths of every file on the camera below ``folder``."""
        cam = self._require_open()
        out: list[str] = []
        stack = [folder]
        while stack:
            f = stack.pop(0)
            files = self._call(f"list {f}", cam.folder_list_files, f)
            out += [f.rstrip("/") + "/" + files.get_name(i) for i in range(files.count())]
            sub = self._call(f"list {f}", cam.folder_list_folders, f)
            stack += [f.rstrip("/") + "/" + sub.get_name(i) for i in range(sub.count())]
        return out
