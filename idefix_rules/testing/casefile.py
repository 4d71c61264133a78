"""Case files: example runs next to a rulebook and what the rulebook must say about them.

A case file is YAML (loaded safely, every node located) with the rulebook it tests, defaults
and named cases; ``docs/testing-rulebooks.md`` describes the format. Loading validates the whole
file and raises one :class:`~idefix_rules.errors.UserInputError` with every mistake found
(codes T001–T099, each at its line and column); the rulebook's own problems keep their codes.

>>> text = '''
... rulebook: ../idefix-ops.rules
... cases:
...   calm:
...     expect: {verdict: pass}
... '''
>>> case_file = parse_case_file(text, "rulebooks/tests/x.yaml")  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from idefix_rules import signals
from idefix_rules.campaign.input.yamlsource import Loc, SourceMap, flag_value, load_yaml
from idefix_rules.commands import Command, RoverGeometry, chain_duration
from idefix_rules.errors import Diagnostic, Span, UserInputError, error, read_user_text
from idefix_rules.rulebook import check_text, read_source
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.rulebook.semantics import names_in
from idefix_rules.units import (
    ANGLE,
    DIMENSIONLESS,
    LENGTH,
    TIME,
    Dimension,
    UnitError,
    describe,
    parse_quantity,
)

# Signals a case may shape. ``command`` follows the chain and derived/collision signals are
# computed (collisions have their own entry), so they are not keyframed.
# ('done' is read only where a run has no 'command', and a case's runs always have one: a run
# whose chain does not finish is `unfinished: true`)
SHAPEABLE = (*(name for name in signals.FMU_SIGNALS if name not in ("t", "command", "done")),
             "collision.clearance")
# Flags hold their value until the next keyframe instead of ramping.
STEP_SIGNALS = frozenset({"stuck"})
DEFAULT_STEP = 1.0  # s
DEFAULT_SIGMA = 0.01  # m: initial position σ, the starting tolerance radius
DEFAULT_TOLERANCE = 0.005  # on normalised index values and risk
DEFAULT_SETTLE = 5.0  # s of samples after the chain ends
MAX_SAMPLES = 100_000  # per run: a case is a short example, not a mission
MAX_RUNS = 10_000  # per case

_TOP_KEYS = ("rulebook", "defaults", "cases", "tolerance")
_SETUP_KEYS = ("chain", "step", "duration", "initial_position_sigma", "wheel_ramp")
_RUN_KEYS = ("signals", "offsets", "collisions", "unfinished")
_CASE_KEYS = ("description", *_SETUP_KEYS, *_RUN_KEYS, "reference", "runs", "variants",
              "failed_runs", "expect")
_EXPECT_KEYS = ("indices", "risk", "dominant", "chances", "prescreens", "rejected", "verdict",
                "verdicts", "path_risk", "decided")
_COLLISION_KEYS = ("part", "level", "from", "to", "at", "buffer")
_WHEEL_RATE = Dimension(angle=1, time=-1)


@dataclass(frozen=True)
class Keyframes:
    """One shaped signal: values at times, linear in between (steps for flags), held outside.

    ``label`` picks one wheel (``wheel.slip[FL]``) or part; ``offset`` adds to the nominal run.
    """

    signal: str
    label: str | None
    times: tuple[float, ...]
    values: tuple[float, ...]
    offset: bool
    span: Span


@dataclass(frozen=True)
class Collision:
    """A contact of one body part with an obstacle of one level over ``[start, end]`` (s);
    ``buffer_only``: the part entered the level's buffer zone without hitting the obstacle."""

    part: str
    level: str
    start: float
    end: float
    buffer_only: bool
    span: Span


@dataclass(frozen=True)
class RunGroup:
    """``count`` identical runs shaped by keyframes and collisions."""

    count: int
    keyframes: tuple[Keyframes, ...]
    collisions: tuple[Collision, ...]
    unfinished: bool = False  # the runs never complete their chain (cut off at the stop limit)


ExpectKind = Literal["index", "risk", "dominant", "chance", "prescreen", "rejected", "verdict",
                     "verdict_rule", "path_risk", "decided"]


@dataclass(frozen=True)
class Expectation:
    """One expected outcome: ``kind`` and ``name`` say what, ``expected`` the value
    (a ``(low, high)`` range for numbers, a bool, a name, or ``{rule: (command numbers)}``),
    ``text`` how it reads in messages."""

    kind: ExpectKind
    name: str | None
    expected: Any
    text: str
    span: Span


