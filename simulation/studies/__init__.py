"""Studies around the light-source search (``dualrgb study ...``): Qt-free, each writes JSON, PNG charts and a
short Markdown summary into an output folder.

* :mod:`.speed_accuracy` - best error against wall time and evaluations for every optimiser;
* :mod:`.stability` - seed spread, LED clipping, dim LEDs, noise / drift / target sensitivity, and the
  noise-aware objective (:mod:`.noise`);
* :mod:`.parsimony` - coarsest spectral step, simplest characterisation model, fewest HDR exposures;
* :mod:`.spectral` - spectral estimation methods x lights chosen for colour or for spectra (and 3-channel);
* :mod:`.unbinned` - the full-intensity search over all ~523 k unbinned pairs, serial or through Dask
  (:mod:`.distributed`).
"""
