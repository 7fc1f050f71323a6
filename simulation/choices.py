"""The names a user chooses from (target modes, search methods), importable without numpy or colour-science so
the CLI can offer them before anything heavy loads; simulation.datasets and simulation.runner use these."""
from __future__ import annotations

MODES = ("reflective", "transmissive")                     # reflective targets or film (transmissive), thesis 5.2
METHODS = ("three-channel", "exhaustive", "pso", "ga")    # simulation.runner.run