@dataclass(frozen=True)
class Case:
    name: str
    description: str | None
    chain: tuple[Command, ...]
    step: float
    duration: float | None
    initial_position_sigma: float
    groups: tuple[RunGroup, ...]
    reference: tuple[Keyframes, ...]
    failed_runs: int
    expectations: tuple[Expectation, ...]
    span: Span
    # the rover's wheel-rate ramp (rad/s², controller.wheel_acceleration): what a command's
    # forward_acceleration follows
    wheel_ramp: float = RoverGeometry().wheel_acceleration

    @property
    def rover(self) -> RoverGeometry:
        """The kinematics of the case's runs and command rules."""
        return RoverGeometry(wheel_acceleration=self.wheel_ramp)

    @property
    def runs(self) -> int:
        return sum(group.count for group in self.groups)


@dataclass(frozen=True)
class CaseFile:
    path: str
    rulebook_path: str
    checked: CheckedRulebook
    cases: tuple[Case, ...]
    source: str = field(repr=False, default="")


# ----------------------------------------------------------------------------- loading

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
    return parse_case_file(text, str(path))


def parse_case_file(text: str, path: str) -> CaseFile:
    try:
        document = load_yaml(text, path)
    except UserInputError as failure:  # YAML syntax: same place, this file's code range
        raise UserInputError([error("T001", d.message, d.span, d.hint)
                              for d in failure.diagnostics], {path: text}) from None
    reader = _Reader(document.locations)
    data = document.data
    if not isinstance(data, dict):
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
        raise UserInputError(reader.problems, sources)
    assert checked is not None
    return CaseFile(path, rulebook_path, checked, tuple(cases), text)


