"""The 10-LED integrating sphere over serial: protocol table, driver (LedSphere), its one error (SphereError),
what is known after switching it off (LightReport) and the host's on-time supervisor."""
from drivers.led_sphere.driver import LedSphere
from drivers.led_sphere.errors import LightReport, SphereError

__all__ = ["LedSphere", "LightReport", "SphereError"]
