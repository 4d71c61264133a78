"""Every mapping mistake on a foreign FMU is an exit-2 diagnostic at its campaign line and
column, reported together with the others, before any run is simulated."""

from __future__ import annotations

import platform
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from test_fmu_foreign_campaign import (
    DIFF_DRIVE_CAMPAIGN,
    POSITION_RULEBOOK,
    UNICYCLE_CAMPAIGN,
    _campaign,
    _run,
)

SLIP_RULEBOOK = POSITION_RULEBOOK.replace('''verdict close_enough''', '''index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1
  because "Slip"
}

verdict close_enough''')

COLLISION_RULEBOOK = POSITION_RULEBOOK.replace('''index I_end''', '''obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

index I_obs "obstacle collisions" {
  value  = sum over parts (sum over levels (collision.hits))
  limit  = 1
  weight = 1
  because "No rock may be hit"
}

index I_end''')


@dataclass(frozen=True)
class Mistake:
    id: str
    fmu: str  # "unicycle" or "diff_drive"
    replace: tuple[tuple[str, str], ...]
    # (marker on the campaign line the diagnostic points at, code, message fragment)
    expected: tuple[tuple[str, str, str], ...]
    rulebook: str = POSITION_RULEBOOK


MISTAKES = [
    Mistake("misspelled-signal-variable", "unicycle", (("    px: x", "    p_x: x"),),
            (("p_x: x", "C401", "fmu.signals.p_x: unknown FMU variable 'p_x' in Unicycle.fmu "
              "hint: did you mean 'px'?"),)),
    Mistake("not-a-signal", "unicycle", (("    px: x", "    px: position.x"),),
            (("position.x", "C500", "fmu.signals.px: 'position.x' is not a signal an FMU "
              "provides"),)),
    Mistake("wheel-signal-without-a-wheel", "unicycle", (("    px: x", "    px: wheel.rate"),),
            (("wheel.rate", "C500", "'wheel.rate' needs one wheel, e.g. 'wheel.rate[FL]'"),)),
    Mistake("a-wheel-signal-for-one-wheel-only", "unicycle",
            (("    py: y\n", "    py: y\n    phase: wheel.slip[FL]\n"),),
            (("wheel.slip[FL]", "C500", "fmu.signals.phase: signal 'wheel.slip' is mapped for FL "
              "only: a wheel signal has all four wheels hint: map wheel.slip[FR], "
              "wheel.slip[RL], wheel.slip[RR] too, or none of them"),)),
    Mistake("done-at-beyond-a-boolean", "diff_drive",
            (("  path: DiffDrive.fmu\n", "  path: DiffDrive.fmu\n  done_at: 2\n"),),
            (("2\n  signals:", "C502", "fmu.done_at: 'arrived' is a Boolean, read as 0 or 1: "
              "'done' never reaches 2"),)),
    Mistake("an-input-mapped-as-a-signal", "unicycle",
            (("    py: y\n", "    py: y\n    w: yaw\n"),),
            (("w: yaw", "C501", "fmu.signals.w: 'w' is an input; a signal must be an output "
              "of the FMU"),)),
    Mistake("a-string-output-mapped-as-a-signal", "unicycle", (("    px: x", "    label: x"),),
            (("label: x", "C502", "'label' is a String; a signal is read from a Real/Float, "
              "Integer, Boolean or Enumeration output"),)),
    Mistake("an-output-of-the-wrong-unit", "diff_drive", (("    psi: yaw", "    psi: x"),
                                                           ("    pos_x: x", "    pos_x: yaw")),
            (("yaw\n", "C503", "fmu.signals.pos_x: 'pos_x' is in mm, but 'yaw' is in rad"),
             ("x\n    arrived", "C503", "fmu.signals.psi: 'psi' is in rad, but 'x' is in m"))),
    Mistake("a-signal-mapped-twice", "unicycle", (("    py: y\n", "    py: y\n    heading: x\n"),),
            (("heading: x", "C511", "signal 'x' is mapped from both 'px' and 'heading'"),)),
    Mistake("a-signal-the-rulebook-reads-is-not-mapped", "unicycle", (), (
        ("signals:", "C405", "fmu.signals: the rulebook reads 'wheel.slip', which the signal "
         "map does not provide"),), SLIP_RULEBOOK),
    Mistake("no-signal-map-and-no-variables-named-like-signals", "unicycle",
            (("  signals:\n    px: x\n    py: y\n", ""),),
            (("path: Unicycle.fmu", "C405", "the rulebook reads 'x', 'y', which Unicycle.fmu has "
              "no variable of that name for (and the campaign gives no fmu.signals map)"),)),
    Mistake("a-parameter-value-of-the-wrong-dimension", "diff_drive",
            (("    slip: {", '    track: {distribution: uniform, low: "10 deg", high: "20 deg"}'
              "\n    slip: {"),),
            (('{distribution: uniform, low: "10 deg"', "C402",
              "uncertainty.parameters.track: expected a length (FMU unit m), got an angle"),)),
    # the tool reads initial.x as metres whatever the FMU declares: an FMU without units
    # took "5 s" as 5 m
    Mistake("a-start-position-of-another-dimension", "unicycle",
            (('initial.x: {distribution: normal, mean: "0 m", std: "1 mm"}',
              'initial.x: {distribution: normal, mean: "0 s", std: "5 s"}'),),
            (('{distribution: normal, mean: "0 s"', "C402",
              "uncertainty.parameters.initial.x: expected a length (initial.x is the rover's "
              "start position, read by this tool in m), got a duration"),)),
    Mistake("a-start-heading-mapped-to-a-length", "diff_drive",
            (("  chain:\n", "  parameters:\n    radius: initial.yaw\n  chain:\n"),
             ("    slip: {", '    initial.yaw: {distribution: fixed, value: "0 deg"}\n'
              "    slip: {")),
            (('{distribution: fixed, value: "0 deg"}', "C402",
              "uncertainty.parameters.initial.yaw: initial.yaw is the rover's start heading, "
              "read by this tool as an angle in rad, but FMU variable 'radius' is in m"),)),
    Mistake("collisions-without-a-pose", "unicycle", (), (
        ("signals:", "C512", "the rulebook reads collisions, which place the rover's bodies by "
         "its pose, but the map does not provide 'pitch', 'roll', 'yaw', 'z'"),),
            COLLISION_RULEBOOK),
    Mistake("an-output-as-a-sampled-parameter", "unicycle",
            (("    slip: {", "    px: {distribution: fixed, value: 1}\n    slip: {"),),
            (("px: {", "C504", "uncertainty.parameters.px: FMU variable 'px' is output; a "
              "parameter must be settable"),)),
    Mistake("a-string-parameter-sampled", "unicycle",
            (("    slip: {", "    site: {distribution: fixed, value: 1}\n    slip: {"),),
            (("site: {", "C505", "FMU parameter 'site' is a String; a sampled or regolith "
              "value needs a Real or Integer"),)),
    Mistake("misspelled-parameter-map", "unicycle", (("    x0: initial.x", "    x00: initial.x"),),
            (("x00:", "C401", "fmu.parameters.x00: unknown FMU variable 'x00' in Unicycle.fmu "
              "hint: did you mean 'x0'?"),)),
    # two FMU variables for one campaign name: y0 silently kept its start value
    Mistake("two-variables-mapped-to-one-name", "unicycle",
            (("    x0: initial.x\n", "    x0: initial.x\n    y0: initial.x\n"),),
            (("y0: initial.x", "C516", "fmu.parameters.y0: 'initial.x' is mapped from both "
              "'x0' and 'y0'; a campaign name sets one FMU variable hint: map each FMU variable "
              "to a name of its own"),)),
    Mistake("chain-as-parameters-to-an-fmu-without-them", "unicycle",
            (("    delivery: inputs\n    inputs:\n      v: body.speed\n      w: body.yaw_rate\n",
              "    delivery: parameters\n"),),
            (("chain:", "C507", "Unicycle.fmu takes no command chain as parameters: it has no "
              "'chain.count', 'chain.max_wheel_rate[0]'"),
             ("chain:", "C507", "hint: map its chain parameters in fmu.parameters (FMU variable: "
              "chain.count, …), or set fmu.chain.delivery to 'inputs'"))),
    Mistake("misspelled-chain-input", "unicycle",
            (("      v: body.speed", "      vv: body.speed"),),
            (("vv:", "C401", "fmu.chain.inputs.vv: unknown FMU variable 'vv' in Unicycle.fmu "
              "hint: did you mean 'v'?"),)),
    Mistake("not-a-set-point", "unicycle", (("v: body.speed", "v: body.velocity"),),
            (("body.velocity", "C509", "fmu.chain.inputs.v: 'body.velocity' is not a "
              "set-point"),)),
    Mistake("a-set-point-fed-to-an-output", "unicycle",
            (("      w: body.yaw_rate", "      w: body.yaw_rate\n      px: command"),),
            (("px: command", "C501", "fmu.chain.inputs.px: 'px' is an output; set-points are "
              "fed to inputs of the FMU every step"),)),
    Mistake("a-set-point-of-the-wrong-unit", "diff_drive",
            (("omega_l: wheel.rate[FL]", "omega_l: body.speed"),),
            (("body.speed", "C503", "fmu.chain.inputs.omega_l: 'omega_l' is in rad/s, but "
              "'body.speed' is in m/s"),)),
    Mistake("inputs-without-delivery-inputs", "unicycle",
            (("    delivery: inputs\n", "    delivery: none\n"),),
            (("inputs:\n", "C508", "fmu.chain.inputs: set-points given, but "
              "fmu.chain.delivery is 'none'"),)),
    Mistake("delivery-inputs-without-inputs", "unicycle",
            (("    inputs:\n      v: body.speed\n      w: body.yaw_rate\n", ""),),
            (("chain:", "C508", "fmu.chain: delivery 'inputs' needs fmu.chain.inputs"),)),
    Mistake("four-mistakes-at-once", "unicycle",
            (("    px: x", "    pz: x"), ("    py: y\n", "    py: y\n    w: yaw\n"),
             ("      v: body.speed", "      vv: body.speed"),
             ("    slip: {", "    px: {distribution: fixed, value: 1}\n    slip: {")),
            (("pz: x", "C401", "unknown FMU variable 'pz'"), ("w: yaw", "C501", "'w' is an input"),
             ("vv:", "C401", "unknown FMU variable 'vv'"), ("px: {", "C504", "'px' is output"))),
]