def _rulebook(reader: _Reader, data: Mapping[str, Any], path: str
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


class _Reader:
    """Typed reads of YAML values that record located problems instead of raising."""

    def __init__(self, locations: SourceMap) -> None:
        self.locations = locations
        self.problems: list[Diagnostic] = []
        # the rulebook's named areas (None: its rulebook could not be read)
        self.areas: tuple[str, ...] | None = None

    def span(self, loc: Loc, at_key: bool = False) -> Span:
        return self.locations.span(loc, at_key)

    def fail(self, code: str, message: str, loc: Loc, hint: str | None = None,
             at_key: bool = False) -> None:
        self.problems.append(error(code, message, self.span(loc, at_key), hint))

    def unknown_keys(self, data: Mapping[Any, Any], loc: Loc, known: Sequence[str]) -> None:
        for key in data:
            if key not in known:
                self.fail("T011", f"unknown key {key!r}", (*loc, key),
                          did_you_mean(str(key), list(known)) or f"known: {', '.join(known)}",
                          at_key=True)

    def quantity(self, value: Any, loc: Loc, dimension: Dimension, what: str) -> float | None:
        """A number with a unit of ``dimension`` (bare numbers only for ratios), in SI."""
        try:
            found = parse_quantity(value if isinstance(value, str | int | float) else "")
        except UnitError as failure:
            self.fail("T005", f"{what}: {failure}", loc, "write a number and a unit, e.g. "
                      "'20 %', '15 deg', '3 cm', '20 s'")
            return None
        if found.dimension != dimension:
            bare = isinstance(value, int | float) or str(value).strip().replace(".", "").isdigit()
            self.fail("T005", f"{what} must be {describe(dimension)}, got "
                      f"{describe(found.dimension)}" + (" (a bare number)" if bare else ""),
                      loc, "add the unit" if bare else None)
            return None
        if not math.isfinite(found.value):
            self.fail("T005", f"{what} must be finite", loc)
            return None
        return found.value

    def number(self, value: Any, loc: Loc, minimum: float | None = None) -> float | None:
        if isinstance(value, bool) or not isinstance(value, int | float) or \
                not math.isfinite(value) or (minimum is not None and value < minimum):
            low = f" ≥ {minimum:g}" if minimum is not None else ""
            self.fail("T009", f"expected a number{low}, got {value!r}", loc)
            return None
        return float(value)

    def count(self, value: Any, loc: Loc, minimum: int) -> int | None:
        if isinstance(value, bool) or not isinstance(value, int) or \
                not minimum <= value <= MAX_RUNS:
            self.fail("T012", f"expected a whole number from {minimum} to {MAX_RUNS}, got "
                      f"{value!r}", loc)
            return None
        return value


# ----------------------------------------------------------------------------- cases

def _case(reader: _Reader, name: str, data: Any, defaults: Mapping[str, Any],
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
    base = _run_group(reader, data, loc, 1)
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
                group = _run_group(reader, variant, vloc, count)
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
        reference = _keyframe_block(reader, data["reference"], (*loc, "reference"), False)
    failed = 0
    if "failed_runs" in data:
        failed = reader.count(data["failed_runs"], (*loc, "failed_runs"), 0) or 0
    expectations: tuple[Expectation, ...] = ()
    if "expect" not in data:
        reader.fail("T002", f"case {name!r} expects nothing: add 'expect:'", loc, at_key=True)
    elif checked is not None:
        expectations = _expectations(reader, data["expect"], (*loc, "expect"), checked,
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


def _chain(reader: _Reader, data: Any, loc: Loc) -> tuple[Command, ...]:
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


def _run_group(reader: _Reader, data: Mapping[str, Any], loc: Loc, count: int) -> RunGroup:
    keyframes: tuple[Keyframes, ...] = ()
    if "signals" in data:
        keyframes += _keyframe_block(reader, data["signals"], (*loc, "signals"), False)
    if "offsets" in data:
        keyframes += _keyframe_block(reader, data["offsets"], (*loc, "offsets"), True)
    collisions: list[Collision] = []
    if "collisions" in data:
        items = data["collisions"]
        if not isinstance(items, list):
            reader.fail("T010", "'collisions' must be a list", (*loc, "collisions"))
            items = []
        for number, item in enumerate(items):
            found = _collision(reader, item, (*loc, "collisions", number))
            if found is not None:
                collisions.append(found)
    unfinished = False
    if "unfinished" in data:
        if isinstance(flag_value(data["unfinished"]), bool):
            unfinished = bool(flag_value(data["unfinished"]))
        else:
            reader.fail("T012", "'unfinished' is true or false", (*loc, "unfinished"))
    return RunGroup(count, keyframes, tuple(collisions), unfinished)


def _signal_key(reader: _Reader, key: str, loc: Loc) -> tuple[str, str | None] | None:
    name, label = key, None
    if key.endswith("]") and "[" in key:
        name, _, rest = key.partition("[")
        label = rest[:-1].strip()
        name = name.strip()
    spec = signals.lookup(name)
    if spec is None or (name not in SHAPEABLE and signals.area_signal(name) is None):
        why = ("is computed from the others" if spec is not None and spec.kind == "derived"
               else "follows the chain" if name == "command"
               else "follows the chain's commands (a run whose chain does not finish: "
                    "'unfinished: true')" if name == "done"
               else "is given by 'collisions'" if name.startswith("collision.")
               else "is not a signal")
        reader.fail("T004", f"{name!r} cannot be shaped by a case: it {why}", loc,
                    did_you_mean(name, list(SHAPEABLE)) or f"signals: {', '.join(SHAPEABLE)}",
                    at_key=True)
        return None
    area = signals.area_signal(name)
    if area is not None and reader.areas is not None and area[0] not in reader.areas:
        # a typo, or an area of another rulebook: its keyframes would be read by no rule
        reader.fail("T004", f"{name!r} cannot be shaped by a case: the rulebook declares no "
                    f"area {area[0]!r}" + (f" (it declares {', '.join(map(repr, reader.areas))})"
                                           if reader.areas else ""), loc,
                    did_you_mean(area[0], list(reader.areas)) if reader.areas else
                    "declare it in the rulebook's obstacles block", at_key=True)
        return None
    if label is not None:
        axis = next((a for a in spec.axes if a != "time"), None)
        labels = signals.AXIS_LABELS.get(axis or "", ())
        if label not in labels:
            reader.fail("T004", f"{name!r} has no label {label!r}" + (
                f"; its labels are {', '.join(labels)}" if labels else " (it has no wheel or "
                "part axis)"), loc, at_key=True)
            return None
    return name, label


def _keyframe_block(reader: _Reader, data: Any, loc: Loc, offset: bool
                    ) -> tuple[Keyframes, ...]:
    if not isinstance(data, dict):
        reader.fail("T002", "expected a mapping of signal names to keyframes "
                    "(e.g. 'wheel.slip[FL]: {0 s: 10 %, 20 s: 80 %}')", loc)
        return ()
    out = []
    shaped: dict[tuple[str, str | None], str] = {}  # (signal, label) -> the key that shaped it
    for key, frames in data.items():
        kloc = (*loc, key)
        found = _signal_key(reader, str(key), kloc)
        if found is None:
            continue
        name, label = found
        # the whole signal and one of its labels, or one label written twice ('[FL]', '[ FL ]')
        clash = shaped.get((name, label)) or (
            shaped.get((name, None)) if label is not None else
            next((k for (n, _), k in shaped.items() if n == name), None))
        if clash is not None:
            reader.fail("T006", f"{key!r} shapes what {clash!r} already shapes; each signal "
                        "(or each of its labels) is given once", kloc,
                        "give each label its own keyframes, or the whole signal once",
                        at_key=True)
            continue
        shaped[(name, label)] = str(key)
        spec = signals.lookup(name)
        assert spec is not None
        if not isinstance(frames, dict) or not frames:
            if isinstance(frames, str | int | float) and not isinstance(frames, bool):
                frames = {"0 s": frames}  # a constant value
            else:
                reader.fail("T006", "keyframes are a mapping of times to values, e.g. "
                            "'{0 s: 10 %, 20 s: 80 %}', or one value", kloc)
                continue
        times: list[float] = []
        values: list[float] = []
        for time_text, value in frames.items():
            time = reader.quantity(time_text, kloc, TIME, f"keyframe time {time_text!r}")
            number = reader.quantity(value, (*kloc, time_text), spec.dimension,
                                     f"{key} at {time_text}")
            if time is None or number is None:
                continue
            if time < 0 or (times and time <= times[-1]):
                reader.fail("T006", f"keyframe times must start at 0 s or later and increase; "
                            f"{time_text!r} does not", (*kloc, time_text), at_key=True)
                continue
            times.append(time)
            values.append(number)
        if times:
            out.append(Keyframes(name, label, tuple(times), tuple(values), offset,
                                 reader.span(kloc, at_key=True)))
    return tuple(out)


def _collision(reader: _Reader, data: Any, loc: Loc) -> Collision | None:
    if not isinstance(data, dict):
        reader.fail("T010", "a collision is a mapping: {part: wheel, level: L2, at: 30 s}", loc)
        return None
    reader.unknown_keys(data, loc, _COLLISION_KEYS)
    parts, levels = signals.AXIS_LABELS["part"], signals.AXIS_LABELS["level"]
    part, level = data.get("part"), data.get("level")
    ok = True
    if part not in parts:
        reader.fail("T010", f"part must be one of {', '.join(parts)}, got {part!r}",
                    (*loc, "part"))
        ok = False
    if level not in levels:
        reader.fail("T010", f"level must be one of {', '.join(levels)}, got {level!r}",
                    (*loc, "level"))
        ok = False
    if "at" in data and ("from" in data or "to" in data):
        reader.fail("T010", "a collision is 'at' one time or 'from' (and 'to') a span, not both",
                    loc)
        return None
    if "to" in data and "from" not in data:
        reader.fail("T010", "'to' needs 'from'", (*loc, "to"), at_key=True)
        return None
    if "at" in data:
        start = end = reader.quantity(data["at"], (*loc, "at"), TIME, "at")
    elif "from" in data:
        start = reader.quantity(data["from"], (*loc, "from"), TIME, "from")
        end = reader.quantity(data.get("to", data["from"]), (*loc, "to"), TIME, "to")
    else:
        reader.fail("T010", "a collision needs 'at' or 'from' (and 'to')", loc)
        return None
    buffer_only = flag_value(data.get("buffer", False))
    if not isinstance(buffer_only, bool):
        reader.fail("T010", "'buffer' is true or false", (*loc, "buffer"))
        ok = False
    if start is None or end is None or not ok:
        return None
    if end < start:
        reader.fail("T010", "'to' comes before 'from'", (*loc, "to"))
        return None
    return Collision(str(part), str(level), start, end, bool(buffer_only),
                     reader.span(loc))


# ----------------------------------------------------------------------------- expectations

def _names(checked: CheckedRulebook, kind: str) -> list[str]:
    model = checked.rulebook
    groups: dict[str, tuple[Any, ...]] = {
        "index": model.indices, "chance": model.chances, "prescreen": model.prescreens,
        "command": model.command_rules, "verdict": model.verdicts}
    return [str(item.name) for item in groups[kind]]


def _named(reader: _Reader, data: Any, loc: Loc, checked: CheckedRulebook,
           kind: str) -> Iterator[tuple[str, Any, Loc]]:
    known = _names(checked, kind)
    if kind == "verdict" and not any("failed" in names_in(rule.condition)
                                     for rule in checked.rulebook.verdicts):
        # the verdict's own rule for failed runs, where no verdict rule reads `failed`
        # (rulebook/statistics.py)
        known = [*known, "no_failed_runs"]
    if not isinstance(data, dict):
        reader.fail("T009", f"expected a mapping of {kind} names to expected values", loc)
        return
    for name, value in data.items():
        if name not in known:
            reader.fail("T008", f"the rulebook has no {kind} {name!r}", (*loc, name),
                        did_you_mean(str(name), known) or
                        (f"its {kind} names: {', '.join(known)}" if known else None),
                        at_key=True)
            continue
        yield str(name), value, (*loc, name)


def _range(reader: _Reader, value: Any, loc: Loc, tolerance: float
           ) -> tuple[tuple[float, float], str] | None:
    """``0.5`` (± the file's tolerance), ``{value: 0.5, tolerance: 0.1}``, ``{at_least: …}``,
    ``{at_most: …}`` → ``((low, high), text)``."""
    if isinstance(value, dict):
        reader.unknown_keys(value, loc, ("value", "tolerance", "at_least", "at_most"))
        if "value" in value and ("at_least" in value or "at_most" in value):
            reader.fail("T009", "give 'value' (and 'tolerance') or 'at_least'/'at_most', not "
                        "both", loc)
            return None
        if "tolerance" in value and "value" not in value:
            reader.fail("T009", "'tolerance' goes with 'value'", (*loc, "tolerance"),
                        at_key=True)
            return None
        if "value" in value:
            centre = reader.number(value["value"], (*loc, "value"))
            spread = tolerance
            if "tolerance" in value:
                spread = reader.number(value["tolerance"], (*loc, "tolerance"), 0.0) or 0.0
            if centre is None:
                return None
            return (centre - spread, centre + spread), f"{centre:g} ± {spread:g}"
        low = reader.number(value["at_least"], (*loc, "at_least")) \
            if "at_least" in value else -math.inf
        high = reader.number(value["at_most"], (*loc, "at_most")) \
            if "at_most" in value else math.inf
        if low is None or high is None or (low == -math.inf and high == math.inf):
            if low is not None and high is not None:
                reader.fail("T009", "give 'value', 'at_least' or 'at_most'", loc)
            return None
        text = " and ".join(part for part in (
            f"≥ {low:g}" if low > -math.inf else "", f"≤ {high:g}" if high < math.inf else "")
            if part)
        return (low, high), text
    centre = reader.number(value, loc)
    if centre is None:
        return None
    return (centre - tolerance, centre + tolerance), f"{centre:g} ± {tolerance:g}"


def _outcome(reader: _Reader, value: Any, loc: Loc, words: tuple[str, str]) -> bool | None:
    """``pass``/``fail`` (or ``true``/``false`` for chances) → bool."""
    flag = flag_value(value) if words == ("true", "false") else value
    if isinstance(flag, bool):
        return flag
    if value in words:
        return bool(value == words[0])
    reader.fail("T009", f"expected {words[0]} or {words[1]}, got {value!r}", loc)
    return None


def _expectations(reader: _Reader, data: Any, loc: Loc, checked: CheckedRulebook,
                  tolerance: float, commands: int) -> tuple[Expectation, ...]:
    if not isinstance(data, dict) or not data:
        reader.fail("T009", "'expect' must be a mapping of expected outcomes", loc)
        return ()
    reader.unknown_keys(data, loc, _EXPECT_KEYS)
    out: list[Expectation] = []

    def add(kind: ExpectKind, name: str | None, expected: Any, text: str, at: Loc) -> None:
        out.append(Expectation(kind, name, expected, text, reader.span(at, at_key=True)))

    if "indices" in data:
        for name, value, at in _named(reader, data["indices"], (*loc, "indices"), checked,
                                      "index"):
            found = _range(reader, value, at, tolerance)
            if found is not None:
                add("index", name, found[0], found[1], at)
    for key, kind in (("risk", "risk"), ("path_risk", "path_risk")):
        if key in data:
            found = _range(reader, data[key], (*loc, key), tolerance)
            if found is not None:
                add(kind, None, found[0], found[1], (*loc, key))  # type: ignore[arg-type]
    if "dominant" in data:
        indices = _names(checked, "index")
        if data["dominant"] not in indices:
            reader.fail("T008", f"the rulebook has no index {data['dominant']!r}",
                        (*loc, "dominant"), did_you_mean(str(data["dominant"]), indices))
        else:
            add("dominant", None, data["dominant"], str(data["dominant"]), (*loc, "dominant"))
    if "chances" in data:
        for name, value, at in _named(reader, data["chances"], (*loc, "chances"), checked,
                                      "chance"):
            held = _outcome(reader, value, at, ("true", "false"))
            if held is not None:
                add("chance", name, held, "holds" if held else "does not hold", at)
    if "prescreens" in data:
        for name, value, at in _named(reader, data["prescreens"], (*loc, "prescreens"), checked,
                                      "prescreen"):
            passed = _outcome(reader, value, at, ("pass", "fail"))
            if passed is not None:
                add("prescreen", name, passed, "pass" if passed else "fail", at)
    if "rejected" in data:
        rejected = _rejected(reader, data["rejected"], (*loc, "rejected"), checked, commands)
        if rejected is not None:
            text = ", ".join(f"{rule} (command {', '.join(map(str, numbers))})" if numbers
                             else rule for rule, numbers in rejected.items()) or "none"
            add("rejected", None, rejected, text, (*loc, "rejected"))
    if "verdict" in data:
        passed = _outcome(reader, data["verdict"], (*loc, "verdict"), ("pass", "fail"))
        if passed is not None:
            add("verdict", None, passed, "pass" if passed else "fail", (*loc, "verdict"))
    if "verdicts" in data:
        for name, value, at in _named(reader, data["verdicts"], (*loc, "verdicts"), checked,
                                      "verdict"):
            passed = _outcome(reader, value, at, ("pass", "fail"))
            if passed is not None:
                add("verdict_rule", name, passed, "pass" if passed else "fail", at)
    if "decided" in data:
        decided = flag_value(data["decided"])
        if not isinstance(decided, bool):
            reader.fail("T009", "'decided' is true or false", (*loc, "decided"))
        else:
            add("decided", None, decided, "decided" if decided else "not decided",
                (*loc, "decided"))
    return tuple(out)


def _rejected(reader: _Reader, data: Any, loc: Loc, checked: CheckedRulebook, commands: int
              ) -> dict[str, tuple[int, ...]] | None:
    """``[rule, …]`` (any command) or ``{rule: [command numbers]}``; ``[]`` = none. A number
    beyond the case's ``commands`` names no command of its chain (T009)."""
    known = _names(checked, "command")
    if isinstance(data, list):
        data = {name: [] for name in data} if all(isinstance(n, str) for n in data) else None
    if not isinstance(data, dict):
        reader.fail("T009", "'rejected' lists command rule names, or maps them to command "
                    "numbers (1-based)", loc)
        return None
    out: dict[str, tuple[int, ...]] = {}
    for name, numbers in data.items():
        if name not in known:
            reader.fail("T008", f"the rulebook has no command rule {name!r}", loc,
                        did_you_mean(str(name), known))
            continue
        if numbers is None:
            numbers = []
        if not isinstance(numbers, list) or not all(
                isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in numbers):
            reader.fail("T009", f"command numbers of {name!r} must be a list of whole numbers "
                        "≥ 1", (*loc, name))
            continue
        beyond = [n for n in numbers if n > commands]
        if beyond:
            reader.fail("T009", f"command {beyond[0]} of {name!r}: the case's chain has "
                        f"{commands} command{'s' if commands != 1 else ''}", (*loc, name))
            continue
        out[str(name)] = tuple(numbers)
    return out


# Dimension constants re-exported for the synthetic-run builder.
__all__ = ["DIMENSIONLESS", "Case", "CaseFile", "Collision", "Expectation", "Keyframes",
           "RunGroup", "discover_case_files", "load_case_file", "parse_case_file"]
