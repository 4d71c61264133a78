"""FMUs this project did not write the FMI side of, built at test time by exporters from the
package registry: ``pythonfmu`` (FMI 2.0 co-simulation) and ``pythonfmu3`` (FMI 3.0
co-simulation and model exchange). Their models are small planar kinematic rovers written in
Python below, with variable names, types and units of their own, as a flight team's model
would have.

* ``Unicycle`` (FMI 2.0): inputs ``v`` (body speed) and ``w`` (yaw rate), parameters ``x0``,
  ``y0`` and ``slip``; outputs ``px``, ``py`` (Real), ``heading`` (Real), ``phase`` (Integer:
  0 waiting, 1 driving, 2 stopped after driving), ``label`` (String); a String parameter
  ``site``.
* ``DiffDrive`` (FMI 3.0): inputs ``omega_l``, ``omega_r`` (wheel rates, rad/s), parameters
  ``track`` and ``radius`` (m), ``slip``; outputs ``pos_x``, ``pos_y`` in mm (Float64),
  ``psi`` (rad), ``arrived`` (Boolean), ``steps`` (Int32).
* ``Announcer`` (FMI 2.0): inputs ``v``, ``w``; outputs ``px``, ``py``, ``heading``, and the
  command it executes as many models report theirs: ``active`` (Integer: -1 before it moves,
  0 while the set-points move it, -1 after) and ``idle`` (Boolean: true before and after the
  drive). It checks itself for its first 2 s, standing still, before it follows the set-points.
* ``PlanarME`` (FMI 3.0 model exchange only): inputs ``v``, ``w``; states and outputs ``px``,
  ``py``, ``psi`` integrated by the importer (fmpy's CVode).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

UNICYCLE = '''
import math
from pythonfmu import Fmi2Causality, Fmi2Variability, Fmi2Slave, Real, Integer, String


class Unicycle(Fmi2Slave):
    author = "test"
    description = "planar kinematic rover driven by body speed and yaw rate"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.v = 0.0
        self.w = 0.0
        self.x0 = 0.0
        self.y0 = 0.0
        self.slip = 0.0
        self.px = 0.0
        self.py = 0.0
        self.heading = 0.0
        self.phase = 0
        self.label = "unicycle"
        self.site = "phobos"
        self.started = False
        for name in ("v", "w"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("x0", "y0", "slip"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        for name in ("px", "py", "heading"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        self.register_variable(Integer("phase", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete))
        self.register_variable(String("label", causality=Fmi2Causality.output,
                                      variability=Fmi2Variability.discrete))
        self.register_variable(String("site", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.tunable))

    def exit_initialization_mode(self):
        self.px, self.py = self.x0, self.y0

    def do_step(self, current_time, step_size):
        if not 0.0 <= self.slip < 1.0:
            raise ValueError(f"slip {self.slip} outside [0, 1)")
        moving = self.v != 0.0 or self.w != 0.0
        if moving:
            self.started = True
        self.phase = 1 if moving else (2 if self.started else 0)
        speed = self.v * (1.0 - self.slip)
        middle = self.heading + 0.5 * self.w * step_size
        self.px += speed * math.cos(middle) * step_size
        self.py += speed * math.sin(middle) * step_size
        self.heading += self.w * step_size
        return True
'''

ANNOUNCER = '''
import math
from pythonfmu import Fmi2Causality, Fmi2Variability, Fmi2Slave, Boolean, Integer, Real


class Announcer(Fmi2Slave):
    author = "test"
    description = "planar rover reporting its active command: -1 and idle before and after"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.v = 0.0
        self.w = 0.0
        self.px = 0.0
        self.py = 0.0
        self.heading = 0.0
        self.active = -1
        self.idle = True
        for name in ("v", "w"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("px", "py", "heading"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        self.register_variable(Integer("active", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete))
        self.register_variable(Boolean("idle", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete))

    def do_step(self, current_time, step_size):
        # it checks itself for its first 2 s before it follows the set-points (and misses them)
        moving = current_time >= 2.0 and (self.v != 0.0 or self.w != 0.0)
        self.active = 0 if moving else -1
        self.idle = not moving
        if moving:
            middle = self.heading + 0.5 * self.w * step_size
            self.px += self.v * math.cos(middle) * step_size
            self.py += self.v * math.sin(middle) * step_size
            self.heading += self.w * step_size
        return True
'''

DIFF_DRIVE = '''
import math
from pythonfmu3 import (Fmi3Causality, Fmi3Variability, Fmi3Slave, Float64, Int32, Boolean)


class DiffDrive(Fmi3Slave):
    author = "test"
    description = "planar differential-drive rover driven by wheel rates"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time = 0.0
        self.omega_l = 0.0
        self.omega_r = 0.0
        self.track = 0.52
        self.radius = 0.10
        self.slip = 0.0
        self.pos_x = 0.0
        self.pos_y = 0.0
        self.psi = 0.0
        self.arrived = False
        self.steps = 0
        self.driven = False
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        for name in ("omega_l", "omega_r"):
            self.register_variable(Float64(name, causality=Fmi3Causality.input, unit="rad/s"))
        for name in ("track", "radius"):
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter,
                                           variability=Fmi3Variability.tunable, unit="m"))
        self.register_variable(Float64("slip", causality=Fmi3Causality.parameter,
                                       variability=Fmi3Variability.tunable))
        for name in ("pos_x", "pos_y"):
            self.register_variable(Float64(name, causality=Fmi3Causality.output, unit="mm"))
        self.register_variable(Float64("psi", causality=Fmi3Causality.output, unit="rad"))
        self.register_variable(Boolean("arrived", causality=Fmi3Causality.output,
                                       variability=Fmi3Variability.discrete))
        self.register_variable(Int32("steps", causality=Fmi3Causality.output,
                                     variability=Fmi3Variability.discrete))

    def do_step(self, current_time, step_size):
        left = self.omega_l * self.radius * (1.0 - self.slip)
        right = self.omega_r * self.radius * (1.0 - self.slip)
        if left or right:
            self.driven = True
        self.arrived = self.driven and not (left or right)
        rate = (right - left) / self.track
        middle = self.psi + 0.5 * rate * step_size
        speed = 0.5 * (left + right)
        self.pos_x += 1000.0 * speed * math.cos(middle) * step_size
        self.pos_y += 1000.0 * speed * math.sin(middle) * step_size
        self.psi += rate * step_size
        self.steps += 1
        self.time = current_time + step_size
        return True
'''


def build_unicycle(folder: Path) -> Path:
    """``Unicycle.fmu`` (FMI 2.0 co-simulation) built by pythonfmu into ``folder``."""
    from pythonfmu.builder import FmuBuilder

    script = folder / "unicycle.py"
    script.write_text(UNICYCLE, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


def build_announcer(folder: Path) -> Path:
    """``Announcer.fmu`` (FMI 2.0 co-simulation) built by pythonfmu into ``folder``."""
    from pythonfmu.builder import FmuBuilder

    script = folder / "announcer.py"
    script.write_text(ANNOUNCER, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


def build_diff_drive(folder: Path) -> Path:
    """``DiffDrive.fmu`` (FMI 3.0 co-simulation) built by pythonfmu3 into ``folder``."""
    from pythonfmu3.builder import FmuBuilder

    script = folder / "diff_drive.py"
    script.write_text(DIFF_DRIVE, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


# Refuses to be instantiated by the runner (instance name "idefix"), saying why in its log, as
# an FMU that checks a licence does; pythonfmu builds it under another name.
REFUSER = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Refuser(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.px = 0.0
        self.register_variable(Real("px", causality=Fmi2Causality.output))
        if kwargs.get("instance_name") == "idefix":
            raise RuntimeError("license server not reachable")

    def do_step(self, current_time, step_size):
        return True
'''


def build_refuser(folder: Path) -> Path:
    """``Refuser.fmu`` (FMI 2.0 co-simulation, pythonfmu) that the runner cannot instantiate."""
    from pythonfmu.builder import FmuBuilder

    script = folder / "refuser.py"
    script.write_text(REFUSER, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


PLANAR_ME = '''
import math
from typing import List
from pythonfmu3 import (Fmi3Causality, Fmi3Variability, Fmi3Initial, Fmi3SlaveBase,
                        ModelExchange, Float64)


class PlanarME(Fmi3SlaveBase, ModelExchange):
    """States px, py, psi integrated by the importer's solver from inputs v and w."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "planar kinematic rover, model exchange"
        self.time = 0.0
        self.v = 0.0
        self.w = 0.0
        self.px = 0.0
        self.py = 0.0
        self.psi = 0.0
        self.der_px = 0.0
        self.der_py = 0.0
        self.der_psi = 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        for name in ("v", "w"):
            self.register_variable(Float64(name, causality=Fmi3Causality.input, start=0.0))
        for name in ("px", "py", "psi"):  # value references 3, 4, 5
            self.register_variable(Float64(name, causality=Fmi3Causality.output, start=0.0,
                                           variability=Fmi3Variability.continuous,
                                           initial=Fmi3Initial.exact))
        for index, name in enumerate(("der_px", "der_py", "der_psi")):
            self.register_variable(Float64(name, causality=Fmi3Causality.local,
                                           variability=Fmi3Variability.continuous,
                                           derivative=3 + index))

    def get_continuous_state_derivatives(self) -> List[float]:
        self.der_px = self.v * math.cos(self.psi)
        self.der_py = self.v * math.sin(self.psi)
        self.der_psi = self.w
        return [self.der_px, self.der_py, self.der_psi]
