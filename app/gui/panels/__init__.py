"""The copy-stand window's panels, one module each; they only wire widgets to the Qt-free packages."""
