"""Every check of a campaign's FMU mapping, before anything is simulated, reported at once.

:func:`check_fmu` reads the FMU's model description and runs small passes, each returning
diagnostics located at the campaign line that says the wrong thing:

* ``fmu_interface``: FMI 2.0 or 3.0, co-simulation or model exchange (C400, stops here when
  not);
* ``parameter_problems`` (:mod:`idefix_rules.campaign.input.parameter_checks`): parameter names,
  settable, dimensions (C401, C402, C504, C505);
* ``signal_problems``: every mapped output exists (did you mean), is an output, has a type a
  getter reads, a unit of the signal's dimension, one variable per signal (C401, C500-C503, C511);
* ``need_problems``: what the rulebook reads (and collisions need) versus what the map
  provides (C405, C512);
* ``chain_problems``: the chain delivery the campaign asks for is one the FMU can take
  (C403, C507-C509);
* warnings: terrain or rocks the FMU cannot receive (C510), ranking by energy without
  ``energy`` (C506), run time without ``command`` or ``done`` (C513), a report without
  positions (C514).
"""

from __future__ import annotations

import difflib
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.yamlsource import format_loc
from idefix_rules.errors import Diagnostic, Severity, Span, UserInputError, error, warning
from idefix_rules.fmu.archive import default_signal_map
from idefix_rules.fmu.description import FmuDescription, FmuVariable, describe_fmu
from idefix_rules.fmu.mapping import CHAIN_ARRAYS, CHAIN_COUNT, DONE_SIGNAL, TERRAIN_FILE
from idefix_rules.fmu.setpoints import SETPOINTS
from idefix_rules.signals import AXIS_LABELS, FMU_SIGNALS
from idefix_rules.units import parse_unit

Loc = tuple[str | int, ...]
# The pose the collision checks place the rover's bodies with.
POSE = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass
class FmuCheck:
    """What the checks found out: the description, the signal map in effect, whether the FMU
    takes the terrain file, and the warnings to show before simulating."""

    description: FmuDescription
    signal_map: dict[str, str]
    terrain_input: bool
    warnings: list[Diagnostic] = field(default_factory=list)

    @property
    def provided(self) -> set[str]:
        """Contract signals the map provides (``t`` always: the runner fills in the grid)."""
        return {target.split("[", 1)[0] for target in self.signal_map.values()} | {"t"}


def check_fmu(campaign: Campaign, fmu_path: Path, evaluator: Any) -> FmuCheck:
    """Run every check; raise one :class:`UserInputError` holding every error (warnings too)."""
    from idefix_rules.campaign.input.areas import area_problems
    from idefix_rules.campaign.input.parameter_checks import parameter_problems

    description = fmu_interface(campaign, fmu_path)
    problems = binary_problems(campaign, description) + parameter_problems(campaign, description)
    signal_map, found = signal_problems(campaign, description)
    problems += found
    check = FmuCheck(description, signal_map, _terrain_variable(campaign, description) is not None)
    problems += need_problems(campaign, evaluator, check)
    problems += chain_problems(campaign, description)
    problems += area_problems(campaign, evaluator)
    problems += terrain_warnings(campaign, check) + run_warnings(campaign, evaluator, check)
    check.warnings = [p for p in problems if p.severity is Severity.WARNING]
    errors = [p for p in problems if p.severity is Severity.ERROR]
    if errors:
        raise UserInputError(errors + check.warnings,
                             sources={str(campaign.source): campaign.text})
    return check


def _span(campaign: Campaign, loc: Loc, at_key: bool = True) -> Span:
    return campaign.locations.span(loc, at_key=at_key)


def _fmu_loc(campaign: Campaign) -> Loc:
    """Where the campaign names its FMU (the whole file for the built-in rover)."""
    return ("fmu", "path") if campaign.fmu is not None else ("fmu",)


def binary_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    """A damaged file in the FMU's zip, or no binary for this platform: C400 at fmu.path now,
    with the other mistakes, not failed reference runs after the other stages."""
    span = campaign.locations.span(_fmu_loc(campaign))
    return [error("C400", f"{description.path}: {problem}", span, hint=hint)
            for problem, hint in ((_damaged_member(description), "copy or export the FMU again"),
                                  (_missing_binary(description), "export the FMU with a binary "
                                   "for this platform (or compile its C sources into one)"))
            if problem is not None]