def _location(text: str, marker: str) -> str:
    """``campaign.yaml:line:column`` of the first ``marker`` in ``text``."""
    offset = text.index(marker)
    line = text.count("\n", 0, offset) + 1
    column = offset - (text.rfind("\n", 0, offset) + 1) + 1
    return f"campaign.yaml:{line}:{column}"


def _edited_diff_drive(diff_drive_fmu: Path, folder: Path, old: bytes, new: bytes) -> Path:
    """A copy of DiffDrive.fmu in ``folder`` whose model description has ``old`` replaced by
    ``new`` (a unit, a type, a range, a dimension the test needs)."""
    import zipfile

    fmu = folder / "DiffDrive.fmu"
    with zipfile.ZipFile(diff_drive_fmu) as source, zipfile.ZipFile(fmu, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                assert old in data
                data = data.replace(old, new)
            target.writestr(item, data)
    return fmu


@pytest.mark.parametrize("mistake", MISTAKES, ids=[m.id for m in MISTAKES])
def test_a_mapping_mistake_is_a_located_exit_2_before_any_run(
        mistake: Mistake, tmp_path: Path, unicycle_fmu: Path, diff_drive_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    text = UNICYCLE_CAMPAIGN if mistake.fmu == "unicycle" else DIFF_DRIVE_CAMPAIGN
    for old, new in mistake.replace:
        assert old in text, old
        text = text.replace(old, new, 1)
    fmu = unicycle_fmu if mistake.fmu == "unicycle" else diff_drive_fmu
    code, output = _run(_campaign(tmp_path, fmu, text, mistake.rulebook), capsys)
    assert code == 2, output
    for marker, code_name, fragment in mistake.expected:
        head = f"{_location(text, marker)}: error[{code_name}]:"
        assert head in output, (head, output)
        for part in fragment.split(" hint: "):  # the source line and caret come between
            assert " ".join(part.split()) in output, (part, output)
    assert not (tmp_path / "out" / "results.h5").exists()  # nothing was simulated


def test_terrain_and_rocks_the_fmu_cannot_receive_are_warnings_and_the_campaign_runs(
        tmp_path: Path, unicycle_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = UNICYCLE_CAMPAIGN.replace("paths:\n", """environment:
  terrain:
    synthetic: {size: "4 m", cell: "5 cm", slope: "2 deg"}
  rocks:
    - {x: "0.5 m", y: "0.3 m", radius: "4 cm", level: L2}
paths:
""")
    code, output = _run(_campaign(tmp_path, unicycle_fmu, text), capsys)
    assert code == 1, output  # as without the environment: the long path fails
    for marker, what in (("terrain:", "terrain"), ("rocks:", "rocks")):
        assert (f"{_location(text, marker)}: [C510] environment.{what}: Unicycle.fmu "
                f"has no terrain input ('terrain.file'), so its runs do not see the campaign's "
                f"{what}") in output, output
    assert output.count("warning: ") >= 2
    # the rulebook reads no collision: the warning said they were evaluated all the same
    assert "collisions are still" not in output and "computed geometrically" not in output
    assert "the campaign's terrain; the rulebook reads no collision or area signal, so it " \
        "plays no part in the risks" in output, output
    assert "the campaign's rocks; the rulebook reads no collision or area signal, so they " \
        "play no part in the risks" in output, output
    # and the report says it too
    report = (tmp_path / "out" / "report.html").read_text().replace("&#x27;", "'")
    notes = report[report.index("<h2>Notes</h2>"):]
    for what in ("terrain", "rocks"):
        assert f"environment.{what}: Unicycle.fmu has no terrain input ('terrain.file'), so " \
            f"its runs do not see the campaign's {what}; the rulebook reads no collision" in notes


@pytest.mark.parametrize(("what", "reads_collisions", "says"), [
    ("terrain", False, "the rulebook reads no collision or area signal, so it plays no part in "
                       "the risks"),
    ("rocks", False, "the rulebook reads no collision or area signal, so they play no part in "
                     "the risks"),
    ("terrain", True, "the rulebook's collision and area signals are still computed "
                      "geometrically from the runs' pose, against the campaign's obstacles on "
                      "this terrain (not on the ground the FMU drove on)"),
    ("rocks", True, "the rulebook's collision signals are still computed geometrically from the "
                    "runs' pose against them"),
])
def test_the_terrain_an_fmu_does_not_see_is_said_as_the_rulebook_uses_it(
        what: str, reads_collisions: bool, says: str) -> None:
    from idefix_rules.campaign.input.fmu_checks import unseen_ground_text

    assert unseen_ground_text(what, "Unicycle.fmu", reads_collisions) == (
        f"Unicycle.fmu has no terrain input ('terrain.file'), so its runs do not see the "
        f"campaign's {what}; {says}")


def test_the_guide_documents_every_mapping_diagnostic_code() -> None:
    import re

    import idefix_rules.campaign.input as inputs
    import idefix_rules.campaign.simulation.worker as worker

    # every module of the campaign-input package (a new one is read without being listed
    # here), and the worker, which finds a map's mistake a run shows (C520)
    emitted = set(re.findall(r'"(C[45]\d\d)"', "".join(
        path.read_text() for path in [*sorted(Path(inputs.__file__).parent.glob("*.py")),
                                      Path(worker.__file__)])))
    guide = (Path(__file__).parents[2] / "docs" / "bring-your-own-fmu.md").read_text()
    documented = set(re.findall(r"^\| (C[45]\d\d) \|", guide, re.M))
    assert emitted - {"C404"} == documented  # C404 (run size) is docs/ci.md's


@pytest.mark.parametrize(("shipped", "says"), [
    ('{"px": x}', "its signal_map.json cannot be read (Expecting value"),
    ('{"px": 1}', "its signal_map.json must be a JSON object of FMU variable names to signal "
                  "names (strings)"),
    ('["px", "x"]', "its signal_map.json must be a JSON object"),
])
def test_a_broken_shipped_signal_map_is_C400_at_the_fmu_path(
        shipped: str, says: str, tmp_path: Path, unicycle_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The map an FMU ships (used when the campaign gives none) is read as a user's file: a
    broken one is exit 2 at `fmu.path`, not a traceback."""
    import shutil
    import zipfile

    fmu = tmp_path / "Shipped.fmu"
    shutil.copy(unicycle_fmu, fmu)
    with zipfile.ZipFile(fmu, "a") as archive:
        archive.writestr("signal_map.json", shipped)
    text = UNICYCLE_CAMPAIGN.replace("Unicycle.fmu", "Shipped.fmu").replace(
        "  signals:\n    px: x\n    py: y\n", "")
    code, output = _run(_campaign(tmp_path, fmu, text), capsys)
    assert code == 2, output
    assert f"{_location(text, 'path: Shipped.fmu')}: error[C400]: Shipped.fmu: not a readable " \
        "FMU: " in output, output
    assert says in " ".join(output.split()), output
    assert "Traceback" not in output


@pytest.mark.parametrize("unit", ["milli-metre", "K"])
def test_a_declared_unit_the_tool_cannot_convert_is_C503(
        unit: str, tmp_path: Path, diff_drive_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """An output in a unit the tool cannot read was taken as SI: `milli-metre` as metres (a
    rover 284 m from its start). Now it is said at the map line, exit 2."""
    declared = b'name="pos_x" valueReference="6" causality="output" unit="mm"'
    fmu = _edited_diff_drive(diff_drive_fmu, tmp_path, declared,
                             declared.replace(b'"mm"', f'"{unit}"'.encode()))
    folder = tmp_path / "c"
    folder.mkdir()
    code, output = _run(_campaign(folder, fmu, DIFF_DRIVE_CAMPAIGN), capsys)
    assert code == 2, output
    where = _location(DIFF_DRIVE_CAMPAIGN, "x\n    pos_y")  # the value the map gives pos_x
    assert f"{where}: error[C503]: fmu.signals.pos_x: " \
        f"'pos_x' is in '{unit}', which this tool cannot convert ('x' is in m)" in output, output


def test_an_fmu_without_a_binary_for_this_platform_is_C400_before_any_run(
        tmp_path: Path, unicycle_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The zip's listing says so before anything is simulated: it was every reference run
    failing to instantiate, exit 3, as if the machine were at fault."""
    import zipfile

    import fmpy

    fmu = tmp_path / "Unicycle.fmu"
    with zipfile.ZipFile(unicycle_fmu) as source, zipfile.ZipFile(fmu, "w") as target:
        for item in source.infolist():  # it ships Windows and Linux binaries: drop this one's
            if not item.filename.startswith(f"binaries/{fmpy.platform}/"):
                target.writestr(item, source.read(item))
    code, output = _run(_campaign(tmp_path, fmu, UNICYCLE_CAMPAIGN), capsys)
    assert code == 2, output
    flat = " ".join(output.split())
    assert f"{_location(UNICYCLE_CAMPAIGN, 'Unicycle.fmu')}: error[C400]: " in output, output
    assert f"no binary for this platform (binaries/{fmpy.platform}/Unicycle" \
        f"{fmpy.sharedLibraryExtension} is missing); it has binaries for win64" in flat, output
    assert not (tmp_path / "out" / "results.h5").exists()


def _elf_header(machine: int, bits: int = 2) -> bytes:
    return b"\x7fELF" + bytes([bits, 1, 1]) + bytes(9) + (3).to_bytes(2, "little") \
        + machine.to_bytes(2, "little")


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.machine() != "x86_64",
                    reason="the ELF check of this test is written for x86_64 Linux")
@pytest.mark.parametrize(("library", "says"), [
    (b"not a library", "is not a shared library (it has no ELF header)"),
    (b"\x7fELF\x02\x01", "is cut short (6 bytes)"),
    (_elf_header(62, bits=1), "is a 32-bit library; this machine loads 64-bit ones"),
    (_elf_header(183), "is built for aarch64; this machine is x86_64"),
])
def test_a_binary_this_machine_cannot_load_is_C400_before_any_run(
        library: bytes, says: str, tmp_path: Path, unicycle_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A binary under this platform's name that is no library for this machine: it was every
    reference run failing to load it (exit 3, after the rulebook and terrain stages)."""
    import zipfile

    import fmpy

    member = f"binaries/{fmpy.platform}/Unicycle{fmpy.sharedLibraryExtension}"
    fmu = tmp_path / "Unicycle.fmu"
    with zipfile.ZipFile(unicycle_fmu) as source, zipfile.ZipFile(fmu, "w") as target:
        for item in source.infolist():
            target.writestr(item, library if item.filename == member else source.read(item))
    code, output = _run(_campaign(tmp_path, fmu, UNICYCLE_CAMPAIGN), capsys)
    assert code == 2, output
    flat = " ".join(output.split())
    assert f"{_location(UNICYCLE_CAMPAIGN, 'Unicycle.fmu')}: error[C400]: " in output, output
    assert f"{member} {says}" in flat, output
    assert not (tmp_path / "out" / "results.h5").exists()


def test_the_real_binary_passes_the_elf_check(unicycle_fmu: Path) -> None:
    from idefix_rules.campaign.input.fmu_checks import _foreign_binary
    from idefix_rules.fmu.description import describe_fmu

    assert _foreign_binary(describe_fmu(unicycle_fmu)) is None


@pytest.mark.parametrize(("mapped", "says"), [
    ("pos_x", "fmu.signals.pos_x: 'pos_x' is a Float64 array; a signal is read from a "
              "Real/Float, Integer, Boolean or Enumeration output"),
    ("pos_x[1]", "fmu.signals.pos_x[1]: 'pos_x[1]' is an element of 'pos_x', a Float64 array: "
                 "elements of FMI 3 arrays are not read"),
])
def test_an_fmi3_array_output_is_C502_not_its_first_element(
        mapped: str, says: str, tmp_path: Path, diff_drive_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """An array output mapped as a signal was read as its first element (y held pos[0])."""
    declared = b'name="pos_x" valueReference="6" causality="output" unit="mm"/>'
    fmu = _edited_diff_drive(diff_drive_fmu, tmp_path, declared,
                             declared[:-2] + b'><Dimension start="3"/></Float64>')
    folder = tmp_path / "c"
    folder.mkdir()
    text = DIFF_DRIVE_CAMPAIGN.replace("    pos_x: x\n", f"    {mapped}: x\n")
    code, output = _run(_campaign(folder, fmu, text), capsys)
    assert code == 2, output
    assert f"{_location(text, mapped + ': x')}: error[C502]: {says}" in " ".join(output.split())


def _slip_given(diff_drive_fmu: Path, tmp_path: Path, slip: bytes, given: str,
                capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """DiffDrive's campaign run with its `slip` parameter declared as ``slip`` (the start of
    its XML element) and the campaign's distribution of it replaced by ``given``: exit code,
    output, campaign text."""
    fmu = _edited_diff_drive(diff_drive_fmu, tmp_path, b'<Float64 name="slip"', slip)
    folder = tmp_path / "c"
    folder.mkdir()
    text = DIFF_DRIVE_CAMPAIGN.replace("slip: {distribution: uniform, low: 0.0, high: 0.05}",
                                       given)
    code, output = _run(_campaign(folder, fmu, text), capsys)
    return code, output, text


@pytest.mark.parametrize(("given", "says"), [
    ("slip: {distribution: uniform, low: 0.0, high: 0.05}",
     "but a uniform distribution draws fractions"),
    ("slip: {distribution: fixed, value: 2.7}", "but 2.7 is not a whole number"),
])
def test_fractions_for_an_integer_parameter_are_C505(
        given: str, says: str, tmp_path: Path, diff_drive_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Values for an Integer parameter were cut to whole numbers where they were set: 2.7 ran
    as 2, and a uniform draw was biased down."""
    code, output, text = _slip_given(diff_drive_fmu, tmp_path, b'<Int32 name="slip"', given,
                                     capsys)
    assert code == 2, output
    assert f"{_location(text, given)}: error[C505]: uncertainty.parameters.slip: FMU parameter " \
        f"'slip' is an Int32, {says}: it would be cut to a whole number" in \
        " ".join(output.split()), output


def test_a_damaged_fmu_is_C400_at_its_path_before_any_stage(
        tmp_path: Path, unicycle_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A byte flipped in the binary inside the zip: it was F102 without a place, after the
    rulebook and terrain stages, leaving an interrupted results file."""
    import zipfile

    import fmpy

    member = f"binaries/{fmpy.platform}/Unicycle{fmpy.sharedLibraryExtension}"
    data = bytearray(unicycle_fmu.read_bytes())
    with zipfile.ZipFile(unicycle_fmu) as archive:
        info = archive.getinfo(member)
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    data[start + info.compress_size // 2] ^= 0xFF
    fmu = tmp_path / "Unicycle.fmu"
    fmu.write_bytes(bytes(data))
    code, output = _run(_campaign(tmp_path, fmu, UNICYCLE_CAMPAIGN), capsys)
    assert code == 2, output
    assert f"{_location(UNICYCLE_CAMPAIGN, 'Unicycle.fmu')}: error[C400]: " in output, output
    assert "not a readable FMU" in output and member in " ".join(output.split()), output
    assert not (tmp_path / "out" / "results.h5").exists()


@pytest.mark.parametrize(("declared", "given", "says"), [
    ('max="0.01"', "slip: {distribution: uniform, low: 0.0, high: 0.05}",
     "above the maximum 0.01 DiffDrive.fmu declares for 'slip', before any run was simulated"),
    ('min="0.01"', "slip: {distribution: fixed, value: 0.005}",
     "draws 0.005 (of 10 planned), below the minimum 0.01 DiffDrive.fmu declares for 'slip'"),
])
def test_a_draw_outside_the_range_an_fmu_declares_is_F110_before_any_run(
        declared: str, given: str, says: str, tmp_path: Path, diff_drive_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The FMU refuses such a value when it is set: the runs failed one by one (exit 1); the
    built-in rover's refusals were caught by its log's wording, a foreign FMU's range never."""
    code, output, text = _slip_given(diff_drive_fmu, tmp_path,
                                     f'<Float64 {declared} name="slip"'.encode(), given, capsys)
    assert code == 2, output
    flat = " ".join(output.split())
    assert f"{_location(text, given)}: error[F110]: uncertainty.parameters.slip: " in flat, output
    assert says in flat, output
    assert not (tmp_path / "c" / "out" / "results.h5").exists()


def test_every_parameter_the_tool_reads_itself_has_its_dimension() -> None:
    """The start position and the kinematic geometry are read by the tool in SI, whatever the
    FMU declares: each has the dimension its value is checked against (C402)."""
    from idefix_rules.campaign.input.campaign_values import (
        CONTRACT_PARAMETERS,
        GEOMETRY_PARAMETERS,
        INITIAL_POSITION,
    )

    assert {*GEOMETRY_PARAMETERS, *INITIAL_POSITION, "initial.yaw"} <= set(CONTRACT_PARAMETERS)


@pytest.mark.parametrize(("old", "new", "says"), [
    # lxml named a file of the current folder that does not exist: "Error reading file
    # '/cwd/modelDescription.xml': Invalid bytes in character encoding"
    (b'modelName="DiffDrive"', b'modelName="Diff\xe9Drive"',
     "its modelDescription.xml is not UTF-8 text, as the FMI standard requires: byte 0xe9 on "
     "line 2"),
    # fmpy's "int() argument must be a string, a bytes-like object or a real number, not
    # 'NoneType'"
    (b'name="pos_y" valueReference="7"', b'name="pos_y"',
     "its modelDescription.xml, line 19: variable 'pos_y' has no valueReference"),
    (b'name="pos_y" valueReference="7"', b'name="pos_y" valueReference="seven"',
     "its modelDescription.xml, line 19: variable 'pos_y' has valueReference 'seven', not a "
     "whole number"),
    # the second 'pos_x' silently stood for both: x read the y position
    (b'name="pos_y" valueReference="7"', b'name="pos_x" valueReference="7"',
     "its modelDescription.xml, line 19: variable 'pos_x' is declared twice (first on line "
     "18)"),
    (b"</ModelVariables>", b"</ModelVariable>",
     "its modelDescription.xml is not well-formed XML: Opening and ending tag mismatch"),
])
def test_a_broken_model_description_is_said_as_such_naming_the_fmu(
        old: bytes, new: bytes, says: str, tmp_path: Path, diff_drive_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    fmu = _edited_diff_drive(diff_drive_fmu, tmp_path, old, new)
    folder = tmp_path / "c"
    folder.mkdir()
    code, output = _run(_campaign(folder, fmu, DIFF_DRIVE_CAMPAIGN), capsys)
    assert code == 2, output
    assert f"{_location(DIFF_DRIVE_CAMPAIGN, 'DiffDrive.fmu')}: error[C400]: " in output, output
    assert f"DiffDrive.fmu: not a readable FMU ({says}" in output, output
    assert "Error reading file" not in output and "NoneType" not in output
