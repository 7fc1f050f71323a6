"""Fixtures of the fault-injection suite (the marker and the reliability table: tests/faults/plugin.py)."""
from __future__ import annotations

import pytest

from fault_rigs import CountingCamera, CountingSphere


@pytest.fixture()
def rig():
    return CountingCamera(), CountingSphere()
