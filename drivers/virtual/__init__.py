"""Virtual lab devices: the LED sphere emulator, the virtual D610 camera and the copy-stand scene it photographs."""
