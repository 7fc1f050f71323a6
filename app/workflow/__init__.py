"""The copy-stand workflow (Qt-free): the one layer the GUI, the CLI and the demo call.

* :mod:`app.workflow.vocabulary` - roles, subjects, light names, step ids, event kinds (and old sessions' strings);
* :mod:`app.workflow.targets` - colour targets: reference XYZ (with the stand's ND filter), TargetSpec;
* :mod:`app.workflow.coverage` - which exposures have darks and flats ("darks 2/4 exposures");
* :mod:`app.workflow.session_processing` - a session's frames grouped by subject and light, processed;
* :mod:`app.workflow.profile` - the calibration profile (versioned JSON + .npz) and its reuse checks;
* :mod:`app.workflow.delivery` - the deliverables of an original (TIFFs with tags, ICC and XMP, sidecar, QA);
* :mod:`app.workflow.copystand` - :class:`CopyStand`: calibrate once, capture and deliver many originals.

Import the submodules themselves; this package imports nothing so its vocabulary stays cheap to load.
"""
