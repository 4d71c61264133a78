"""Every check of a campaign's FMU mapping, before anything is simulated, reported at once.

:func:`check_fmu` reads the FMU's model description and runs small passes, each returning
diagnostics located at the campaign line that says the wrong thing:

* ``fmu_interface``: FMI 2.0 or 3.0, co-simulation or model exchange (C400, stops here when
  not);
* ``parameter_problems`` (:mod:`idefix_rules.campaign.input.parameter_checks`): parameter names,
  settable, dimensions (C401, C402, C504, C505);
* ``signal_problems`` (:mod:`idefix_rules.campaign.input.signal_map_checks`): every mapped
  output exists (did you mean), is an output, has a type a getter reads, a unit of the signal's
  dimension, one variable per signal (C401, C500-C503, C511);
* ``need_problems``: what the rulebook reads (and collisions need) versus what the map
  provides (C405, C512);
* ``chain_problems`` (:mod:`idefix_rules.campaign.input.chain_checks`): the chain delivery
  the campaign asks for is one the FMU can take (C403, C507-C509);
* warnings: terrain or rocks the FMU cannot receive (C510), ranking by energy without
  ``energy`` (C506), run time without ``command`` or ``done`` (C513), a report without
  positions (C514).
"""

from __future__ import annotations

import platform
import sys
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from idefix_rules.campaign.input.chain_checks import chain_problems
from idefix_rules.campaign.input.fmu_variable_checks import Loc, fmu_loc, fmu_names, loc_span
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.input.signal_map_checks import signal_problems
from idefix_rules.errors import Diagnostic, Severity, Span, UserInputError, error, warning
from idefix_rules.fmu.description import FmuDescription, FmuVariable, describe_fmu
from idefix_rules.fmu.mapping import DONE_SIGNAL, TERRAIN_FILE
from idefix_rules.signals import FMU_SIGNALS

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
    problems += terrain_warnings(campaign, check, evaluator)
    problems += run_warnings(campaign, evaluator, check)
    check.warnings = [p for p in problems if p.severity is Severity.WARNING]
    errors = [p for p in problems if p.severity is Severity.ERROR]
    if errors:
        raise UserInputError(errors + check.warnings,
                             sources={str(campaign.source): campaign.text})
    return check


