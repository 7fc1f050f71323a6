"""The copy stand: the devices opened, sessions made, the stand's rules before the light (metering, plans, preflight,
the mode rule, the light held by hand) and CopyStand, the one object every front end drives.
"""
