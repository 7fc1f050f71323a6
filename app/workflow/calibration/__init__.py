"""The calibration: the profile (checked on every load and reuse), the targets and the stand's own charts, the one
processing path of a session's frames, the stand model fitted to the captures, the LED and camera measurements.
"""