def _damaged_member(description: FmuDescription) -> str | None:
    """The first file of the FMU's zip whose bytes do not match their checksum, said; None
    for a sound zip (or an extracted folder)."""
    path = Path(description.path)
    if path.is_dir():
        return None
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
    except (OSError, zipfile.BadZipFile, EOFError, zlib.error) as failure:
        return f"not a readable FMU ({failure})"
    return None if bad is None else f"not a readable FMU: {bad} is damaged (its checksum " \
        "does not match)"


def _missing_binary(description: FmuDescription) -> str | None:
    """What is missing when the FMU has no shared library for this platform under the model
    identifier of the interface the runner uses (co-simulation first); None when it has."""
    import fmpy

    identifier = description.co_simulation or description.model_exchange
    folder = fmpy.platform_tuple if description.major == 3 else fmpy.platform
    wanted = f"binaries/{folder}/{identifier}{fmpy.sharedLibraryExtension}"
    path = Path(description.path)
    if path.is_dir():
        present = (path / wanted).is_file()
    else:
        with zipfile.ZipFile(path) as archive:
            present = wanted in archive.namelist()
    if present:
        return None
    supported = fmpy.supported_platforms(str(path))
    platforms = [p for p in supported if p != "c-code"]
    has = f"it has binaries for {', '.join(platforms)}" if platforms else "it has no binaries"
    sources = " and C sources" if "c-code" in supported else ""
    return f"no binary for this platform ({wanted} is missing); {has}{sources}"


def _did_you_mean(name: str, known: Iterable[str]) -> str | None:
    # FMU variable names are often short ('px', 'v'): a lower cut-off than difflib's 0.6
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.5)
    return f"did you mean {close[0]!r}?" if close else None


def fmu_interface(campaign: Campaign, fmu_path: Path) -> FmuDescription:
    """The FMU's description; C400 when it is unreadable or not FMI 2.0/3.0 co-simulation."""
    span = campaign.locations.span(_fmu_loc(campaign))
    try:
        description = describe_fmu(fmu_path, span)
    except UserInputError as failure:
        reason = failure.diagnostics[0].message.removeprefix("not a readable FMU: ")
        raise UserInputError(error("C400", f"{fmu_path}: not a readable FMU ({reason})", span),
                             sources={str(campaign.source): campaign.text}) from None
    if description.major in (2, 3) and (description.co_simulation or description.model_exchange):
        return description  # model exchange only: fmpy's solver integrates it
    kinds = ", ".join(kind for kind, part in (("co-simulation", description.co_simulation),
                                              ("model exchange", description.model_exchange))
                      if part)
    raise UserInputError(error(
        "C400", f"{fmu_path}: an FMI {description.fmi_version} FMU for {kinds or 'nothing'}; "
                "the campaign runner needs FMI 2.0 or 3.0 co-simulation or model exchange",
        span, hint="export the model as an FMI 2.0 or 3.0 co-simulation FMU"),
        sources={str(campaign.source): campaign.text})


# ----------------------------------------------------------------------------- signals

