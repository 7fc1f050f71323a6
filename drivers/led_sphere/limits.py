"""The host's limits for talking to the sphere, importable without pyserial or numpy (the CLI offers them while
it builds its parser): reply timeout and the on-time limit of each lit period (drivers.led_sphere.driver)."""
from __future__ import annotations

from dualrgb.drivers.led_sphere import protocol as P

DEFAULT_TIMEOUT_S = 1.0
DEFAULT_MAX_ON_S = 10.0        # per lit period (thesis 4.3.2: no LED drift in the first 10 s)
MAX_ON_RANGE_S = (P.ON_LIMIT_MIN_MS / 1000, P.ON_LIMIT_MAX_MS / 1000)
