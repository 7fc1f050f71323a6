"""What every layer of dualrgb uses and nothing of dualrgb's own: atomic file writes (:mod:`common.atomic_files`),
the mark of errors meant for the user (:mod:`common.errors`)
and progress reporting with cancellation (:mod:`common.progress`). It imports no other dualrgb package."""