def signal_problems(campaign: Campaign, description: FmuDescription
                    ) -> tuple[dict[str, str], list[Diagnostic]]:
    """The signal map in effect and what is wrong with it."""
    explicit = campaign.model.fmu.signals
    if explicit is None:
        try:
            mapping = default_signal_map(description, Path(description.path))
        except UserInputError as failure:  # its shipped signal_map.json: said at fmu.path
            return {}, [error("C400", f"{description.path.name}: "
                                      f"{failure.diagnostics[0].message}",
                              _span(campaign, _fmu_loc(campaign)),
                              hint="give the campaign its own map (fmu.signals: FMU variable: "
                                   "signal)")]
        absent = [name for name in mapping if name not in description.variables]
        problems = [] if not absent else [error(
            "C401", f"the signal map shipped in {description.path.name} names "
                    f"{len(absent)} variable(s) it does not have: "
                    f"{', '.join(map(repr, absent[:6]))}{' …' if len(absent) > 6 else ''}",
            _span(campaign, _fmu_loc(campaign)),
            hint="give the campaign its own map (fmu.signals: FMU variable: signal)")]
        return mapping, problems + [
            problem for fmu_name, target in mapping.items() if fmu_name not in absent
            for problem in _signal_entry(campaign, description, fmu_name, target,
                                         _fmu_loc(campaign))]
    problems = []
    seen: dict[str, str] = {}
    for fmu_name, target in explicit.items():
        loc: Loc = ("fmu", "signals", fmu_name)
        entry = _signal_entry(campaign, description, fmu_name, target, loc)
        problems += entry
        if entry:
            continue
        if target in seen:
            problems.append(error(
                "C511", f"{format_loc(loc)}: signal '{target}' is mapped from both "
                        f"'{seen[target]}' and '{fmu_name}'", _span(campaign, loc),
                hint="map each signal from one FMU variable"))
        seen[target] = fmu_name
    problems += _partial_wheels(campaign, seen) + _unreachable_done(campaign, description, seen)
    return dict(explicit), problems


def _unreachable_done(campaign: Campaign, description: FmuDescription, seen: dict[str, str]
                      ) -> list[Diagnostic]:
    """``done`` from a Boolean output reads 0 or 1: a ``done_at`` above 1 is never reached
    (every run would drive to the stop limit), one at 0 or below at the first sample."""
    variable = description.variables.get(seen.get(DONE_SIGNAL, ""))
    done_at = campaign.model.fmu.done_at
    if variable is None or variable.reader != "boolean" or 0.0 < done_at <= 1.0:
        return []
    loc: Loc = ("fmu", "done_at")
    reached = "never reaches" if done_at > 1 else "is from the first sample at least"
    return [error("C502", f"{format_loc(loc)}: {variable.name!r} is a {variable.type}, read as "
                          f"0 or 1: 'done' {reached} {done_at:g}",
                  _span(campaign, loc, at_key=False),
                  hint="leave done_at out (1: true) for a Boolean output")]


def _partial_wheels(campaign: Campaign, seen: dict[str, str]) -> list[Diagnostic]:
    """A wheel signal is four columns: mapped for some wheels only, the others would be empty
    (not a number) and every run would fail on them."""
    problems = []
    wheels = AXIS_LABELS["wheel"]
    for base in dict.fromkeys(target.partition("[")[0] for target in seen):
        mapped = [w for w in wheels if f"{base}[{w}]" in seen]
        if mapped and len(mapped) < len(wheels):
            loc: Loc = ("fmu", "signals", seen[f"{base}[{mapped[0]}]"])
            missing = [w for w in wheels if w not in mapped]
            problems.append(error(
                "C500", f"{format_loc(loc)}: signal '{base}' is mapped for "
                        f"{', '.join(mapped)} only: a wheel signal has all four wheels",
                _span(campaign, loc, at_key=False),
                hint=f"map {', '.join(f'{base}[{w}]' for w in missing)} too, or none of them"))
    return problems


