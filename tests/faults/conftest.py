"""Fault-injection tests (issue 9's reliability table): the virtual lab with small frames and short light limits."""
from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest  # noqa: E402

from app.sequences.shooter import Shooter  # noqa: E402
from app.session import CaptureSession  # noqa: E402
from app.virtual_lab import VirtualLab  # noqa: E402
from light_record import FAST  # noqa: E402


@pytest.fixture()
def lab():
    with VirtualLab(frame_size=(96, 64), timeout_s=0.3) as lab:
        yield lab
        lab.camera.inject(None)             # release a camera left hanging
        lab.emulator.inject(None)


@pytest.fixture()
def shooter(lab, tmp_path):
    session = CaptureSession.create(tmp_path / "session", {"test": "light safety"})
    return Shooter(lab.camera, lab.sphere, session, stand=lab.place, safety=FAST)
