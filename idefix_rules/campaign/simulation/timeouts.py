"""The run timeout: a run taking longer is ended and recorded as failed (local pool and Dask).

``--run-timeout SECONDS`` sets it for every run; ``--run-timeout 0`` disables it. Without the
option each run gets a default, so a hanging FMU never blocks a campaign:

* a reference run (nothing measured yet) may take :data:`REFERENCE_PER_SIMULATED_SECOND` wall
  seconds per simulated second of its path, and at least :data:`REFERENCE_FLOOR`;
* a Monte Carlo run may take :data:`FACTOR` times what the campaign's reference runs cost per
  simulated second, times its path's simulated duration, and at least :data:`FLOOR`.

Defaults are rounded up to the series 1, 2, 5, 10, 20, 50 … s, so the small jitter of a
measurement does not change the timeout (nor the failure reason that names it).

>>> monte_carlo_timeout(stop_time=300.0, cost=0.0004, option=None)
20.0
>>> monte_carlo_timeout(stop_time=300.0, cost=0.05, option=None)
500.0
>>> reference_timeout(stop_time=30.0, option=None), reference_timeout(30.0, 0.0)
(50.0, None)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from typing import Any, Protocol

FLOOR = 20.0  # s
FACTOR = 20.0
REFERENCE_FLOOR = 50.0  # s (FLOOR and this are steps of the series below)
REFERENCE_PER_SIMULATED_SECOND = 1.0
COST_ATTRIBUTE = "reference_seconds"  # a path's measured reference run, stored on the path


class _Plan(Protocol):
    @property
    def stop_time(self) -> float: ...


def nice_ceiling(seconds: float) -> float:
    """The smallest of 1, 2, 5, 10, 20, 50 … that is at least ``seconds``."""
    if seconds <= 1.0:
        return 1.0
    decade = 10.0 ** math.floor(math.log10(seconds))
    for step in (1.0, 2.0, 5.0, 10.0):
        if step * decade >= seconds * (1 - 1e-12):
            return step * decade
    return 10.0 * decade  # pragma: no cover - the loop always returns


def explicit(option: float | None) -> tuple[bool, float | None]:
    """``(given, timeout)`` for the ``--run-timeout`` value (0 means no timeout)."""
    if option is None:
        return False, None
    return True, (option if option > 0 else None)


def reference_timeout(stop_time: float, option: float | None) -> float | None:
    """The timeout of a reference run of a path simulating ``stop_time`` seconds."""
    given, value = explicit(option)
    if given:
        return value
    return nice_ceiling(max(REFERENCE_FLOOR, stop_time * REFERENCE_PER_SIMULATED_SECOND))


def setup_timeout(option: float | None) -> float | None:
    """The timeout of setting the FMU up with no step simulated (the probe before the
    reference runs, the extreme draws' checks): :data:`REFERENCE_FLOOR`, or the option.

    >>> setup_timeout(None), setup_timeout(2.0), setup_timeout(0.0)
    (50.0, 2.0, None)
    """
    given, value = explicit(option)
    return value if given else REFERENCE_FLOOR


def monte_carlo_timeout(stop_time: float, cost: float | None,
                        option: float | None) -> float | None:
    """The timeout of a Monte Carlo run; ``cost`` is the measured wall seconds per simulated
    second of the reference runs (None: not measured, the reference run's timeout applies)."""
    given, value = explicit(option)
    if given:
        return value
    if cost is None:
        return reference_timeout(stop_time, option)
    return nice_ceiling(max(FLOOR, FACTOR * cost * stop_time))


def measured_cost(costs: Sequence[tuple[float, float]]) -> float | None:
    """Wall seconds per simulated second over ``(seconds, stop_time)`` of reference runs."""
    simulated = sum(stop for _, stop in costs)
    if not costs or simulated <= 0:
        return None
    return sum(seconds for seconds, _ in costs) / simulated


def reference_timeouts(plans: dict[str, Any],
                       option: float | None) -> Callable[[Hashable], float | None]:
    """Timeout per reference task (keyed by path name)."""
    return lambda key: reference_timeout(float(plans[str(key)].stop_time), option)


def monte_carlo_timeouts(plans: dict[str, Any], store: Any,
                         option: float | None) -> Callable[[Hashable], float | None]:
    """Timeout per Monte Carlo task (keyed ``(path, run)``), from the stored reference costs."""
    costs = []
    for name, plan in plans.items():
        seconds = store.path_group(name).attrs.get(COST_ATTRIBUTE) \
            if store.has_path(name) else None
        if seconds is not None:
            costs.append((float(seconds), float(plan.stop_time)))
    cost = measured_cost(costs)

    def timeout(key: Hashable) -> float | None:
        name = key[0] if isinstance(key, tuple) else key
        return monte_carlo_timeout(float(plans[str(name)].stop_time), cost, option)

    return timeout