def _signal_entry(campaign: Campaign, description: FmuDescription, fmu_name: str,
                  target: str, loc: Loc) -> list[Diagnostic]:
    """One ``FMU variable: signal`` entry: exists, names a signal, output, readable, unit."""
    where = format_loc(loc)
    fmu_file = description.path.name
    variable = description.variables.get(fmu_name)
    whole = description.variables.get(fmu_name.partition("[")[0])
    if variable is None and whole is not None and whole.array:
        return [error("C502", f"{where}: {fmu_name!r} is an element of {whole.name!r}, a "
                              f"{whole.type}: elements of FMI 3 arrays are not read",
                      _span(campaign, loc), hint="map a scalar output of the FMU")]
    if variable is None:
        outputs = [v.name for v in description.variables.values() if v.causality == "output"]
        return [error("C401", f"{where}: unknown FMU variable {fmu_name!r} in {fmu_file}",
                      _span(campaign, loc),
                      _did_you_mean(fmu_name, outputs or description.variables))]
    base, _, rest = target.partition("[")
    spec = FMU_SIGNALS.get(base)
    value_span = _span(campaign, loc, at_key=False)
    if spec is None:
        return [error("C500", f"{where}: {target!r} is not a signal an FMU provides",
                      value_span, _did_you_mean(base, FMU_SIGNALS)
                      or f"one of {', '.join(FMU_SIGNALS)}")]
    wheels = AXIS_LABELS["wheel"]
    if "wheel" in spec.axes and rest.rstrip("]") not in wheels:
        return [error("C500", f"{where}: {target!r} needs one wheel, e.g. '{base}[FL]'",
                      value_span, hint=f"wheels are {', '.join(wheels)}")]
    if "wheel" not in spec.axes and rest:
        return [error("C500", f"{where}: {target!r}: signal '{base}' has no wheel axis",
                      value_span)]
    problems = []
    if variable.causality != "output":
        problems.append(error(
            "C501", f"{where}: {fmu_name!r} is {_article(variable.causality)}; a signal must "
                    "be an output of the FMU", _span(campaign, loc),
            hint="`fmpy info` lists the FMU's outputs"))
    if variable.reader not in ("real", "integer", "boolean"):
        problems.append(error(
            "C502", f"{where}: {fmu_name!r} is a {variable.type}; a signal is read from a "
                    "Real/Float, Integer, Boolean or Enumeration output", _span(campaign, loc)))
    problems += _unit_problem(campaign, loc, variable, base, spec.unit)
    return problems


def _article(causality: str) -> str:
    return f"an {causality}" if causality[:1] in "aeiou" else f"a {causality}"


def _unit_problem(campaign: Campaign, loc: Loc, variable: FmuVariable, name: str,
                  unit: str) -> list[Diagnostic]:
    """A declared unit whose dimension is not the signal's (or set-point's) is an error, and
    so is one the tool cannot read (its values would be taken as SI: `milli-metre` as metres)."""
    if name == DONE_SIGNAL:
        return []
    if variable.si is None:
        if not variable.unit or variable.unit == "-":  # none declared: SI as the docs say
            return []
        return [error("C503", f"{format_loc(loc)}: {variable.name!r} is in "
                              f"{variable.unit!r}, which this tool cannot convert ('{name}' "
                              f"is in {unit})", _span(campaign, loc, at_key=False),
                      hint="declare the unit in SI symbols (mm, m/s, rad, A.s …, or a "
                           "<BaseUnit> without an offset) or map another variable")]
    expected = parse_unit(unit)
    if variable.si.dimension == expected.dimension:
        return []
    return [error("C503", f"{format_loc(loc)}: {variable.name!r} is in {variable.unit}, but "
                          f"'{name}' is in {unit}", _span(campaign, loc, at_key=False),
                  hint="map a variable of that dimension (values are converted to SI by the "
                       "FMU's declared unit)")]


# ----------------------------------------------------------------------------- needs

def need_problems(campaign: Campaign, evaluator: Any, check: FmuCheck) -> list[Diagnostic]:
    """The rulebook's signals (and the collision checks' pose) must be provided by the map."""
    provided = check.provided
    required = {name for name in getattr(evaluator, "required_signals", ())
                if name in FMU_SIGNALS}
    problems = []
    explicit = campaign.model.fmu.signals is not None
    loc: Loc = ("fmu", "signals") if explicit else _fmu_loc(campaign)
    missing = sorted(required - provided)
    if missing:
        text = ", ".join(map(repr, missing))
        problems.append(error(
            "C405", f"fmu.signals: the rulebook reads {text}, which the signal map does not "
                    "provide" if explicit else
                    f"the rulebook reads {text}, which {check.description.path.name} has no "
                    "variable of that name for (and the campaign gives no fmu.signals map)",
            _span(campaign, loc),
            hint="map an FMU variable to each (FMU variable: signal), e.g. body.pos.y: y"))
    if getattr(evaluator, "needs_collisions", False):
        pose = sorted(set(POSE) - provided)
        if pose:
            problems.append(error(
                "C512", f"fmu.signals: the rulebook reads collisions, which place the rover's "
                        f"bodies by its pose, but the map does not provide "
                        f"{', '.join(map(repr, pose))}", _span(campaign, loc),
                hint="map the FMU's pose outputs (x, y, z, roll, pitch, yaw)"))
    return problems


