"""dualrgb application layer: sessions, sequences, processing, CLI and the Qt GUI (gui/ is the only Qt user)."""
