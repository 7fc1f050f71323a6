"""Capture sessions: the crash-safe session folder (:mod:`core.session.capture_session`), its append-only
manifest and definition rules (:mod:`core.session.manifest`), the one-writer OS lock (:mod:`core.session.lock`),
the session's log file (:mod:`core.session.log`) and the light dose of its lit periods
(:mod:`core.session.light_dose`)."""
