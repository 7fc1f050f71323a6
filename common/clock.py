"""The time written into outputs: the clock, or ``SOURCE_DATE_EPOCH`` when set (the reproducible-builds
convention, https://reproducible-builds.org/specs/source-date-epoch/), so that two runs over the same inputs can
write the same bytes (``dualrgb process`` serially, on worker processes or on a cluster)."""
from __future__ import annotations

import os
from datetime import UTC, datetime


def output_time() -> datetime:
    """Now (UTC), or ``SOURCE_DATE_EPOCH`` (whole seconds since 1970, UTC) when the environment sets it."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if not epoch:
        return datetime.now(UTC)
    try:
        return datetime.fromtimestamp(int(epoch), UTC)
    except (ValueError, OverflowError):
        raise ValueError(f"SOURCE_DATE_EPOCH={epoch!r}: expected whole seconds since 1970 (UTC)") from None
