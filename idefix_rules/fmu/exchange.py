"""One run of a model-exchange FMU (FMI 2.0 or 3.0) with fmpy's own solver (CVode).

A model-exchange FMU has no solver inside: fmpy integrates it (:func:`fmpy.simulate_fmu`),
instantiating it for every run. Set-points fed as inputs are held over each communication step
(two input rows per step boundary, which fmpy reads as a discontinuity); outputs are sampled on
the same grid, events not recorded, so a run has exactly ``steps + 1`` samples like a
co-simulation run.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.errors import InfrastructureError
from idefix_rules.fmu.binding import corrupts_process
from idefix_rules.fmu.description import FmuVariable


def _fmpy_description(unzipped: str) -> Any:
    """fmpy's reading of the model description of an extracted FMU, once per process and
    version of the file (an extraction folder is replaced when its FMU is)."""
    stamp = (Path(unzipped) / "modelDescription.xml").stat().st_mtime_ns
    return _read_description(unzipped, stamp)


@functools.lru_cache(maxsize=4)
def _read_description(unzipped: str, stamp: int) -> Any:
    from fmpy import read_model_description

    return read_model_description(unzipped, validate=False)


def simulate_model_exchange(unzipped: Path, name: str,
                            start: Sequence[tuple[FmuVariable, float | int | str]],
                            feed: Sequence[tuple[FmuVariable, np.ndarray]],
                            outputs: Sequence[FmuVariable], steps: int,
                            interval: float) -> list[np.ndarray]:
    """The outputs' columns (``steps + 1`` samples each, in ``outputs`` order)."""
    from fmpy import instantiate_fmu, simulate_fmu
    from fmpy.fmi1 import FMICallException

    signal = None
    if feed and steps > 0:
        edges = np.arange(steps + 1) * interval
        signal = np.zeros(2 * steps, dtype=[("time", np.float64)]
                          + [(variable.name, np.float64) for variable, _ in feed])
        signal["time"] = np.repeat(edges, 2)[1:-1]
        for variable, values in feed:
            signal[variable.name] = np.repeat(np.asarray(values[:steps], dtype=float), 2)
    names = list(dict.fromkeys(variable.name for variable in outputs))
    description = _fmpy_description(str(unzipped))
    instance = None
    try:
        # instantiated here, not by fmpy: fmpy frees an instance it made only when the run
        # succeeds, so every failed run left one allocated in the worker for good
        instance = instantiate_fmu(str(unzipped), description, "ModelExchange",
                                   require_functions=False)
        result = simulate_fmu(
            str(unzipped), validate=False, fmi_type="ModelExchange", solver="CVode",
            start_values={variable.name: value for variable, value in start},
            input=signal, output=names, stop_time=steps * interval,
            output_interval=interval, record_events=False, model_description=description,
            fmu_instance=instance)
    except Exception as failure:  # fmpy raises plain exceptions for failed FMI calls
        if instance is not None and isinstance(failure, FMICallException) and \
                not corrupts_process(failure.status):
            # an Error leaves the instance to be freed (FMI 2.0.4 and 3.0: fmi2FreeInstance
            # is allowed after it); after Fatal, or a failure inside the solver's callbacks
            # (its status unknown), no call is allowed and the process is retired instead
            with contextlib.suppress(Exception):
                instance.freeInstance()
        # the cause stays: a failed call's status says what it left (binding.corrupts_process)
        raise InfrastructureError(f"{name}: model exchange simulation failed ({failure})") \
            from failure
    instance.freeInstance()  # fmpy terminated it at the run's end
    if len(result) != steps + 1:
        raise InfrastructureError(f"{name}: the solver returned {len(result)} samples, "
                                  f"expected {steps + 1}")
    return [np.asarray(result[variable.name]) for variable in outputs]
