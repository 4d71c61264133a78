"""The time stamps the results file keeps (started, finished, evaluated, resumed)."""

from __future__ import annotations

import datetime


def now_iso() -> str:
    """Now, in UTC, ISO 8601 to the second."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
