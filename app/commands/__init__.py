"""One module per ``dualrgb`` subcommand; each exposes ``register(subparsers)`` (see app/cli.py)."""
