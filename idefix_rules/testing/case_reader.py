"""Typed reads of a case file's YAML values (a quantity with its unit, a number, a count of
runs) that record each mistake at its line and column instead of raising, so that loading says
every mistake of the file at once (:class:`CaseReader`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from idefix_rules.campaign.input.yamlsource import Loc, SourceMap
from idefix_rules.errors import Diagnostic, Span, error
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.testing.case_model import MAX_RUNS
from idefix_rules.units import Dimension, UnitError, describe, parse_quantity


class CaseReader:
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
