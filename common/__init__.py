"""What every layer of dualrgb uses and nothing of dualrgb's own: atomic file writes (:mod:`common.atomic_files`)
and progress reporting with cancellation (:mod:`common.progress`). It imports no other dualrgb package."""
