"""Assumed against simulated slip: the rulebook's ``theoretical_slip`` beside the reference run's.

The theoretical path (``theory.*``, ``local_error``) shortens every command's travel by the
rulebook's assumed fixed slip *s* (``scale = 1 - s``). When the rover model slips much less (or
more), every local error measures that assumption rather than the drive. So each simulated path
reports the slip its **reference run** (nominal values) actually had, measured the way the
theoretical path uses it:

* ``measured`` — effective slip: ``1 - travelled / commanded``, where *commanded* is the
  ``Σ |delta_position|`` of the chain's translating commands and *travelled* the body centre's
  planar path length while those commands were active (``command`` signal). A chain of point
  turns only uses the heading instead: ``1 - Σ |Δyaw| / Σ |delta_heading|``.
* ``wheel_slip`` — for information: the mean longitudinal slip ratio (``wheel.slip``) of the four
  wheels over the samples where a command is active.

When ``|measured - assumed| > SLIP_MARGIN`` the campaign warns (console, ``summary.json`` under
``slip``, the HTML report) and names the setting to change. A reference run that cannot be
measured (a foreign FMU's map without ``command``, a chain that commands no motion) is *not
measured*, with the reason (``not_measured``): neither agreeing nor disagreeing.

>>> import numpy as np
>>> from idefix_rules.commands import Command
>>> reference = {"x": np.array([0.0, 0.4, 0.8, 0.8]), "y": np.zeros(4),
...              "command": np.array([0, 0, 0, -1])}
>>> round(effective_slip(reference, (Command(0.05, 1.0, 0.0),)), 3)
0.2
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.commands import Command

SLIP_MARGIN = 0.05  # 5 percentage points between assumed and measured slip
SETTING = "theoretical_slip"


@dataclass(frozen=True)
class SlipCheck:
    """One path: the rulebook's assumed slip beside its reference run's measured slip."""

    path: str
    assumed: float
    measured: float | None
    wheel_slip: float | None
    margin: float = SLIP_MARGIN
    rulebook: str = "the rulebook"
    not_measured: str | None = None  # why ``measured`` is None (None when measured)

    @property
    def disagrees(self) -> bool:
        return self.measured is not None and abs(self.measured - self.assumed) > self.margin

    @property
    def warning(self) -> str | None:
        if not self.disagrees or self.measured is None:
            return None
        return (f"{self.path}: the reference run slipped {100 * self.measured:.1f} % "
                f"(effective, along the path) but {self.rulebook} assumes {SETTING} = "
                f"{100 * self.assumed:.1f} % for the theoretical path: they differ by more "
                f"than {100 * self.margin:.0f} %, so local errors "
                f"measure the assumption; set `{SETTING} = {100 * max(self.measured, 0.0):.0f} %` "
                f"in the "
                f"rulebook's settings if this reference run is representative")

    def to_dict(self) -> dict[str, Any]:
        return {"path": self.path, "assumed": self.assumed, "measured": _finite(self.measured),
                "wheel_slip": _finite(self.wheel_slip), "margin": self.margin,
                "setting": SETTING, "disagrees": self.disagrees, "warning": self.warning,
                "not_measured": self.unmeasured_reason}

    @property
    def unmeasured_reason(self) -> str | None:
        """Why nothing was measured (None when something was)."""
        if self.measured is not None and math.isfinite(self.measured):
            return None
        return self.not_measured or "the reference run gives no effective slip"


def slip_warning(checks: Sequence[SlipCheck]) -> str | None:
    """One warning for every path whose reference run disagrees with the assumed slip (the
    assumption is the rulebook's, so it is said once, not once per path); None when all agree.

    >>> checks = [SlipCheck("a", 0.2, 0.111, None, rulebook="rulebook r 1.0.0"),
    ...           SlipCheck("b", 0.2, 0.19, None), SlipCheck("c", 0.2, 0.01, None)]
    >>> print(slip_warning(checks))  # doctest: +NORMALIZE_WHITESPACE
    the reference runs slipped a 11.1 %, c 1.0 % (effective, along the path) but rulebook r
    1.0.0 assumes theoretical_slip = 20.0 % for the theoretical path: they differ by more than
    5 %, so local errors measure the assumption; set `theoretical_slip = 11 %` (a) or `1 %` (c)
    in the rulebook's settings if that reference run is representative
    """
    off = [c for c in checks if c.disagrees and c.measured is not None]
    if not off:
        return None
    if len(off) == 1:
        return off[0].warning
    first = off[0]
    slipped = ", ".join(f"{c.path} {100 * (c.measured or 0.0):.1f} %" for c in off)
    settings = [f"{100 * max(c.measured or 0.0, 0.0):.0f} %" for c in off]
    choices = [f"`{SETTING} = {settings[0]}` ({off[0].path})"]
    choices += [f"`{value}` ({c.path})" for value, c in zip(settings[1:], off[1:], strict=True)]
    said = ", ".join(choices[:-1]) + f" or {choices[-1]}"
    return (f"the reference runs slipped {slipped} (effective, along the path) but "
            f"{first.rulebook} assumes {SETTING} = {100 * first.assumed:.1f} % for the "
            f"theoretical path: they differ by more than {100 * first.margin:.0f} %, so local "
            f"errors measure the assumption; set {said} in the rulebook's settings if that "
            "reference run is representative")


def unmeasured_text(checks: Sequence[SlipCheck]) -> str | None:
    """``not measured for PATHS: REASON`` for the paths whose reference run gave no slip, one
    group per reason; None when every path was measured.

    >>> print(unmeasured_text([SlipCheck("a", 0.0, None, None, not_measured="no 'command'"),
    ...                        SlipCheck("b", 0.0, None, None, not_measured="no 'command'"),
    ...                        SlipCheck("c", 0.0, 0.01, None)]))
    not measured for a, b: no 'command'
    """
    reasons: dict[str, list[str]] = {}
    for check in checks:
        reason = check.unmeasured_reason
        if reason is not None:
            reasons.setdefault(reason, []).append(check.path)
    if not reasons:
        return None
    return "not measured for " + "; for ".join(f"{', '.join(paths)}: {reason}"
                                               for reason, paths in reasons.items())


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def effective_slip(reference: Mapping[str, np.ndarray], chain: Sequence[Command]
                   ) -> float | None:
    """``1 - travelled / commanded`` of a reference run (see the module docstring); None
    when the run lacks the signals or the chain commands no motion
    (:func:`slip_measurement` says which)."""
    return slip_measurement(reference, chain)[0]


def slip_measurement(reference: Mapping[str, np.ndarray], chain: Sequence[Command]
                     ) -> tuple[float | None, str | None]:
    """The effective slip of a reference run and, when there is none, why.

    Without ``command`` the samples cannot be told apart by command: the run's own timing
    (an FMU's controller, a rover that slips) need not be the chain's ideal one.

    >>> value, why = slip_measurement({"x": np.zeros(3), "y": np.zeros(3)},
    ...                               (Command(0.05, 1.0, 0.0),))
    >>> print(value, why)  # doctest: +NORMALIZE_WHITESPACE
    None the reference run has no 'command' (the FMU's signal map does not provide it), so which
    command was active at each sample is not known
    """
    missing = [name for name in ("x", "y", "command") if name not in reference]
    if missing:
        listed = ", ".join(f"'{name}'" for name in missing)
        why = "it" if len(missing) == 1 else "them"
        said = ", so which command was active at each sample is not known" \
            if "command" in missing else ""
        return None, (f"the reference run has no {listed} (the FMU's signal map does not provide "
                      f"{why}){said}")
    command = np.rint(np.asarray(reference["command"], dtype=float)).astype(int)
    x, y = np.asarray(reference["x"], dtype=float), np.asarray(reference["y"], dtype=float)
    step = np.hypot(np.diff(x), np.diff(y))  # step i → i+1 belongs to command[i]
    translating = [k for k, c in enumerate(chain) if c.delta_position != 0.0]
    if translating:
        commanded = sum(abs(chain[k].delta_position) for k in translating)
        travelled = float(step[np.isin(command[:-1], translating)].sum())
    else:
        turning = [k for k, c in enumerate(chain) if c.delta_heading != 0.0]
        if not turning:
            return None, "the chain commands no motion"
        if "yaw" not in reference:
            return None, ("the chain only turns on the spot and the reference run has no 'yaw' "
                          "(the FMU's signal map does not provide it)")
        commanded = sum(abs(chain[k].delta_heading) for k in turning)
        turned = np.abs(np.diff(np.asarray(reference["yaw"], dtype=float)))
        travelled = float(turned[np.isin(command[:-1], turning)].sum())
    value = 1.0 - travelled / commanded
    if not math.isfinite(value):
        return None, "the reference run's pose is not finite"
    return value, None


def mean_wheel_slip(reference: Mapping[str, np.ndarray]) -> float | None:
    """Mean ``wheel.slip`` of the four wheels while a command is active (None: not stored)."""
    if "wheel.slip" not in reference or "command" not in reference:
        return None
    active = np.rint(np.asarray(reference["command"], dtype=float)) >= 0
    slip = np.asarray(reference["wheel.slip"], dtype=float)[active]
    value = float(np.mean(slip)) if slip.size else math.nan
    return value if math.isfinite(value) else None


def slip_checks(store: Any, assumed: float, rulebook: str = "the rulebook"
                ) -> list[SlipCheck]:
    """A :class:`SlipCheck` per path of a results file that has a reference run."""
    checks = []
    for name in store.path_names:
        reference = store.reference(name)
        if reference is None:
            continue
        group = store.path_group(name)
        chain = tuple(Command(*map(float, row)) for row in group["chain"][()])
        measured, why = slip_measurement(reference, chain)
        checks.append(SlipCheck(name, assumed, measured, mean_wheel_slip(reference),
                                rulebook=rulebook, not_measured=why))
    return checks


def stored_records(file: Any) -> list[dict[str, Any]]:
    """The slip records (:meth:`SlipCheck.to_dict`) of a results file's stored summary."""
    evaluation = file.get("evaluation") if file is not None else None
    try:
        summary = json.loads(str(evaluation.attrs.get("summary", "{}"))) if evaluation else {}
    except ValueError:
        return []
    records = (summary.get("slip") or {}).get("paths", []) if isinstance(summary, dict) else []
    return [record for record in records if isinstance(record, dict)]
