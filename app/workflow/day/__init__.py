"""The day and its queue: the originals of a day's queue read, planned before the light and run, and the day's file that
brings a session, its calibration and its queue back after a restart.
"""
