"""Camera drivers: one interface (base.Camera), a gphoto2 implementation and the virtual lab camera."""
from dualrgb.drivers.camera.base import Camera, CameraError, CameraSettings, RawCapture

__all__ = ["Camera", "CameraError", "CameraSettings", "RawCapture"]