def binary_problems(campaign: Campaign, description: FmuDescription) -> list[Diagnostic]:
    """A damaged file in the FMU's zip, or no binary for this platform: C400 at fmu.path now,
    with the other mistakes, not failed reference runs after the other stages."""
    span = campaign.locations.span(fmu_loc(campaign))
    return [error("C400", f"{description.path}: {problem}", span, hint=hint)
            for problem, hint in ((_damaged_member(description), "copy or export the FMU again"),
                                  (_missing_binary(description) or _foreign_binary(description),
                                   "export the FMU with a binary for this platform (or compile "
                                   "its C sources into one)"))
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


def _binary_member(description: FmuDescription) -> str:
    """The FMU's shared library for this platform, as a path inside it: the model identifier
    of the interface the runner uses (co-simulation first)."""
    import fmpy

    identifier = description.co_simulation or description.model_exchange
    folder = fmpy.platform_tuple if description.major == 3 else fmpy.platform
    return f"binaries/{folder}/{identifier}{fmpy.sharedLibraryExtension}"


def _missing_binary(description: FmuDescription) -> str | None:
    """What is missing when the FMU has no shared library for this platform under the model
    identifier of the interface the runner uses (co-simulation first); None when it has."""
    import fmpy

    wanted = _binary_member(description)
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


# ELF machine numbers (e_machine) of the platforms fmpy runs on, by platform.machine()
_ELF_MACHINES = {"x86_64": 62, "AMD64": 62, "aarch64": 183, "arm64": 183}


def _foreign_binary(description: FmuDescription) -> str | None:
    """On Linux: what is wrong when the FMU's shared library for this platform is no 64-bit
    ELF library for this machine (a truncated file, another architecture), which the workers
    could not load; None when it is one, or when this cannot be told here."""
    machine = _ELF_MACHINES.get(platform.machine())
    if not sys.platform.startswith("linux") or machine is None:
        return None
    wanted = _binary_member(description)
    path = Path(description.path)
    try:
        if path.is_dir():
            with open(path / wanted, "rb") as library:
                header = library.read(20)
        else:
            with zipfile.ZipFile(path) as archive, archive.open(wanted) as library:
                header = library.read(20)
    except (OSError, KeyError, zipfile.BadZipFile, EOFError, zlib.error):
        return None  # missing or unreadable: said by the other checks
    if header[:4] != b"\x7fELF":
        return f"{wanted} is not a shared library (it has no ELF header)"
    if len(header) < 20:
        return f"{wanted} is cut short ({len(header)} bytes)"
    if header[4] != 2:
        return f"{wanted} is a 32-bit library; this machine loads 64-bit ones"
    found = int.from_bytes(header[18:20], "little" if header[5] == 1 else "big")
    if found != machine:
        names = {62: "x86_64", 183: "aarch64", 3: "i386", 40: "arm"}
        return f"{wanted} is built for {names.get(found, f'ELF machine {found}')}; this " \
               f"machine is {platform.machine()}"
    return None


def fmu_interface(campaign: Campaign, fmu_path: Path) -> FmuDescription:
    """The FMU's description; C400 when it is unreadable or not FMI 2.0/3.0 co-simulation."""
    span = campaign.locations.span(fmu_loc(campaign))
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


# ----------------------------------------------------------------------------- needs

def need_problems(campaign: Campaign, evaluator: Any, check: FmuCheck) -> list[Diagnostic]:
    """The rulebook's signals (and the collision checks' pose) must be provided by the map."""
    provided = check.provided
    required = {name for name in getattr(evaluator, "required_signals", ())
                if name in FMU_SIGNALS}
    problems = []
    explicit = campaign.model.fmu.signals is not None
    loc: Loc = ("fmu", "signals") if explicit else fmu_loc(campaign)
    missing = sorted(required - provided)
    if missing:
        text = ", ".join(map(repr, missing))
        problems.append(error(
            "C405", f"fmu.signals: the rulebook reads {text}, which the signal map does not "
                    "provide" if explicit else
                    f"the rulebook reads {text}, which {check.description.path.name} has no "
                    "variable of that name for (and the campaign gives no fmu.signals map)",
            loc_span(campaign, loc),
            hint="map an FMU variable to each (FMU variable: signal), e.g. body.pos.y: y"))
    if getattr(evaluator, "needs_collisions", False):
        pose = sorted(set(POSE) - provided)
        if pose:
            problems.append(error(
                "C512", f"fmu.signals: the rulebook reads collisions, which place the rover's "
                        f"bodies by its pose, but the map does not provide "
                        f"{', '.join(map(repr, pose))}", loc_span(campaign, loc),
                hint="map the FMU's pose outputs (x, y, z, roll, pitch, yaw)"))
    return problems


# ----------------------------------------------------------------------------- warnings

def _terrain_variable(campaign: Campaign, description: FmuDescription) -> FmuVariable | None:
    name = fmu_names(campaign).get(TERRAIN_FILE, TERRAIN_FILE)
    variable = description.variables.get(name)
    return variable if variable is not None and variable.reader == "string" \
        and variable.settable else None


def given_ground(environment: Any) -> list[str]:
    """What of the ground a campaign's environment gives: ``terrain`` (a DEM or a synthetic
    terrain), ``rocks``."""
    return [what for what, given in (
        ("terrain", environment.terrain.dem or environment.terrain.synthetic),
        ("rocks", environment.rocks)) if given]


def unseen_ground_text(what: str, fmu_name: str, reads_collisions: bool) -> str:
    """What C510 says of the campaign's ``what`` (``terrain`` or ``rocks``) that an FMU without
    a terrain input does not see, for a rulebook that reads collisions (or areas) or not: the
    report's note says the same.

    >>> print(unseen_ground_text("rocks", "rover.fmu", False))  # doctest: +NORMALIZE_WHITESPACE
    rover.fmu has no terrain input ('terrain.file'), so its runs do not see the campaign's rocks;
    the rulebook reads no collision or area signal, so they play no part in the risks
    """
    said = (f"{fmu_name} has no terrain input ('{TERRAIN_FILE}'), so its runs do not see the "
            f"campaign's {what}")
    if not reads_collisions:
        they = "it plays" if what == "terrain" else "they play"
        return f"{said}; the rulebook reads no collision or area signal, so {they} no part in " \
            "the risks"
    if what == "terrain":
        return (f"{said}; the rulebook's collision and area signals are still computed "
                "geometrically from the runs' pose, against the campaign's obstacles on this "
                "terrain (not on the ground the FMU drove on)")
    return (f"{said}; the rulebook's collision signals are still computed geometrically from "
            "the runs' pose against them")


def terrain_warnings(campaign: Campaign, check: FmuCheck, evaluator: Any) -> list[Diagnostic]:
    """Terrain or rocks the FMU has no terrain input for: it drives on its own ground."""
    if check.terrain_input:
        return []
    reads_collisions = bool(getattr(evaluator, "needs_collisions", False))
    return [warning(
        "C510", f"environment.{what}: "
                f"{unseen_ground_text(what, check.description.path.name, reads_collisions)}",
        loc_span(campaign, ("environment", what)),
        hint="give the FMU a String parameter for docs/terrain-format.md files and map it: "
             "fmu.parameters: {its.name: terrain.file}")
        for what in given_ground(campaign.model.environment)]


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
            loc_span(campaign, ("fmu", "signals") if campaign.model.fmu.signals is not None
                  else fmu_loc(campaign)),
            hint="map the FMU's body position outputs to 'x' and 'y'"))
    if not provided & {"command", DONE_SIGNAL} and campaign.model.fmu.chain.delivery != "none":
        problems.append(warning(
            "C513", "a run's time is its stop time: the map provides neither 'command' nor "
                    "'done'", loc_span(campaign, ("fmu", "signals") if campaign.model.fmu.signals
                                    is not None else fmu_loc(campaign)),
            hint="map an output that reports the chain complete to 'done' (with fmu.done_at)"))
    return problems


def describe_warnings(diagnostics: Iterable[Diagnostic], sources: Mapping[str, str]
                      ) -> list[str]:
    """Warnings as the texts the CLI prints (location, source line with a caret, hint)."""
    # The CLI says "warning:" itself; the code stays, in brackets.
    return [d.format(sources.get(d.span.path) if d.span is not None else None)
            .replace(f"{d.severity.value}[{d.code}]: ", f"[{d.code}] ", 1)
            for d in diagnostics]
