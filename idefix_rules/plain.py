"""Plain data: the JSON-ready form of the project's records (dataclasses, numpy values)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np


def as_plain(obj: Any) -> Any:
    """JSON-ready form of the rulebook's dataclasses (statistics, verdicts) and of numpy
    values: dicts, lists, numbers, strings; a float that is not finite becomes None.

    >>> as_plain({"a": np.float64(0.5), "b": (1, np.nan)})
    {'a': 0.5, 'b': [1, None]}
    """
    to_dict = getattr(obj, "to_dict", None)
    if callable(to_dict):
        return as_plain(to_dict())
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: as_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        return {str(k): as_plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [as_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj
