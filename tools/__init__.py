"""Maintainer scripts (not shipped in the wheel): rebuild the packaged data under resources/."""
