"""Case files: example runs next to a rulebook and what the rulebook must say about them.

A case file is YAML (loaded safely, every node located) with the rulebook it tests, defaults
and named cases; ``docs/testing-rulebooks.md`` describes the format. Loading validates the whole
file and raises one :class:`~idefix_rules.errors.UserInputError` with every mistake found
(codes T001–T099, each at its line and column); the rulebook's own problems keep their codes.
What a case file describes is in :mod:`.case_model`; a case's run groups are read by
:mod:`.case_runs`, its expectations by :mod:`.case_expectations`.

>>> text = '''
... rulebook: ../idefix-ops.rules
... cases:
...   calm:
...     expect: {verdict: pass}
... '''
>>> case_file = parse_case_file(text, "rulebooks/tests/x.yaml")  # doctest: +SKIP
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from idefix_rules.campaign.input.yamlsource import Loc, load_yaml
from idefix_rules.commands import Command, RoverGeometry, chain_duration
from idefix_rules.errors import (
    Diagnostic,
    Span,
    UserInputError,
    error,
    read_user_text,
    unique_diagnostics,
)
from idefix_rules.rulebook import check_text, read_source
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.testing.case_expectations import read_expectations
from idefix_rules.testing.case_model import (
    DEFAULT_SETTLE,
    DEFAULT_SIGMA,
    DEFAULT_STEP,
    DEFAULT_TOLERANCE,
    MAX_SAMPLES,
    Case,
    CaseFile,
    Collision,
    Expectation,
    Keyframes,
    RunGroup,
)
from idefix_rules.testing.case_reader import CaseReader
from idefix_rules.testing.case_runs import read_keyframe_block, read_run_group
from idefix_rules.units import ANGLE, DIMENSIONLESS, LENGTH, TIME, Dimension

_TOP_KEYS = ("rulebook", "defaults", "cases", "tolerance")
_SETUP_KEYS = ("chain", "step", "duration", "initial_position_sigma", "wheel_ramp")
_RUN_KEYS = ("signals", "offsets", "collisions", "unfinished")
_CASE_KEYS = ("description", *_SETUP_KEYS, *_RUN_KEYS, "reference", "runs", "variants",
              "failed_runs", "expect")
_WHEEL_RATE = Dimension(angle=1, time=-1)


# A case file has a top-level `cases:` (a campaign file, also YAML and also naming a
# `rulebook:`, has none)
_CASES_KEY = re.compile(r"^cases\s*:", re.MULTILINE)


def _holds_cases(path: Path) -> bool:
    from idefix_rules.limits import MAX_CASE_FILE_BYTES

    try:
        if path.stat().st_size > MAX_CASE_FILE_BYTES:
            return True  # refused as T001 for its size, before it is read
        return bool(_CASES_KEY.search(path.read_text(encoding="utf-8")))
    except (OSError, UnicodeDecodeError):
        return True  # said as T001 when it is read


def discover_case_files(paths: Sequence[str | Path]) -> list[Path]:
    """Case files named by ``paths``: files as given, folders searched for ``*.yaml``/``*.yml``
    holding a top-level ``cases:`` (recursively, sorted: a project folder's campaign files
    are no case files), each file once however often it is named. No path:
    ``rulebooks/tests`` under the working folder."""
    found: list[Path] = []
    seen: set[Path] = set()
    for path in (paths or [Path("rulebooks/tests")]):
        path = Path(path)
        if path.is_dir():
            named = sorted(p for p in path.rglob("*") if p.suffix in (".yaml", ".yml")
                           and p.is_file() and _holds_cases(p))
        else:
            named = [path]
        for file in named:
            key = file.resolve()
            if key not in seen:
                seen.add(key)
                found.append(file)
    if not found:
        where = ", ".join(map(str, paths)) or "rulebooks/tests"
        raise UserInputError(error("T013", f"no case files (*.yaml with cases:) found in {where}",
                                   Span(where)))
    return found


def load_case_file(path: str | Path) -> CaseFile:
    """Read, validate and check a case file and its rulebook; every mistake in one error."""
    from idefix_rules.limits import MAX_CASE_FILE_BYTES, check_file_size

    check_file_size(path, MAX_CASE_FILE_BYTES, "T001", "case file")
    text = read_user_text(path, "T001", "case file")
    if Path(path).suffix == ".rules":
        raise UserInputError(_a_rulebook(str(path)))
    return parse_case_file(text, str(path))


# The header a rulebook starts with (after comments); a case file's first key is `rulebook:`
_RULEBOOK_HEADER = re.compile(r'(?:\s|#[^\n]*)*rulebook[ \t]+"')


def _a_rulebook(path: str) -> list[Diagnostic]:
    """T001 for a rulebook named where a case file is wanted (``idefix-verify test
    rulebooks/idefix-ops.rules``), naming the case files beside it that test it."""
    rulebook = Path(path)
    beside = sorted(p for folder in (rulebook.parent / "tests", rulebook.parent)
                    if folder.is_dir() for p in folder.glob("*.y*ml")
                    if p.suffix in (".yaml", ".yml") and _holds_cases(p))
    naming = [p for p in beside if _names_rulebook(p, rulebook.name)] or beside
    shown = ", ".join(str(p) for p in naming[:3]) + (", …" if len(naming) > 3 else "")
    hint = (f"its case files: {shown}; " if naming else "") + \
        f"`idefix-verify check {path}` checks the rulebook itself"
    return [error("T001", f"{path} is a rulebook, not a case file: `idefix-verify test` takes "
                  "case files (YAML with 'rulebook:' and 'cases:', docs/testing-rulebooks.md)",
                  Span(path), hint)]


def _names_rulebook(case_file: Path, name: str) -> bool:
    try:
        return name in case_file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False


def _keyframes_at(loc: Loc) -> bool:
    """Whether the mapping at ``loc`` is a signal's keyframes (``cases.NAME.signals.SIGNAL``,
    also in ``offsets``, ``reference`` and a variant), whose keys are times: ``0`` is read as
    the time written without its unit (T005), not refused as a key that is no name."""
    return len(loc) >= 4 and loc[0] == "cases" and loc[-2] in ("signals", "offsets",
                                                               "reference")


def parse_case_file(text: str, path: str) -> CaseFile:
    try:
        document = load_yaml(text, path, keys_as_written=_keyframes_at)
    except UserInputError as failure:  # YAML syntax: same place, this file's code range
        if _RULEBOOK_HEADER.match(text):
            raise UserInputError(_a_rulebook(path)) from None
        raise UserInputError([error("T001", d.message, d.span, d.hint)
                              for d in failure.diagnostics], {path: text}) from None
    reader = CaseReader(document.locations)
    data = document.data
    if not isinstance(data, dict):
        if _RULEBOOK_HEADER.match(text):
            raise UserInputError(_a_rulebook(path))
        raise UserInputError(error("T002", "a case file is a mapping with 'rulebook' and "
                                   "'cases'", Span(path, 1, 1)), {path: text})
    reader.unknown_keys(data, (), _TOP_KEYS)
    checked, rulebook_path = _rulebook(reader, data, path)
    if checked is not None:
        reader.areas = tuple(area.name for area in checked.areas)
    tolerance = DEFAULT_TOLERANCE
    if "tolerance" in data:
        given = reader.number(data["tolerance"], ("tolerance",), minimum=0.0)
        tolerance = tolerance if given is None else given
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        reader.fail("T002", "'defaults' must be a mapping", ("defaults",))
        defaults = {}
    reader.unknown_keys(defaults, ("defaults",), _SETUP_KEYS)
    cases_data = data.get("cases")
    if not isinstance(cases_data, dict) or not cases_data:
        reader.fail("T002", "'cases' must be a mapping of case names to cases", ("cases",))
        cases_data = {}
    cases = []
    for name, case_data in cases_data.items():
        case = _case(reader, str(name), case_data, defaults, checked, tolerance)
        if case is not None:
            cases.append(case)
    if reader.problems:
        sources = {path: text}
        if checked is not None:
            sources[checked.rulebook.path] = checked.rulebook.source
        # a mistake in 'defaults' is read again with every case: said once
        raise UserInputError(unique_diagnostics(reader.problems), sources)
    assert checked is not None
    return CaseFile(path, rulebook_path, checked, tuple(cases), text)


def _rulebook(reader: CaseReader, data: Mapping[str, Any], path: str
              ) -> tuple[CheckedRulebook | None, str]:
    name = data.get("rulebook")
    if not isinstance(name, str) or not name.strip():
        reader.fail("T003", "the case file must name its rulebook: 'rulebook: PATH' (relative "
                    "to the case file)", ("rulebook",))
        return None, ""
    rulebook_path = os.path.normpath(Path(path).parent / name)
    try:
        source = read_source(rulebook_path)
    except UserInputError as failure:
        reader.fail("T003", failure.diagnostics[0].message, ("rulebook",))
        return None, rulebook_path
    try:
        result = check_text(source, rulebook_path)
    except UserInputError as failure:
        reader.problems += failure.diagnostics
        return None, rulebook_path
    if result.checked is None:
        reader.problems += result.errors
    return result.checked, rulebook_path


def _case(reader: CaseReader, name: str, data: Any, defaults: Mapping[str, Any],
          checked: CheckedRulebook | None, tolerance: float) -> Case | None:
    loc: Loc = ("cases", name)
    if not isinstance(data, dict):
        reader.fail("T002", f"case {name!r} must be a mapping", loc)
        return None
    reader.unknown_keys(data, loc, _CASE_KEYS)
    setup = {**defaults, **{k: v for k, v in data.items() if k in _SETUP_KEYS}}

    def where(key: str) -> Loc:
        return (*loc, key) if key in data else ("defaults", key)

    chain = _chain(reader, setup.get("chain", []), where("chain"))
    step = DEFAULT_STEP
    if "step" in setup:
        given = reader.quantity(setup["step"], where("step"), TIME, "step")
        if given is not None and given <= 0:
            reader.fail("T005", "step must be above 0 s", where("step"))
        elif given is not None:
            step = given
    duration = None
    if "duration" in setup:
        duration = reader.quantity(setup["duration"], where("duration"), TIME, "duration")
        if duration is not None and not 0 <= duration <= MAX_SAMPLES * step:
            reader.fail("T005", f"duration must lie between 0 s and {MAX_SAMPLES} steps "
                        f"({MAX_SAMPLES * step:g} s at this step)", where("duration"))
            duration = None
    sigma = DEFAULT_SIGMA
    if "initial_position_sigma" in setup:
        found = reader.quantity(setup["initial_position_sigma"], where("initial_position_sigma"),
                                LENGTH, "initial_position_sigma")
        if found is not None and found <= 0:
            reader.fail("T005", "initial_position_sigma must be above 0 (it is the starting "
                        "tolerance radius)", where("initial_position_sigma"))
        elif found is not None:
            sigma = found
    ramp = RoverGeometry().wheel_acceleration
    if "wheel_ramp" in setup:
        found = reader.quantity(setup["wheel_ramp"], where("wheel_ramp"), ANGLE / TIME / TIME,
                                "wheel_ramp")
        if found is not None and found < 0:
            reader.fail("T005", "wheel_ramp cannot be negative (0: rate steps)",
                        where("wheel_ramp"))
        elif found is not None:
            ramp = found
    base = read_run_group(reader, data, loc, 1)
    groups: list[RunGroup] = []
    if "variants" in data:
        variants = data["variants"]
        if not isinstance(variants, list) or not variants:
            reader.fail("T012", "'variants' must be a list of run groups", (*loc, "variants"))
        else:
            for number, variant in enumerate(variants):
                vloc = (*loc, "variants", number)
                if not isinstance(variant, dict):
                    reader.fail("T012", "a variant is a mapping with 'count'", vloc)
                    continue
                reader.unknown_keys(variant, vloc, ("count", *_RUN_KEYS))
                count = reader.count(variant.get("count"), (*vloc, "count"), 1) or 1
                group = read_run_group(reader, variant, vloc, count)
                groups.append(RunGroup(count, base.keyframes + group.keyframes,
                                       base.collisions + group.collisions,
                                       base.unfinished or group.unfinished))
        if "runs" in data:
            reader.fail("T012", "give either 'runs' or 'variants' (their counts add up to the "
                        "runs)", (*loc, "runs"), at_key=True)
    else:
        runs = reader.count(data["runs"], (*loc, "runs"), 1) if "runs" in data else 1
        groups.append(RunGroup(runs or 1, base.keyframes, base.collisions, base.unfinished))
    reference: tuple[Keyframes, ...] = ()
    if "reference" in data:
        reference = read_keyframe_block(reader, data["reference"], (*loc, "reference"), False)
    failed = 0
    if "failed_runs" in data:
        failed = reader.count(data["failed_runs"], (*loc, "failed_runs"), 0) or 0
    expectations: tuple[Expectation, ...] = ()
    if "expect" not in data:
        reader.fail("T002", f"case {name!r} expects nothing: add 'expect:'", loc, at_key=True)
    elif checked is not None:
        expectations = read_expectations(reader, data["expect"], (*loc, "expect"), checked,
                                         tolerance, len(chain))
    last = max([f.times[-1] for g in groups for f in g.keyframes]
               + [c.end for g in groups for c in g.collisions]
               + [f.times[-1] for f in reference], default=0.0)
    if duration is not None and last > duration:
        # the run ends at `duration`: a keyframe or collision after it shapes nothing
        reader.fail("T005", f"a keyframe or collision at {last:g} s lies after the run's end "
                    f"(duration {duration:g} s)", where("duration"))
    length = duration if duration is not None else max(
        chain_duration(chain, RoverGeometry()) + DEFAULT_SETTLE, last)
    if length / step > MAX_SAMPLES:
        reader.fail("T005", f"the case's run would have {length / step:.3g} samples (more than "
                    f"{MAX_SAMPLES}): shorten the chain or keyframes, or sample less often",
                    loc, at_key=True)
    description = data.get("description")
    return Case(name, str(description) if description is not None else None, chain, step,
                duration, sigma, tuple(groups), reference, failed, expectations,
                reader.span(loc, at_key=True), ramp)


def _chain(reader: CaseReader, data: Any, loc: Loc) -> tuple[Command, ...]:
    if not isinstance(data, list):
        reader.fail("T007", "'chain' must be a list of commands", loc)
        return ()
    chain = []
    keys = ("max_wheel_rate", "delta_position", "delta_heading")
    dimensions = (_WHEEL_RATE, LENGTH, ANGLE)
    for number, item in enumerate(data):
        cloc = (*loc, number)
        if not isinstance(item, dict):
            reader.fail("T007", "a command is a mapping with max_wheel_rate, delta_position and "
                        "delta_heading", cloc)
            continue
        reader.unknown_keys(item, cloc, keys)
        values: list[float | None] = []
        for key, dimension in zip(keys, dimensions, strict=True):
            if key not in item:
                reader.fail("T007", f"command {number + 1} lacks {key}", cloc)
                values.append(None)
                continue
            values.append(reader.quantity(item[key], (*cloc, key), dimension, key))
        if values[0] is not None and not values[0] > 0.0:
            reader.fail("T007", f"command {number + 1}: max_wheel_rate must be above 0 rad/s "
                        "(a campaign's commands are)", (*cloc, "max_wheel_rate"))
            values[0] = None
        if all(v is not None for v in values):
            chain.append(Command(*(float(v) for v in values if v is not None)))
    return tuple(chain)


# The case model (case_model.py) re-exported beside the loaders, and a dimension constant for
# the synthetic-run builder.
__all__ = ["DIMENSIONLESS", "Case", "CaseFile", "Collision", "Expectation", "Keyframes",
           "RunGroup", "discover_case_files", "load_case_file", "parse_case_file"]
