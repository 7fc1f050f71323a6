"""dualrgb: dual-RGB multispectral capture with an LED integrating sphere.

One import namespace over the repository's top-level folders (pyproject.toml maps them at install time):
``dualrgb.simulation`` (spectral simulation, characterisation, searches and optimisers), ``dualrgb.drivers``
(sphere, camera, raw files, virtual lab), ``dualrgb.app`` (the Qt-free workflow, the command line and the Qt GUI),
``dualrgb.common`` (atomic files, progress and cancel) and ``dualrgb.resources`` (packaged data).
Nothing is imported here: ``dualrgb --help`` starts without numpy or Qt.
"""