# ----------------------------------------------------------------------------- chain

def chain_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    """The chain delivery the campaign asks for must fit the FMU."""
    chain = campaign.model.fmu.chain
    if chain.delivery == "inputs":
        return _input_problems(campaign, description)
    problems = []
    if chain.inputs:
        problems.append(error(
            "C508", f"fmu.chain.inputs: set-points given, but fmu.chain.delivery is "
                    f"{chain.delivery!r}", _span(campaign, ("fmu", "chain", "inputs")),
            hint="set fmu.chain.delivery: inputs to feed them"))
    if chain.delivery == "none":
        return problems
    return problems + _parameter_chain(campaign, description)


def _fmu_names(campaign: Campaign) -> dict[str, str]:
    """Our parameter name → the FMU variable it is mapped to (``fmu.parameters`` reversed)."""
    return {ours: theirs for theirs, ours in (campaign.model.fmu.parameters or {}).items()}


def _parameter_chain(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    renamed = _fmu_names(campaign)
    variables = description.variables
    loc: Loc = ("fmu", "chain") if campaign.locations.keys.get(("fmu", "chain")) \
        else _fmu_loc(campaign)
    count_name = renamed.get(CHAIN_COUNT, CHAIN_COUNT)
    first = [renamed.get(f"{array}[0]", f"{array}[0]") for array in CHAIN_ARRAYS]
    absent = [name for name in (count_name, *first) if name not in variables]
    if absent:
        return [error(
            "C507", f"{description.path.name} takes no command chain as parameters: it has no "
                    f"{', '.join(map(repr, absent))}", _span(campaign, loc),
            hint="map its chain parameters in fmu.parameters (FMU variable: chain.count, …), "
                 "or set fmu.chain.delivery to 'inputs' (set-points each step) or 'none'")]
    problems = []
    for name in (count_name, *first):
        variable = variables[name]
        if not variable.settable:
            problems.append(error(
                "C507", f"chain variable {name!r} is {_article(variable.causality)}"
                        f" ({variable.variability}); the chain is set as parameters",
                _span(campaign, loc)))
    if variables[count_name].reader != "integer":
        problems.append(error(
            "C507", f"chain variable {count_name!r} is a {variables[count_name].type}; the "
                    "command count is an Integer", _span(campaign, loc)))
    capacity = 0
    while all(renamed.get(f"{array}[{capacity}]", f"{array}[{capacity}]") in variables
              for array in CHAIN_ARRAYS):
        capacity += 1
    problems += [error("C403", f"paths.{spec.name}: {len(spec.chain)} commands, but "
                               f"{description.path.name} takes at most {capacity} per chain "
                               f"(chain.max_wheel_rate[0] … [{capacity - 1}])",
                       campaign.locations.span(("paths", spec.name), at_key=True),
                       hint="split the chain, or use an FMU built for longer chains")
                 for spec in campaign.paths if len(spec.chain) > capacity]
    return problems


def _input_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    inputs = campaign.model.fmu.chain.inputs
    if not inputs:
        return [error("C508", "fmu.chain: delivery 'inputs' needs fmu.chain.inputs (FMU input: "
                              "set-point)", _span(campaign, ("fmu", "chain")),
                      hint=f"set-points: {', '.join(SETPOINTS)}")]
    problems = []
    for fmu_name, setpoint in inputs.items():
        loc: Loc = ("fmu", "chain", "inputs", fmu_name)
        where = format_loc(loc)
        variable = description.variables.get(fmu_name)
        if variable is None:
            inputs_known = [v.name for v in description.variables.values()
                            if v.causality == "input"] or list(description.variables)
            problems.append(error("C401", f"{where}: unknown FMU variable {fmu_name!r} in "
                                          f"{description.path.name}", _span(campaign, loc),
                                  _did_you_mean(fmu_name, inputs_known)))
            continue
        if setpoint not in SETPOINTS:
            problems.append(error(
                "C509", f"{where}: {setpoint!r} is not a set-point",
                _span(campaign, loc, at_key=False),
                _did_you_mean(setpoint, SETPOINTS) or f"one of {', '.join(SETPOINTS)}"))
            continue
        if variable.causality != "input":
            problems.append(error(
                "C501", f"{where}: {fmu_name!r} is {_article(variable.causality)}; set-points "
                        "are fed to inputs of the FMU every step", _span(campaign, loc)))
        if variable.reader not in ("real", "integer"):
            problems.append(error(
                "C502", f"{where}: {fmu_name!r} is a {variable.type}; a set-point is a Real "
                        "(or, for 'command', an Integer) input", _span(campaign, loc)))
        problems += _unit_problem(campaign, loc, variable, setpoint, SETPOINTS[setpoint])
    return problems


# ----------------------------------------------------------------------------- warnings

def _terrain_variable(campaign: Campaign, description: FmuDescription) -> FmuVariable | None:
    name = _fmu_names(campaign).get(TERRAIN_FILE, TERRAIN_FILE)
    variable = description.variables.get(name)
    return variable if variable is not None and variable.reader == "string" \
        and variable.settable else None


def terrain_warnings(campaign: Campaign, check: FmuCheck) -> list[Diagnostic]:
    """Terrain or rocks the FMU has no terrain input for: it drives on its own ground."""
    if check.terrain_input:
        return []
    environment = campaign.model.environment
    given = [("terrain",) if environment.terrain.dem or environment.terrain.synthetic else None,
             ("rocks",) if environment.rocks else None]
    return [warning(
        "C510", f"environment.{loc[0]}: {check.description.path.name} has no terrain input "
                f"('{TERRAIN_FILE}'), so its runs do not see the campaign's {loc[0]}; "
                "collisions are still evaluated geometrically against the campaign's rocks",
        _span(campaign, ("environment", *loc)),
        hint="give the FMU a String parameter for docs/terrain-format.md files and map it: "
             "fmu.parameters: {its.name: terrain.file}")
        for loc in given if loc is not None]


def run_warnings(campaign: Campaign, evaluator: Any, check: FmuCheck) -> list[Diagnostic]:
    """What the tool cannot do without 'energy', 'command'/'done' and 'x'/'y'."""
    provided = check.provided
    problems = []
    ranking = getattr(getattr(getattr(evaluator, "checked", None), "rulebook", None),
                      "ranking", None)
    if "energy" not in provided and ranking is not None:
        for key in ranking.keys:
            if getattr(key.expr, "name", None) == "energy":
                span = key.span if key.span.line > 0 else Span(str(campaign.rulebook))
                problems.append(warning(
                    "C506", "ranking by energy is unavailable: the FMU's signal map provides "
                            "no 'energy'; paths equal in the other keys are ranked by name",
                    span, hint="map the FMU's cumulative charge output to 'energy', or rank "
                               "without energy"))
    position = sorted({"x", "y"} - provided)
    if position:
        problems.append(warning(
            "C514", f"the report draws no runs on its result maps and no box plots: the map "
                    f"provides no {' or '.join(map(repr, position))}",
            _span(campaign, ("fmu", "signals") if campaign.model.fmu.signals is not None
                  else _fmu_loc(campaign)),
            hint="map the FMU's body position outputs to 'x' and 'y'"))
    if not provided & {"command", DONE_SIGNAL} and campaign.model.fmu.chain.delivery != "none":
        problems.append(warning(
            "C513", "a run's time is its stop time: the map provides neither 'command' nor "
                    "'done'", _span(campaign, ("fmu", "signals") if campaign.model.fmu.signals
                                    is not None else _fmu_loc(campaign)),
            hint="map an output that reports the chain complete to 'done' (with fmu.done_at)"))
    return problems


def describe_warnings(diagnostics: Iterable[Diagnostic], sources: Mapping[str, str]
                      ) -> list[str]:
    """Warnings as the texts the CLI prints (location, source line with a caret, hint)."""
    # The CLI says "warning:" itself; the code stays, in brackets.
    return [d.format(sources.get(d.span.path) if d.span is not None else None)
            .replace(f"{d.severity.value}[{d.code}]: ", f"[{d.code}] ", 1)
            for d in diagnostics]
