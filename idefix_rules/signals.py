"""The signal contract: the names rulebooks speak of, with units and axes.

Rulebooks never name FMU variables. A run's data is a mapping from these names to numpy arrays
vectorised across runs: axis 0 is always the run, then the axes listed here in order. ``time``
is the sample axis, ``wheel`` has the labels of :data:`AXIS_LABELS` (FL, FR, RL, RR), and so on.

Three kinds of signal:

* ``fmu``: produced by the rover FMU (mapped from its variable names by the campaign);
* ``derived``: computed by the evaluator from fmu signals and the run context
  (``ref.*``, theoretical path, errors, drift, tolerance radius, speed, acceleration);
* ``collision``: provided by the obstacle checker (:mod:`idefix_rules.obstacles`).

>>> SIGNALS["wheel.slip"].axes
('time', 'wheel')
>>> SIGNALS["collision.hits"].axes
('part', 'level')
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from idefix_rules.units import Dimension, parse_unit

Kind = Literal["fmu", "derived", "collision"]

AXIS_LABELS: dict[str, tuple[str, ...]] = {
    "wheel": ("FL", "FR", "RL", "RR"),
    "part": ("wheel", "solar_panel", "chassis"),
    "level": ("L1", "L2", "L3"),
}


@dataclass(frozen=True)
class SignalSpec:
    """One named signal: SI unit, axes after the run axis, who provides it."""

    name: str
    unit: str
    axes: tuple[str, ...]
    kind: Kind
    description: str

    @property
    def dimension(self) -> Dimension:
        return parse_unit(self.unit).dimension


def _specs(*specs: SignalSpec) -> dict[str, SignalSpec]:
    return {spec.name: spec for spec in specs}


FMU_SIGNALS = _specs(
    SignalSpec("t", "s", ("time",), "fmu", "simulation time"),
    SignalSpec("x", "m", ("time",), "fmu", "body centre position, start frame"),
    SignalSpec("y", "m", ("time",), "fmu", "body centre position, start frame"),
    SignalSpec("z", "m", ("time",), "fmu", "body centre height"),
    SignalSpec("roll", "rad", ("time",), "fmu", "body roll"),
    SignalSpec("pitch", "rad", ("time",), "fmu", "body pitch"),
    SignalSpec("yaw", "rad", ("time",), "fmu", "body yaw, unwrapped"),
    SignalSpec("wheel.rate", "rad/s", ("time", "wheel"), "fmu", "wheel angular rate"),
    SignalSpec("wheel.slip", "1", ("time", "wheel"), "fmu", "longitudinal slip ratio"),
    SignalSpec("wheel.slip_angle", "rad", ("time", "wheel"), "fmu", "wheel slip angle"),
    SignalSpec("wheel.sinkage", "m", ("time", "wheel"), "fmu", "wheel sinkage"),
    SignalSpec("wheel.current", "A", ("time", "wheel"), "fmu", "motor current"),
    SignalSpec("energy", "A·s", ("time",), "fmu", "cumulative charge drawn by the motors"),
    SignalSpec("command", "1", ("time",), "fmu", "index of the active command, -1 when done"),
    SignalSpec("stuck", "1", ("time",), "fmu", "1 while the controller reports the rover stuck"),
    SignalSpec("done", "1", ("time",), "fmu",
               "1 from the sample the FMU reports the chain complete (a mapped done/phase "
               "output; gives the run time when there is no 'command')"),
)

# Derived by the evaluator. ``ref.<name>`` exists for every fmu signal too (see REF_PREFIX).
DERIVED_SIGNALS = _specs(
    SignalSpec("theory.x", "m", ("time",), "derived", "theoretical path (assumed fixed slip)"),
    SignalSpec("theory.y", "m", ("time",), "derived", "theoretical path (assumed fixed slip)"),
    SignalSpec("theory.yaw", "rad", ("time",), "derived", "theoretical heading"),
    SignalSpec("local_error", "m", ("time",), "derived",
               "distance actual vs theoretical path (accuracy)"),
    SignalSpec("global_error", "m", ("time",), "derived",
               "distance actual vs reference run (spread)"),
    SignalSpec("drift", "m", ("time",), "derived",
               "what the drive adds to the start offset: displacement from its own start, in "
               "its start frame, vs the reference run's"),
    SignalSpec("tolerance_radius", "m", ("time",), "derived",
               "tolerance around the reference path, grows while turning"),
    SignalSpec("heading_error", "rad", ("time",), "derived", "yaw minus reference-run yaw"),
    SignalSpec("chain_done", "1", ("time",), "derived",
               "1 from the sample the chain is complete ('command' -1 after its start, else a "
               "mapped 'done', else the ideal schedule), 0 before"),
    SignalSpec("speed", "m/s", ("time",), "derived", "planar speed of the body centre"),
    SignalSpec("acceleration", "m/s^2", ("time",), "derived", "rate of change of speed"),
)

COLLISION_SIGNALS = _specs(
    SignalSpec("collision.hits", "1", ("part", "level"), "collision",
               "distinct obstacles hit per body part and level (n_obs,k,l)"),
    SignalSpec("collision.buffer", "1", ("part", "level"), "collision",
               "distinct buffer zones entered (without hitting the obstacle) per part and level"),
    SignalSpec("collision.contact", "1", ("time", "part", "level"), "collision",
               "1 at samples where the part intersects an obstacle of that level"),
    SignalSpec("collision.clearance", "m", ("time", "part"), "collision",
               "smallest distance from the part to any obstacle (negative never: 0 in contact)"),
)

REF_PREFIX = "ref."
# Signals of the rulebook's named areas (``area NAME …`` in its obstacles block), computed with
# the collision signals from the run's pose: ``area.NAME.inside`` is 1 while a wheel's ground
# contact point lies in the area, ``area.NAME.buffer`` 1 while one lies within the area's buffer
# of it (inside included). Only declared areas exist: the checker types them.
AREA_PREFIX = "area."
AREA_SIGNAL_PARTS: tuple[str, ...] = ("inside", "buffer")

SIGNALS: dict[str, SignalSpec] = {**FMU_SIGNALS, **DERIVED_SIGNALS, **COLLISION_SIGNALS}


def lookup(name: str) -> SignalSpec | None:
    """Spec of a signal name, including ``ref.*`` twins of fmu signals."""
    if name.startswith(REF_PREFIX):
        base = FMU_SIGNALS.get(name[len(REF_PREFIX):])
        if base is None:
            return None
        return SignalSpec(name, base.unit, base.axes, "derived",
                          f"reference run: {base.description}")
    area = area_signal(name)
    if area is not None:
        what = ("a wheel's contact point is in the area" if area[1] == "inside" else
                "a wheel's contact point is within the area's buffer")
        return SignalSpec(name, "1", ("time",), "collision", f"1 while {what} '{area[0]}'")
    return SIGNALS.get(name)


def area_signal(name: str) -> tuple[str, str] | None:
    """``("crater", "inside")`` for ``area.crater.inside``; None for other names."""
    if not name.startswith(AREA_PREFIX):
        return None
    area, _, part = name[len(AREA_PREFIX):].rpartition(".")
    if not area or part not in AREA_SIGNAL_PARTS or not area.isidentifier():
        return None
    return area, part
