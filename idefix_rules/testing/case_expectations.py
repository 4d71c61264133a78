"""What a case expects of its rulebook, read from its ``expect:`` mapping: index values
and risks within a tolerance, the dominant index, chances, pre-screens, rejecting command rules,
verdicts and whether the decision is settled, each name checked against the rulebook
(:func:`read_expectations`)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from idefix_rules.campaign.input.yamlsource import Loc, flag_value
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.rulebook.semantics import names_in
from idefix_rules.rulebook.types import FAILED_RUNS_RULE
from idefix_rules.testing.case_model import Expectation, ExpectKind
from idefix_rules.testing.case_reader import CaseReader

_EXPECT_KEYS = ("indices", "risk", "dominant", "chances", "prescreens", "rejected", "verdict",
                "verdicts", "path_risk", "decided")


def _names(checked: CheckedRulebook, kind: str) -> list[str]:
    model = checked.rulebook
    groups: dict[str, tuple[Any, ...]] = {
        "index": model.indices, "chance": model.chances, "prescreen": model.prescreens,
        "command": model.command_rules, "verdict": model.verdicts}
    return [str(item.name) for item in groups[kind]]


def _named(reader: CaseReader, data: Any, loc: Loc, checked: CheckedRulebook,
           kind: str) -> Iterator[tuple[str, Any, Loc]]:
    known = _names(checked, kind)
    if kind == "verdict" and not any("failed" in names_in(rule.condition)
                                     for rule in checked.rulebook.verdicts):
        # the verdict's own rule for failed runs, where no verdict rule reads `failed`
        # (rulebook/statistics.py)
        known = [*known, FAILED_RUNS_RULE]
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


def _range(reader: CaseReader, value: Any, loc: Loc, tolerance: float
           ) -> tuple[tuple[float, float], str] | None:
    """``0.5`` (± the file's tolerance), ``{value: 0.5, tolerance: 0.1}``, ``{at_least: …}``,
    ``{at_most: …}`` → ``((low, high), text)``; T009 for a range no index or risk (each in
    [0, 1]) can meet, which would fail whatever the rulebook does."""
    found = _written_range(reader, value, loc, tolerance)
    if found is None:
        return None
    (low, high), text = found
    if low > high:
        reader.fail("T009", f"the expected range ({text}) is empty: no value meets it", loc)
        return None
    if high < 0.0 or low > 1.0:
        reader.fail("T009", f"an index or a risk lies in [0, 1], so the expected {text} can "
                    "never hold", loc, "write it as a fraction: 0.7, not 70")
        return None
    return found


def _written_range(reader: CaseReader, value: Any, loc: Loc, tolerance: float
                   ) -> tuple[tuple[float, float], str] | None:
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


def _outcome(reader: CaseReader, value: Any, loc: Loc, words: tuple[str, str]) -> bool | None:
    """``pass``/``fail`` (or ``true``/``false`` for chances) → bool."""
    flag = flag_value(value) if words == ("true", "false") else value
    if isinstance(flag, bool):
        return flag
    if value in words:
        return bool(value == words[0])
    reader.fail("T009", f"expected {words[0]} or {words[1]}, got {value!r}", loc)
    return None


def read_expectations(reader: CaseReader, data: Any, loc: Loc, checked: CheckedRulebook,
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


def _rejected(reader: CaseReader, data: Any, loc: Loc, checked: CheckedRulebook, commands: int
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
