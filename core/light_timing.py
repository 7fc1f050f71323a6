"""The light's default timing, the one place it is set (standard library only: the command line shows it before any
heavy import): after switching the light on, the wait before the shutter opens."""
SETTLE_S = 0.2                  # light on -> shutter (core.light_safety.SafetySettings, app.workflow.stand.defaults)
