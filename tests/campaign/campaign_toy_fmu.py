"""Builds the toy rover FMU of the campaign tests (``toy_fmu/toy.c``) with gcc.

Its variables follow the built-in rover FMU's names (``initial.x``, ``chain.*``, ``x``,
``wheel.FL.slip`` …) so the default maps apply; ``toy.crash_at`` / ``toy.hang_at`` /
``toy.error_at`` / ``toy.nan_at`` (s, 0 = never) make a run segfault, loop forever, return an
FMI error or output a NaN position from that time on; ``toy.fatal_at`` makes it return fmi2Fatal
after corrupting what every instance in the process shares (later steps of any instance there
slip more than asked, as an FMU's corrupted global state would make them); ``toy.hang_setup``
(1: yes) makes it loop forever leaving initialisation, before any step, and (with the
environment variable ``TOY_SETUP_LOG`` naming a file) each set-up is logged there as a line;
``toy.reset_fails_above`` (0 = never) makes ``fmi2Reset`` fail after a run whose slip was above
it: with the status the environment variable ``TOY_RESET_STATUS`` gives (3 Error, 4 Fatal).
"""

from __future__ import annotations

import json
import os
import subprocess
import zipfile
from pathlib import Path

import fmpy

HERE = Path(__file__).parent / "toy_fmu"
MAX_COMMANDS = 8
WHEELS = ("FL", "FR", "RL", "RR")
WHEEL_OUTPUTS = (("rate", "rad/s"), ("slip", "1"), ("slip_angle", "rad"), ("sinkage", "m"),
                 ("current", "A"))

PARAMETERS = [("initial.x", "m", 0.0), ("initial.y", "m", 0.0), ("initial.yaw", "rad", 0.0),
              ("toy.crash_at", "s", 0.0), ("toy.hang_at", "s", 0.0), ("toy.error_at", "s", 0.0),
              ("soil.cohesion", "Pa", 250.0), ("toy.slip", "1", 0.1), ("toy.nan_at", "s", 0.0),
              ("toy.fatal_at", "s", 0.0), ("toy.hang_setup", "1", 0.0),
              ("toy.reset_fails_above", "1", 0.0)]
CHAIN = ([(f"chain.max_wheel_rate[{i}]", "rad/s", 0.0) for i in range(MAX_COMMANDS)]
         + [(f"chain.delta_position[{i}]", "m", 0.0) for i in range(MAX_COMMANDS)]
         + [(f"chain.delta_heading[{i}]", "rad", 0.0) for i in range(MAX_COMMANDS)])
OUTPUTS = ([("t", "s"), ("x", "m"), ("y", "m"), ("z", "m"), ("roll", "rad"), ("pitch", "rad"),
            ("yaw", "rad")]
           + [(f"wheel.{w}.{what}", unit) for w in WHEELS for what, unit in WHEEL_OUTPUTS]
           + [("energy", "A.s"), ("command", "1"), ("stuck", "1")])


def _header() -> str:
    names = [p[0] for p in PARAMETERS] + [c[0] for c in CHAIN] + [o[0] for o in OUTPUTS]
    index = {name: i for i, name in enumerate(names)}
    lines = [
        f"#define N_REAL {len(names)}",
        f"#define MAX_COMMANDS {MAX_COMMANDS}",
        "#define HALF_TRACK 0.26",
        "#define WHEEL_RADIUS 0.10",
        f"#define VR_INITIAL_X {index['initial.x']}",
        f"#define VR_INITIAL_Y {index['initial.y']}",
        f"#define VR_INITIAL_YAW {index['initial.yaw']}",
        f"#define VR_CRASH_AT {index['toy.crash_at']}",
        f"#define VR_HANG_AT {index['toy.hang_at']}",
        f"#define VR_ERROR_AT {index['toy.error_at']}",
        f"#define VR_NAN_AT {index['toy.nan_at']}",
        f"#define VR_FATAL_AT {index['toy.fatal_at']}",
        f"#define VR_HANG_SETUP {index['toy.hang_setup']}",
        f"#define VR_RESET_FAILS_ABOVE {index['toy.reset_fails_above']}",
        f"#define VR_SLIP {index['toy.slip']}",
        f"#define VR_RATE0 {index['chain.max_wheel_rate[0]']}",
        f"#define VR_DP0 {index['chain.delta_position[0]']}",
        f"#define VR_DH0 {index['chain.delta_heading[0]']}",
        f"#define VR_T {index['t']}",
        f"#define VR_X {index['x']}",
        f"#define VR_Y {index['y']}",
        f"#define VR_YAW {index['yaw']}",
        f"#define VR_WHEEL0 {index['wheel.FL.rate']}",
        f"#define VR_ENERGY {index['energy']}",
        f"#define VR_COMMAND {index['command']}",
    ]
    return "\n".join(lines) + "\n"


def _model_description() -> str:
    units = sorted({u for _, u, *_ in PARAMETERS + CHAIN} | {u for _, u in OUTPUTS})
    rows = []
    vr = 0
    for name, unit, start in PARAMETERS + CHAIN:
        rows.append(f'    <ScalarVariable name="{name}" valueReference="{vr}" '
                    f'causality="parameter" variability="tunable"><Real unit="{unit}" '
                    f'start="{start}"/></ScalarVariable>')
        vr += 1
    for name, unit in OUTPUTS:
        rows.append(f'    <ScalarVariable name="{name}" valueReference="{vr}" '
                    f'causality="output" variability="continuous"><Real unit="{unit}"/>'
                    "</ScalarVariable>")
        vr += 1
    rows.append('    <ScalarVariable name="chain.count" valueReference="0" causality="parameter" '
                'variability="tunable"><Integer start="0"/></ScalarVariable>')
    rows.append('    <ScalarVariable name="terrain.file" valueReference="0" '
                'causality="parameter" variability="tunable"><String start=""/>'
                "</ScalarVariable>")
    outputs = "\n".join(f'      <Unknown index="{len(PARAMETERS) + len(CHAIN) + i + 1}"/>'
                        for i in range(len(OUTPUTS)))
    unit_defs = "\n".join(f'    <Unit name="{u}"/>' for u in units)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="toy" guid="{{toy-rover-0001}}"
  variableNamingConvention="structured" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="toy" canHandleVariableCommunicationStepSize="true"/>
  <UnitDefinitions>
{unit_defs}
  </UnitDefinitions>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}
    </Outputs>
  </ModelStructure>
</fmiModelDescription>
"""


def signal_map() -> dict[str, str]:
    """FMU variable → contract name, like the built-in FMU's shipped map."""
    names = {name: name for name, _ in OUTPUTS if not name.startswith("wheel.")}
    for wheel in WHEELS:
        for what, _ in WHEEL_OUTPUTS:
            names[f"wheel.{wheel}.{what}"] = f"wheel.{what}[{wheel}]"
    return names


def build_toy_fmu(folder: Path) -> Path:
    """Compile ``toy.fmu`` into ``folder`` and return its path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "toy_vr.h").write_text(_header())
    library = folder / "toy.so"
    include = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-std=c99", f"-I{include}",
                    f"-I{folder}", str(HERE / "toy.c"), "-o", str(library), "-lm"],
                   check=True, capture_output=True)
    target = folder / "toy.fmu"
    with zipfile.ZipFile(target, "w") as archive:
        archive.writestr("modelDescription.xml", _model_description())
        archive.write(library, "binaries/linux64/toy.so")
        archive.writestr("signal_map.json", json.dumps(signal_map(), indent=1))
    os.utime(target)
    return target
