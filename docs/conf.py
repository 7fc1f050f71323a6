"""Sphinx configuration of the user docs (`make docs`: build/docs; `make test` builds it with warnings as errors).

Pages are Markdown (MyST). The command reference is generated from the CLI's parser (sphinx-argparse over
``dualrgb.app.cli.build_parser``); figures quoted in the text come from committed JSON through the ``json``
role of ``_ext/jsonfigures.py``, and the generated tables are written into the pages by the commands that make
them (tests check the pages hold what the generators write).
"""
from __future__ import annotations

import sys
from importlib.metadata import version as _installed_version
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))        # jsonfigures


project = "dualrgb"
author = "the dualrgb developers"
copyright = "the dualrgb developers, BSD 3-Clause"
release = version = _installed_version("dualrgb")     # `make venv` installs it editable

extensions = ["myst_parser", "sphinxarg.ext", "jsonfigures"]
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3
source_suffix = {".md": "markdown"}
root_doc = "index"
# the developers' notes are the material the pages were written from, not pages; docs/data holds study runs
exclude_patterns = ["_build", "notes/**", "data/**", "screenshots/**", "figures/**"]
suppress_warnings: list[str] = []
# quotes and ellipses only: "--method" in a command's help text must stay two hyphens, not an en dash
smartquotes_action = "qe"

html_theme = "furo"
html_title = f"dualrgb {release}"
html_static_path: list[str] = []
