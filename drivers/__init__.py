"""Qt-free hardware drivers: LED sphere (serial), camera (gphoto2), raw loading, USB discovery, virtual devices."""
