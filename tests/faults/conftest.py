"""Fixtures of the fault-injection suite (the marker and the reliability table: tests/faults/plugin.py): counting
rigs, and the virtual lab with small frames and short light limits for the light-safety cases."""
from __future__ import annotations

import pytest
from fault_rigs import CountingCamera, CountingSphere
from light_record import FAST

from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.shooter import Shooter
from dualrgb.drivers.virtual.lab import VirtualLab


@pytest.fixture()
def rig():
    return CountingCamera(), CountingSphere()


@pytest.fixture()
def lab():
    with VirtualLab(frame_size=(96, 64), timeout_s=0.3) as lab:
        yield lab
        lab.camera.inject(None)             # release a camera left hanging
        lab.emulator.inject(None)


@pytest.fixture()
def shooter(lab, tmp_path):
    session = CaptureSession.create(tmp_path / "session", {"test": "light safety"})
    return Shooter(lab.camera, lab.sphere, session, safety=FAST)
