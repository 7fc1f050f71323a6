"""dualrgb.core: the low layer every other imports, importing none of them - the vocabulary (roles, step ids,
light names, subjects, an original's identifier and file names), the run engine with its messages and its
hands (the only code that acts on a device), the light-on rule, the device protocols and the crash-safe
capture session. It imports only common, drivers, simulation and resources (tests/test_layers.py)."""
