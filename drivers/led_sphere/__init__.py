"""The 10-LED integrating sphere over serial: protocol table, driver (LedSphere) and its one error (SphereError)."""
from drivers.led_sphere.driver import LedSphere
from drivers.led_sphere.errors import SphereError

__all__ = ["LedSphere", "SphereError"]
