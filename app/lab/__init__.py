"""The virtual lab's front-end side: what the `dualrgb lab` commands, the `--virtual-lab` shorthand, the window
and the demo use, and nothing of the production workflow (app.workflow, app.processing, app.session,
app.sequences) ever imports (tests/test_layers.py holds it).

* :mod:`app.lab.process` - `dualrgb lab serve` as a child process, its instruments' addresses;
* :mod:`app.lab.score` - `dualrgb lab score SESSION`: deliverables against the lab's virtual originals;
* :mod:`app.lab.truth`, :mod:`app.lab.ground_truth`, :mod:`app.lab.spectral_truth` - the per-pixel comparisons;
* :mod:`app.lab.targets` - the lab's own grids and ND filter (the demo's study; the shorthand's grids).
"""
