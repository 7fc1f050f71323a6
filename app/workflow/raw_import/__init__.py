"""Raw files from another program: the roles file, every check before anything is written, the copy into a session and
the same calibration and delivery as a captured day.
"""
