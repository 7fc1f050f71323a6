"""A small saved calibration profile for the workflow and delivery tests (one light, 8 x 12 frames)."""
from __future__ import annotations

from datetime import UTC, datetime

import numpy as np

from dualrgb.app.processing.calibration import DarkFrame, FlatField, MasterDark
from dualrgb.app.workflow.calibration.profile import CalibrationProfile, CameraIdentity, SphereIdentity
from dualrgb.core.vocabulary import NamedLight
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.matrix_fit import CharacterisationMatrix

D65 = [95.047, 100.0, 108.883]


def make_profile(tmp_path, shape: tuple[int, int] = (8, 12), **over) -> CalibrationProfile:
    """The profile, its darks and white of ``shape``: the raw frames' (rows, columns), e.g. (64, 96) for the fault
    suite's virtual lab."""
    lights = [NamedLight("P light 1", LightSource((1, 6, 7), (0.0, 0.42, 1.0), "P light 1"))]
    darks = MasterDark()
    darks.put(DarkFrame(0.01, np.full(shape, 600, np.float32), 5))
    darks.put(DarkFrame(0.5, np.full(shape, 601, np.float32), 5))
    created = over.pop("created", datetime.now(UTC))
    prof = CalibrationProfile(
        id="cal-test", created_at=created.isoformat(timespec="seconds"), mode="reflective",
        camera=CameraIdentity("Nikon D610", "3012345", "60 mm", 50, 8.0), sphere=SphereIdentity("S", "1", "S-1", 25.0),
        preset="P", lights=lights, exposures={"P light 1": [0.01, 0.5]}, base_exposures={"P light 1": 0.01},
        matrix=CharacterisationMatrix(np.eye(3) * 90, ["R1", "G1", "B1"]),
        statistics={"best": "least-squares",
                    "methods": {"least-squares": {"train": {"mean": 0.4}, "test": {"mean": 0.3}}}},
        white_xyz=D65, raw={"white_level": 15520, "black_level": 600, "cfa": "RGGB", "linear_limit": 11000,
                            "shape": list(shape)}, sources={"0001_dark.dng": "ab" * 32}, ppi=300.0,
        darks=darks, whites={"P light 1": FlatField(np.full(shape, 1000.0, np.float32))}, **over)
    prof.save(tmp_path)
    return prof
