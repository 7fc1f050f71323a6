"""``python -m dualrgb``: the command line (same as the ``dualrgb`` script)."""
import sys

from dualrgb.app.cli import main

sys.exit(main())
