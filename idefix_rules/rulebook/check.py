"""Checking a rulebook: small named passes over the rule model, each returning diagnostics.

``check(rulebook)`` first resolves the constants (types and SI values, in dependency order),
then runs every pass of :data:`CHECKS` (and :data:`STRICT_CHECKS` with ``strict=True``). All
problems of a file are collected; the result carries a :class:`CheckedRulebook` with every
constant value the compiler needs already in SI. The constants are resolved in
:mod:`~idefix_rules.rulebook.constants`; the passes are those of
:mod:`~idefix_rules.rulebook.declaration_checks` and
:mod:`~idefix_rules.rulebook.expression_checks`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from idefix_rules.errors import Diagnostic, Severity, unique_diagnostics
from idefix_rules.rulebook.constants import resolve_constants
from idefix_rules.rulebook.declaration_checks import (
    check_areas,
    check_combine,
    check_header,
    check_names,
    check_obstacle_levels,
    check_required_sections,
    check_settings,
    warn_unused_constants,
    warn_zero_weights,
)
from idefix_rules.rulebook.environment import (
    LEVELS,
    AreaSpec,
    Check,
    CheckEnv,
    ObstacleLevelSpec,
    scope_of,
)
from idefix_rules.rulebook.expression_checks import (
    check_chances,
    check_command_rules,
    check_command_windows,
    check_constant_parts,
    check_indices,
    check_percentiles,
    check_prescreens,
    check_ranking,
    check_verdict_margins,
    check_verdicts,
)
from idefix_rules.rulebook.fold import Value, fold
from idefix_rules.rulebook.model import Expr, Rulebook
from idefix_rules.rulebook.types import ExprType, Scope


@dataclass(frozen=True)
class CheckedRulebook:
    """A rulebook that passed the checks, with every constant resolved to SI."""

    rulebook: Rulebook
    constants: dict[str, Value]
    constant_types: dict[str, ExprType]
    settings: dict[str, float]
    obstacle_levels: tuple[ObstacleLevelSpec, ...]
    limits: dict[str, float]
    weights: dict[str, float]
    index_types: dict[str, ExprType]
    confidence: float
    indifference: float = 0.0  # run-risk difference within which two paths tie (0: never)
    # per verdict, the margin around its limits (SI; 0: none): within it is "marginal"
    verdict_margins: dict[str, float] = field(default_factory=dict)
    nominals: dict[str, float] = field(default_factory=dict)  # indices that give a nominal
    areas: tuple[AreaSpec, ...] = ()

    def scope(self, kind: str) -> Scope:
        """The scope the checker used for one context (``command``, ``run``, …)."""
        return scope_of(kind, self.rulebook, self.constant_types)

    def value(self, expr: Expr) -> Value:
        """SI value of a constant expression of this rulebook (windows, thresholds …)."""
        return fold(expr, self.constants)

    def level_of_size(self, size: float) -> str:
        """Obstacle level a rock of ``size`` metres gets from the thresholds."""
        for spec in self.obstacle_levels:
            if spec.below is None or size < spec.below:
                return spec.level
        return LEVELS[-1]


@dataclass
class CheckResult:
    diagnostics: list[Diagnostic]
    checked: CheckedRulebook | None

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity is Severity.ERROR]

    @property
    def ok(self) -> bool:
        return not self.errors


CHECKS: tuple[Check, ...] = (
    check_header,
    check_names,
    check_settings,
    check_obstacle_levels,
    check_areas,
    check_command_rules,
    check_indices,
    check_chances,
    check_command_windows,
    check_percentiles,
    check_constant_parts,
    check_combine,
    check_prescreens,
    check_verdicts,
    check_verdict_margins,
    check_ranking,
    check_required_sections,
)

STRICT_CHECKS: tuple[Check, ...] = (warn_unused_constants, warn_zero_weights)


def check(rulebook: Rulebook, strict: bool = False,
          structure: Sequence[Diagnostic] = ()) -> CheckResult:
    """Run every pass; all diagnostics of the file, sorted by position. ``structure``: the
    parser's problems with ``rulebook`` (:func:`~idefix_rules.rulebook.parser.lower_rulebook`),
    reported with the passes' own; the parts that failed to lower are not checked again."""
    from idefix_rules.rulebook.cascade import fold_cascades, fold_misfit_constants, path_hints
    from idefix_rules.rulebook.lints import LINTS

    env = CheckEnv(rulebook)
    diagnostics = [*structure, *resolve_constants(env)]
    for check_pass in CHECKS + (STRICT_CHECKS + LINTS if strict else ()):
        diagnostics.extend(check_pass(env))
    diagnostics = path_hints(rulebook, fold_cascades(rulebook, set(env.constants),
                                                     unique_diagnostics(diagnostics)))
    diagnostics = fold_misfit_constants(rulebook, env.constant_types, diagnostics)
    diagnostics.sort(key=lambda d: (d.span.line if d.span else 0,
                                    d.span.column if d.span else 0))
    checked = None
    if not any(d.severity is Severity.ERROR for d in diagnostics):
        checked = CheckedRulebook(
            rulebook=rulebook,
            constants=env.constants,
            constant_types=env.constant_types,
            settings=env.settings,
            obstacle_levels=tuple(env.levels),
            areas=tuple(env.areas),
            limits=env.limits,
            nominals=env.nominals,
            weights=env.weights,
            index_types=env.index_types,
            confidence=env.confidence,
            indifference=env.indifference,
            verdict_margins=env.verdict_margins,
        )
    return CheckResult(diagnostics, checked)
