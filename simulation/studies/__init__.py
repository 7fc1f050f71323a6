"""Studies around the light-source search (``dualrgb study ...``): Qt-free, each writes JSON, PNG charts and a
short Markdown summary into an output folder.

* :mod:`.speed_accuracy` - best error against wall time and evaluations for every optimiser;
* :mod:`.stability` - seed spread, LED clipping, dim LEDs, noise / drift / target sensitivity, and the
  noise-aware objective (:mod:`.noise`);
* :mod:`.parsimony` - spectral grid, simplest characterisation model, fewest HDR exposures, per mode, chosen on
  training data (:mod:`.parsimony_report` writes it); :mod:`.hdr` - the HDR merge per mode, its bias with
  standard errors;
* :mod:`.spectral` - spectral estimation methods x lights chosen for colour or for spectra (and 3-channel);
* :mod:`.thesis` - the thesis' tables beside the project's figures (:mod:`.thesis_report`: rows, the docs page's table);
* :mod:`.unbinned` - the full-intensity search over all ~523 k unbinned pairs, serial or through Dask
  (:mod:`.distributed`).
"""
