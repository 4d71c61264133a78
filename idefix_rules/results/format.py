"""What a results file is: its name and version, run status codes, the precision each run
signal is stored with (layout in ``docs/results-format.md``).

Shared by the writer (:mod:`idefix_rules.campaign.storage.store`) and every reader, so neither side
spells a code or a version of its own.
"""

from __future__ import annotations

from typing import Any

import numpy as np

FORMAT = "idefix-results"
FORMAT_VERSION = 5
# Files a --resume continues: format 2 allocated every run at the start, which format 3 reads
# as one block holding every row; formats 2 and 3 hold no terrain, which a resume stores
# (format 4: idefix_rules.results.terrain); the run datasets of formats 2 to 4 keep the
# precision they were made with (format 5 stores z and energy as float32).
RESUMABLE_FORMAT_VERSIONS = (2, 3, 4, 5)

STATUS_MISSING = 0
STATUS_COMPLETE = 1
STATUS_FAILED = 2
STATUS_NOT_NEEDED = 3  # an adaptive campaign stopped its path before this run

# Read through max / percentile / comparisons or as small angles, never differentiated as
# large values: float32 keeps them to 6e-8 of their value (a tilt of 0.1 rad to 6e-9 rad), far
# inside any rulebook tolerance (docs/results-format.md). The height z only adds to a position
# (3e-8 m at 0.5 m) and the cumulative charge is read at a run's end (6e-8 of it); the
# planar position, heading and time, which are differentiated, stay float64.
FLOAT32_SIGNALS = frozenset({"wheel.rate", "wheel.slip", "wheel.slip_angle", "wheel.sinkage",
                             "wheel.current", "command", "stuck", "roll", "pitch", "z",
                             "energy"})
COMPRESSION = "gzip"
COMPRESSION_LEVEL = 1

# The stretches a run's clearance profile has (evaluation/collisions/clearance_profile): its
# samples in this many equal parts, the smallest clearance of any body part in each (what
# the report's run panel draws).
CLEARANCE_POINTS = 120

CHAIN_COLUMNS = ("max_wheel_rate", "delta_position", "delta_heading")
CHAIN_UNITS = ("rad/s", "m", "rad")


def storage_dtype(name: str) -> np.dtype[Any]:
    """The dtype a run signal is stored with (float32 where that is enough, else float64)."""
    return np.dtype(np.float32 if name in FLOAT32_SIGNALS else np.float64)


def decode_reason(value: bytes) -> str:
    """A stored failure reason (fixed-size, NUL-padded UTF-8) as text."""
    return bytes(value).rstrip(b"\0").decode("utf-8", errors="replace")

# ``runs_mode`` of a worst-case search's results file (``idefix-verify worst``): its runs are
# searched worlds, not Monte Carlo draws.
SEARCHED_RUNS = "worst"
# A search's own record beside its results.h5; a campaign never writes one
SEARCH_RECORD_FILE = "worst.json"


def attribute_text(value: Any) -> str:
    """An HDF5 string attribute as text, whether h5py gives it as str or bytes."""
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def is_search(attrs: Any) -> bool:
    """Whether a results file's root attributes are a worst-case search's."""
    return str(attrs.get("runs_mode", "fixed")) == SEARCHED_RUNS


def drawn_paired(attrs: Any) -> bool:
    """Whether run ``j`` of every path was simulated in the same drawn world (the root
    attribute ``paired``). Never for a worst-case search, whose paths search their worlds
    apart: its files written before the search stored ``paired`` false claim it true."""
    return bool(attrs.get("paired", False)) and not is_search(attrs)
