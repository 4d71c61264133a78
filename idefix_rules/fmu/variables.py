"""The rover FMU's variables, declared once.

This table is the single source of ``fmu/idefix_rover/modelDescription.xml`` and of the C header
``fmu/idefix_rover/sources/variables.h`` (value references, defaults). Both files are generated
by :func:`write_generated_files` and committed; ``tests/fmu/test_fmu_variables.py`` fails when
they drift from this table.

>>> VARIABLES_BY_NAME["soil.cohesion"].unit
'Pa'
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal
from xml.sax.saxutils import quoteattr

MAX_COMMANDS = 32
WHEEL_NAMES = ("FL", "FR", "RL", "RR")

Causality = Literal["parameter", "output"]
Kind = Literal["Real", "Integer", "String"]


@dataclass(frozen=True)
class Variable:
    """One FMU variable: name, kind, causality, unit, default and what it means."""

    name: str
    kind: Kind
    causality: Causality
    unit: str
    start: float | str
    description: str
    display_unit: str = ""

    @property
    def c_name(self) -> str:
        """Enum name in variables.h, e.g. ``VR_SOIL_COHESION``."""
        text = self.name.upper()
        for char in ".[]":
            text = text.replace(char, "_")
        return "VR_" + text.strip("_").replace("__", "_")


def _p(name: str, unit: str, start: float, description: str, display_unit: str = "") -> Variable:
    return Variable(name, "Real", "parameter", unit, start, description, display_unit)


def _o(name: str, unit: str, description: str) -> Variable:
    return Variable(name, "Real", "output", unit, 0.0, description)


_PARAMETERS: tuple[Variable, ...] = (
    _p("rover.mass", "kg", 25.0, "total rover mass"),
    _p("rover.gravity", "m/s2", 0.0057, "gravitational acceleration (Phobos about 0.0057)"),
    _p("rover.wheel_radius", "m", 0.10, "wheel radius (assumption, see docs/rover-model.md)"),
    _p("rover.wheel_width", "m", 0.06, "wheel width (assumption, see docs/rover-model.md)"),
    _p("rover.half_track", "m", 0.26, "lateral distance body centre to wheel centre plane"),
    _p("rover.half_wheelbase", "m", 0.20, "longitudinal distance body centre to wheel axle"),
    _p("rover.yaw_inertia", "kg.m2", 1.0, "moment of inertia about the vertical axis"),
    _p("rover.cog_height", "m", 0.25, "centre of gravity height above the wheel contact plane"),
    _p("rover.grouser_height", "m", 0.001,
       "grouser height: the shear length of a soil contact is at least sqrt(2 r h_g)"),
    _p("rover.leg_compliance", "m/N", 0.03,
       "vertical compliance of each leg and its held joint at the wheel (series with the soil)"),
    _p("rover.body_centre_height", "m", 0.30,
       "body centre height above the wheel contact plane (pose z is this point)"),
    _p("soil.k_c", "N/m2", 1.4e3,
       "Bekker cohesive modulus k_c at soil.reference_cohesion (unit for n = 1)"),
    _p("soil.k_phi", "N/m3", 820e3,
       "Bekker frictional modulus k_phi at soil.reference_gravity (unit for n = 1)"),
    _p("soil.n", "1", 1.0, "Bekker sinkage exponent n"),
    _p("soil.cohesion", "Pa", 250.0, "Mohr-Coulomb cohesion c of undisturbed regolith"),
    _p("soil.friction_angle", "rad", math.radians(35.0), "Mohr-Coulomb internal friction angle",
       "deg"),
    _p("soil.shear_modulus_K", "m", 0.012, "Janosi-Hanamoto shear deformation modulus K"),
    _p("soil.rut_cohesion_factor", "1", 0.5,
       "fraction of cohesion left in soil already sheared by a wheel (ruts)"),
    _p("soil.multipass_factor", "1", 0.3,
       "extra sinkage of a wheel in a rut, as a fraction of its first-pass sinkage"),
    _p("soil.reference_gravity", "m/s2", 1.62,
       "gravity at which soil.k_phi was measured (its frictional part scales with g)"),
    _p("soil.reference_cohesion", "Pa", 170.0,
       "cohesion of the soil soil.k_c was measured on (its cohesive part scales with c; 0: "
       "k_c as given)"),
    _p("soil.max_sinkage", "m", 0.03, "largest sinkage: depth of the compressible layer"),
    _p("soil.grid_cell", "m", 0.01, "cell size of the plastic sinkage (rut) grid"),
    _p("rock.friction_coefficient", "1", 0.6, "wheel-rock Coulomb friction coefficient"),
    _p("rock.shear_K", "m", 0.001, "shear displacement to mobilise wheel-rock friction"),
    _p("rock.contact_length", "m", 0.02,
       "rim length sheared in a wheel-rock contact (with rock.shear_K: the slip mobilising "
       "rock friction)"),
    _p("motor.no_load_current", "A", 0.0003, "current of a turning motor without load"),
    _p("motor.torque_constant", "N.m/A", 2.0, "wheel torque per ampere (motor and gear)"),
    _p("motor.max_torque", "N.m", 0.2, "largest wheel torque; above it the wheel stalls"),
    _p("controller.wheel_acceleration", "rad/s2", 0.015,
       "wheel rate ramp at the start and end of each command (0: rate steps)"),
    _p("controller.timeout_factor", "1", 2.0,
       "command timeout as a multiple of its ideal duration"),
    _p("controller.stuck_time", "s", 10.0, "window of the stuck observer"),
    _p("controller.stuck_progress", "1", 0.01,
       "stuck (cannot progress) when the net progress over the window is below this fraction "
       "of the commanded: above the creep of the regularised contact laws, below a slow climb"),
    _p("controller.heading_feedback", "1", 1.0,
       "1: heading closed-loop on the gyro yaw measurement; 0: open-loop on wheel odometry"),
    _p("controller.heading_gain", "1/s", 0.5,
       "closed loop: yaw-rate correction per radian of heading lag during arcs and straights"),
    _p("controller.heading_tolerance", "rad", math.radians(0.2),
       "closed loop: a command ends when the gyro heading is this close to the commanded one",
       "deg"),
    _p("controller.rate_floor", "1", 0.5,
       "closed loop on arcs and straights: the heading correction keeps every wheel between "
       "this fraction of its feed-forward rate and (2 - it) times that rate (never a standstill)"),
    _p("gyro.bias", "rad/s", 0.0, "gyro yaw-rate bias"),
    _p("gyro.scale_error", "1", 0.0, "gyro scale-factor error (measured = (1 + e) x true + bias)"),
    _p("initial.x", "m", 0.0, "initial body centre x"),
    _p("initial.y", "m", 0.0, "initial body centre y"),
    _p("initial.yaw", "rad", 0.0, "initial yaw", "deg"),
    _p("solver.step", "s", 0.05, "internal quasi-static step (largest)"),
    _p("solver.velocity_epsilon", "m/s", 1e-5, "regularisation speed of the shear laws"),
)

_CHAIN: tuple[Variable, ...] = (
    Variable("chain.count", "Integer", "parameter", "", 0,
             f"number of commands in the chain (at most {MAX_COMMANDS})"),
    *(
        _p(f"chain.max_wheel_rate[{i}]", "rad/s", 0.0, f"command {i}: rate of the fastest wheel")
        for i in range(MAX_COMMANDS)
    ),
    *(
        _p(f"chain.delta_position[{i}]", "m", 0.0, f"command {i}: arc length (negative: reverse)")
        for i in range(MAX_COMMANDS)
    ),
    *(
        _p(f"chain.delta_heading[{i}]", "rad", 0.0, f"command {i}: yaw change (positive: left)",
           "deg")
        for i in range(MAX_COMMANDS)
    ),
)

_TERRAIN = (
    Variable("terrain.file", "String", "parameter", "", "",
             "terrain file (docs/terrain-format.md); empty: flat ground at z = 0, no rocks"),
)

_WHEEL_OUTPUTS = (
    ("rate", "rad/s", "wheel angular rate"),
    ("slip", "1", "longitudinal slip ratio"),
    ("slip_angle", "rad", "slip angle of the wheel contact velocity"),
    ("sinkage", "m", "sinkage below the undisturbed surface"),
    ("current", "A", "motor current"),
    ("load", "N", "normal load"),
)

_OUTPUTS: tuple[Variable, ...] = (
    _o("t", "s", "simulation time"),
    _o("x", "m", "body centre x"),
    _o("y", "m", "body centre y"),
    _o("z", "m", "body centre height above the terrain datum"),
    _o("roll", "rad", "roll (R = Rz(yaw) Ry(pitch) Rx(roll); positive lifts the left side)"),
    _o("pitch", "rad", "pitch (positive: nose down)"),
    _o("yaw", "rad", "yaw, unwrapped"),
    *(
        _o(f"wheel.{wheel}.{what}", unit, f"{wheel} {text}")
        for what, unit, text in _WHEEL_OUTPUTS
        for wheel in WHEEL_NAMES
    ),
    _o("energy", "A.s", "cumulative charge drawn by the motors"),
    _o("command", "1", "index of the active command, -1 when the chain is done"),
    _o("stuck", "1", "1 while the stuck observer reports the rover stuck"),
)

VARIABLES: tuple[Variable, ...] = _PARAMETERS + _CHAIN + _TERRAIN + _OUTPUTS
VARIABLES_BY_NAME = {v.name: v for v in VARIABLES}

# FMI unit name -> exponents (kg, m, s, A, rad) and factor; only units used above.
_UNITS: dict[str, tuple[dict[str, int], float]] = {
    "1": ({}, 1.0),
    "m": ({"m": 1}, 1.0),
    "kg": ({"kg": 1}, 1.0),
    "s": ({"s": 1}, 1.0),
    "1/s": ({"s": -1}, 1.0),
    "A": ({"A": 1}, 1.0),
    "N": ({"kg": 1, "m": 1, "s": -2}, 1.0),
    "rad": ({"rad": 1}, 1.0),
    "rad/s": ({"rad": 1, "s": -1}, 1.0),
    "rad/s2": ({"rad": 1, "s": -2}, 1.0),
    "m/s": ({"m": 1, "s": -1}, 1.0),
    "m/N": ({"kg": -1, "s": 2}, 1.0),
    "m/s2": ({"m": 1, "s": -2}, 1.0),
    "Pa": ({"kg": 1, "m": -1, "s": -2}, 1.0),
    "N/m2": ({"kg": 1, "m": -1, "s": -2}, 1.0),
    "N/m3": ({"kg": 1, "m": -2, "s": -2}, 1.0),
    "N.m": ({"kg": 1, "m": 2, "s": -2}, 1.0),
    "kg.m2": ({"kg": 1, "m": 2}, 1.0),
    "N.m/A": ({"kg": 1, "m": 2, "s": -2, "A": -1}, 1.0),
    "A.s": ({"A": 1, "s": 1}, 1.0),
}
_DISPLAY_UNITS = {"rad": ("deg", 180.0 / math.pi)}


def value_references() -> dict[str, int]:
    """Value reference of every variable; Reals, Integers and Strings count separately."""
    counters = {"Real": 0, "Integer": 0, "String": 0}
    refs = {}
    for variable in VARIABLES:
        refs[variable.name] = counters[variable.kind]
        counters[variable.kind] += 1
    return refs


def render_model_description() -> str:
    refs = value_references()
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        "<!-- Generated from idefix_rules/fmu/variables.py; do not edit by hand. -->",
        '<fmiModelDescription fmiVersion="2.0" modelName="idefix_rover"',
        '  guid="{6a1d2f3e-1d3c-4b8e-9f60-1defa11c0de5}"',
        '  description="IDEFIX-like four-wheel skid-steered rover on deformable regolith '
        '(quasi-static, see docs/rover-model.md)"',
        '  generationTool="idefix-rules" variableNamingConvention="structured"'
        ' numberOfEventIndicators="0">',
        '  <CoSimulation modelIdentifier="idefix_rover"'
        ' canHandleVariableCommunicationStepSize="true"'
        ' canNotUseMemoryManagementFunctions="true">',
        "    <SourceFiles>",
        *(f'      <File name="{name}"/>' for name in SOURCE_FILES),
        "    </SourceFiles>",
        "  </CoSimulation>",
        "  <UnitDefinitions>",
    ]
    for unit, (exponents, factor) in _UNITS.items():
        attrs = "".join(f' {k}="{v}"' for k, v in exponents.items())
        if factor != 1.0:
            attrs += f' factor="{factor!r}"'
        lines.append(f'    <Unit name="{unit}">')
        lines.append(f"      <BaseUnit{attrs}/>")
        for display, display_factor in [_DISPLAY_UNITS[unit]] if unit in _DISPLAY_UNITS else []:
            lines.append(f'      <DisplayUnit name="{display}" factor="{display_factor!r}"/>')
        lines.append("    </Unit>")
    lines += ["  </UnitDefinitions>", "  <DefaultExperiment startTime=\"0.0\" stopTime=\"300.0\""
              " stepSize=\"0.1\"/>", "  <ModelVariables>"]
    outputs = []
    for index, variable in enumerate(VARIABLES, start=1):
        attrs = (f'name={quoteattr(variable.name)} valueReference="{refs[variable.name]}"'
                 f' causality="{variable.causality}"')
        if variable.causality == "parameter":
            attrs += ' variability="fixed" initial="exact"'
        else:
            attrs += ' variability="continuous"'
            outputs.append(index)
        attrs += f" description={quoteattr(variable.description)}"
        if variable.kind == "Real":
            inner = f'unit="{variable.unit}"'
            if variable.display_unit:
                inner += f' displayUnit="{variable.display_unit}"'
            if variable.causality == "parameter":
                inner += f' start="{float(variable.start)!r}"'
            element = f"<Real {inner}/>"
        elif variable.kind == "Integer":
            element = f'<Integer start="{int(variable.start)}"/>'
        else:
            element = f"<String start={quoteattr(str(variable.start))}/>"
        lines.append(f"    <ScalarVariable {attrs}>")
        lines.append(f"      {element}")
        lines.append("    </ScalarVariable>")
    lines += ["  </ModelVariables>", "  <ModelStructure>", "    <Outputs>"]
    lines += [f'      <Unknown index="{i}"/>' for i in outputs]
    lines += ["    </Outputs>", "    <InitialUnknowns>"]
    lines += [f'      <Unknown index="{i}"/>' for i in outputs]
    lines += ["    </InitialUnknowns>", "  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(lines)


def render_header() -> str:
    refs = value_references()
    reals = [v for v in VARIABLES if v.kind == "Real"]
    lines = [
        "/* Generated from idefix_rules/fmu/variables.py; do not edit by hand. */",
        "#ifndef IDEFIX_VARIABLES_H",
        "#define IDEFIX_VARIABLES_H",
        "",
        f"#define MAX_COMMANDS {MAX_COMMANDS}",
        f"#define N_REAL {len(reals)}",
        "#define VR_CHAIN_COUNT 0 /* Integer */",
        "#define VR_TERRAIN_FILE 0 /* String */",
        "",
        "/* Real value references */",
    ]
    for variable in reals:
        if "[" in variable.name and not variable.name.endswith("[0]"):
            continue
        name = variable.c_name.removesuffix("_0") if "[" in variable.name else variable.c_name
        lines.append(f"#define {name} {refs[variable.name]}")
    wheel_first = {what: refs[f"wheel.FL.{what}"] for what, _, _ in _WHEEL_OUTPUTS}
    lines.append("")
    lines.append("/* per-wheel outputs: base + wheel index (FL, FR, RL, RR) */")
    for what, first in wheel_first.items():
        lines.append(f"#define VR_WHEEL_{what.upper()} {first}")
    lines.append("")
    lines.append("/* start values of every Real, indexed by value reference */")
    lines.append("#define REAL_DEFAULTS { \\")
    for variable in reals:
        lines.append(f"    {float(variable.start)!r}, /* {variable.name} */ \\")
    lines.append("}")
    lines.append("#define FIRST_OUTPUT_VR " + str(refs[_OUTPUTS[0].name]))
    lines += ["", "#endif", ""]
    return "\n".join(lines)


def default_signal_map() -> dict[str, str]:
    """FMU variable name -> contract name (``wheel.rate[FL]`` addresses one wheel column)."""
    mapping = {}
    for variable in _OUTPUTS:
        parts = variable.name.split(".")
        if parts[-1] == "load":  # not part of the signal contract
            continue
        if len(parts) == 3 and parts[0] == "wheel":
            mapping[variable.name] = f"wheel.{parts[2]}[{parts[1]}]"
        else:
            mapping[variable.name] = variable.name
    return mapping


def render_signal_map() -> str:
    import json

    return json.dumps(default_signal_map(), indent=2) + "\n"


SOURCE_FILES = ("terrain.c", "soil.c", "wheel.c", "contact.c", "loads.c", "balance.c", "rover.c",
                "parameters.c", "controller.c", "fmi2_glue.c")


def write_generated_files(fmu_dir: Path) -> None:
    """Regenerate modelDescription.xml, sources/variables.h and signal_map.json."""
    (fmu_dir / "modelDescription.xml").write_text(render_model_description(), encoding="utf-8")
    (fmu_dir / "sources" / "variables.h").write_text(render_header(), encoding="utf-8")
    (fmu_dir / "signal_map.json").write_text(render_signal_map(), encoding="utf-8")


if __name__ == "__main__":  # python -m idefix_rules.fmu.variables
    write_generated_files(Path(__file__).resolve().parents[2] / "fmu" / "idefix_rover")
