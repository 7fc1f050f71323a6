"""The copy-stand workflow (Qt-free): the one layer the GUI, the CLI and the demo call, split by subject.

* :mod:`app.workflow.stand` - the devices opened, sessions made, the rules before the light, and
  :class:`~app.workflow.stand.copystand.CopyStand`: calibrate once, capture and deliver many originals;
* :mod:`app.workflow.calibration` - the profile (checked on every load and reuse), the targets and the stand's own
  charts, the one processing path of a session's frames, the stand model;
* :mod:`app.workflow.delivery` - the deliverables of an original (masters, sidecar, fixity), re-delivery, bags;
* :mod:`app.workflow.day` - the day's queue and the day file that brings a session back after a restart;
* :mod:`app.workflow.raw_import` - raw files shot by another program, checked, copied and delivered.

Below it, :mod:`core` holds the vocabulary (roles, subjects, light names, step ids), the run engine (the only code
that acts on a device), the light-on rule, the device protocols and the capture session.

Import the submodules themselves; this package imports nothing so its vocabulary stays cheap to load.
"""