'''


def build_planar_me(folder: Path) -> Path:
    """``PlanarME.fmu`` (FMI 3.0 model exchange only) built by pythonfmu3 into ``folder``."""
    from pythonfmu3.builder import FmuBuilder

    script = folder / "planar_me.py"
    script.write_text(PLANAR_ME, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


def run_in_child(fmu: Path, options: dict[str, Any],
                 runs: list[tuple[Any, ...]]) -> tuple[list[dict[str, Any]], bool]:
    """``FmuRunner(fmu, **options).run(*run)`` for each run, in a forked child process, and
    whether the runner used model exchange. Exporters that embed an interpreter (pythonfmu)
    are not always safe to load and unload many times in one process (the campaign runs them
    in its worker processes): a child keeps the test session out of harm's way. A failure is
    raised again here with its type and message."""
    import multiprocessing

    with multiprocessing.get_context("fork").Pool(1) as pool:
        outputs, failure, exchange = pool.apply(_child_runs, (fmu, options, runs))
    if failure is not None:
        from idefix_rules import errors

        kind, message = failure
        raise getattr(errors, kind, RuntimeError)(message)
    return outputs, exchange


def _child_runs(fmu: Path, options: dict[str, Any], runs: list[tuple[Any, ...]]
                ) -> tuple[Any, tuple[str, str] | None, bool]:
    from idefix_rules.fmu import FmuRunner

    try:
        with FmuRunner(fmu, **options) as runner:
            return [runner.run(*run) for run in runs], None, runner.model_exchange
    except Exception as failure:  # sent back as data: FMU errors need not pickle
        return None, (type(failure).__name__, str(failure)), False
