"""Capture sessions: the crash-safe session folder (:mod:`app.session.capture_session`), its append-only
manifest and definition rules (:mod:`app.session.manifest`), the one-writer OS lock (:mod:`app.session.lock`),
the session's log file (:mod:`app.session.log`) and the light dose of its lit periods
(:mod:`app.session.light_dose`)."""
