"""The compiled rulebook: a checked rule model turned into numpy closures, vectorised over runs.

>>> from idefix_rules.rulebook import load_rulebook, compile_rulebook, RunContext  # doctest: +SKIP
>>> evaluator = compile_rulebook(load_rulebook("rulebooks/idefix-ops.rules"))  # doctest: +SKIP
>>> context = RunContext(chain, rover, 0.02, reference)  # doctest: +SKIP
>>> evaluation = evaluator.evaluate(signals, context)  # doctest: +SKIP

``evaluate`` takes signals keyed by contract name, axis 0 = runs, and a :class:`RunContext`
(the explicit input derived signals need) and returns a :class:`RunEvaluation`. Index
semantics: ``clamp(value / limit, 0, 1)``, or piecewise linear through (0, 0), (nominal, 0.5)
and (limit, 1) when the index gives a nominal (:func:`.semantics.normalised`); the per-sample
value is the ``map`` when given, else
the value with every time reduction replaced by its operand (:func:`.semantics.per_sample_form`),
normalised the same way; I_max = max over indices of weight × value (eq. 1). Non-finite data
makes an index 1 (see :mod:`.semantics`). Nothing of the rulebook text is executed.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import UserInputError
from idefix_rules.rulebook import statistics
from idefix_rules.rulebook.across import AcrossRuns, finished, non_finite_nodes, runs_reductions
from idefix_rules.rulebook.check import CheckedRulebook, check
from idefix_rules.rulebook.derived import (
    DerivedSettings,
    DerivedSignals,
    RunContext,
    inputs_of,
    optional_inputs_of,
)
from idefix_rules.rulebook.environment import ObstacleLevelSpec
from idefix_rules.rulebook.expressions import (
    Closure,
    ExpressionCompiler,
    Frame,
    per_run,
    per_run_sample,
    runs_first,
    signal_closure,
)
from idefix_rules.rulebook.fold import folded_number
from idefix_rules.rulebook.model import Expr, Number, Reduce, Rulebook
from idefix_rules.rulebook.named_values import command_quantities, layout_constants, scope_closure
from idefix_rules.rulebook.results import (
    CommandViolation,
    PathStatistics,
    PrescreenFinding,
    RunEvaluation,
    Verdict,
)
from idefix_rules.rulebook.run_values import FINITE, bad_runs, normalise, time_energy
from idefix_rules.rulebook.semantics import (
    OWN_SAMPLES_INPUTS,
    any_counts_own_samples,
    names_in,
    per_sample_form,
)
from idefix_rules.signals import AREA_PREFIX, lookup


def checked_model(rulebook: Rulebook | CheckedRulebook) -> CheckedRulebook:
    """The checked model; a plain rule model is checked first (errors → ``UserInputError``)."""
    if isinstance(rulebook, CheckedRulebook):
        return rulebook
    result = check(rulebook)
    if result.checked is None:
        raise UserInputError(result.errors, {rulebook.path: rulebook.source})
    return result.checked


@dataclass(frozen=True)
class _Index:
    name: str
    limit: float
    nominal: float | None
    weight: float
    value: Closure
    per_sample: Closure
    reads: tuple[str, ...]  # signal names, for the non-finite rule
    over_runs: frozenset[Reduce]  # the path-level values it reads, for the same rule


@dataclass(frozen=True)
class _Condition:
    name: str
    test: Closure
    reads: tuple[str, ...]
    rationale: str | None
    expr: Expr
    over_runs: frozenset[Reduce] = frozenset()


class CompiledRulebook:
    """Evaluator of one rulebook; see the module docstring and ``docs/architecture.md``."""

    def __init__(self, rulebook: Rulebook | CheckedRulebook) -> None:
        self.checked = checked_model(rulebook)
        model = self.checked.rulebook
        self.rulebook: Rulebook = model
        self.name = model.header.name
        self.version = model.header.version
        self.source_hash = hashlib.sha256(model.source.encode("utf-8")).hexdigest()
        self.obstacle_levels: tuple[ObstacleLevelSpec, ...] = self.checked.obstacle_levels
        self.confidence = self.checked.confidence
        self.derived_settings = DerivedSettings(
            theoretical_slip=self.checked.settings.get("theoretical_slip", 0.0),
            tolerance_growth=self.checked.settings.get("tolerance_growth", 0.0))
        self.constants = layout_constants(self.checked.constants)
        self.index_names = tuple(i.name for i in model.indices)
        self.chance_names = tuple(c.name for c in model.chances)

        run = ExpressionCompiler(self.constants, signal_closure)
        forms = [(i.value, i.map if i.map is not None else per_sample_form(i.value))
                 for i in model.indices]
        run.share([e for pair in forms for e in pair] + [c.condition for c in model.chances])
        self._indices = tuple(
            _Index(i.name, self.checked.limits[i.name], self.checked.nominals.get(i.name),
                   self.checked.weights[i.name],
                   run.compile(value), run.compile(sample),
                   self._signals_read(value, sample),
                   frozenset(runs_reductions([value, sample])))
            for i, (value, sample) in zip(model.indices, forms, strict=True))
        self._chances = tuple(
            _Condition(c.name, run.compile(c.condition), self._signals_read(c.condition),
                       c.rationale, c.condition, frozenset(runs_reductions([c.condition])))
            for c in model.chances)
        # Reductions over the runs of a path: their operands, evaluated in a first pass.
        self.runs_reductions: tuple[Reduce, ...] = runs_reductions(
            [e for pair in forms for e in pair] + [c.condition for c in model.chances])
        self._runs_operands = {node: run.compile(node.operand)
                               for node in self.runs_reductions}
        self._runs_reads = {node: self._signals_read(node.operand)
                            for node in self.runs_reductions}
        # a percentile's P naming constants, folded (the checker made it a number in 0 … 100)
        self._runs_parameters = {
            node: float(number) for node in self.runs_reductions
            if node.parameter is not None and not isinstance(node.parameter, Number)
            and (number := folded_number(node.parameter, self.checked.constants)) is not None}

        scoped = ExpressionCompiler(self.constants, scope_closure)
        self._command_rules = tuple(
            _Condition(r.name, scoped.compile(r.condition), (), r.rationale, r.condition)
            for r in model.command_rules)
        self._prescreens = tuple(
            _Condition(p.name, scoped.compile(p.condition), (), p.rationale, p.condition)
            for p in model.prescreens)

        # What a per-run value is, independent of the rulebook it sits in: the expression and
        # the SI values of the constants it reads (evaluations sharing a source share values).
        self._value_keys = {
            **{i.name: self._value_key(i.value) for i in model.indices},
            **{c.name: self._value_key(c.condition) for c in model.chances}}

        read = set().union(*(set(i.reads) for i in self._indices),
                           *(set(c.reads) for c in self._chances))
        # every signal the indices and chances name (given, derived, ref.*, area signals)
        self.signals_read: frozenset[str] = frozenset(read)
        provided = set().union(*(inputs_of(name) for name in read)) if read else set()
        # 'command' (run time) and 'energy' are used when present, not required (a foreign
        # FMU may lack them): see DerivedSignals.provides.
        self.required_signals: frozenset[str] = frozenset(provided | {"t"})
        # Read when the runs hold them, done without otherwise (the start yaw of 'drift'):
        # whoever reads stored runs for this evaluator reads these too.
        # and what tells where each run's own samples end, for the reductions counting them
        # (semantics: "A run's own samples")
        counting = any(any_counts_own_samples(expr, self.constants) for expr in
                       (*(i.value for i in model.indices), *(c.condition for c in model.chances)))
        self.optional_signals: frozenset[str] = frozenset(
            (set().union(*(optional_inputs_of(name) for name in read))
             | (OWN_SAMPLES_INPUTS if counting else set())) - self.required_signals
            if read else ())
        # the signals of the rulebook's named areas (given with the collision signals)
        self.area_signals: tuple[str, ...] = tuple(
            name for area in self.checked.areas for name in area.signal_names())
        # the named areas' signals the indices and chances read (from the poses)
        self.area_signals_read: frozenset[str] = frozenset(
            name for name in read if name.startswith(AREA_PREFIX))
        self.needs_collisions = any(name.startswith("collision.") for name in provided) or \
            bool(self.area_signals_read)
        across_read = set(self._signals_read(*(n.operand for n in self.runs_reductions)))
        # What the first pass over a path's runs reads (never collision signals: E802).
        across_counting = any(any_counts_own_samples(n.operand, self.constants)
                              for n in self.runs_reductions)
        self.across_signals: frozenset[str] = frozenset(
            set().union(*(inputs_of(name) | optional_inputs_of(name) for name in across_read))
            | {"t", "command"} | (OWN_SAMPLES_INPUTS if across_counting else set())
            if self.runs_reductions else ())
        # What the per-sample values alone need (per_sample_values): the result map's
        # signals and reductions over runs, a subset of the whole evaluation's.
        sample_forms = [sample for _, sample in forms]
        self.sample_runs_reductions: tuple[Reduce, ...] = runs_reductions(sample_forms)
        sample_read = set(self._signals_read(*sample_forms))
        self.sample_signals: frozenset[str] = frozenset(
            set().union(*(inputs_of(name) for name in sample_read)) | {"t"})
        # (the height adds to a global error when the runs hold it; a reduction left in a
        # per-sample form that counts a run's own samples reads where the runs end)
        sample_counting = any(any_counts_own_samples(form, self.constants)
                              for form in sample_forms)
        self.sample_optional_signals: frozenset[str] = frozenset(
            set().union(*(optional_inputs_of(name) for name in sample_read),
                        {"z"} if "global_error" in sample_read else set(),
                        OWN_SAMPLES_INPUTS if sample_counting else set())
            - self.sample_signals if sample_read else ())

    def __reduce__(self) -> tuple[type[CompiledRulebook], tuple[CheckedRulebook]]:
        """Pickle as the checked model and compile again on loading (closures do not pickle),
        so an evaluator can be shipped to worker processes."""
        return (CompiledRulebook, (self.checked,))

    def _value_key(self, expr: Expr) -> tuple[Any, ...]:
        constants = []
        for name in sorted(names_in(expr)):
            if name in self.constants:
                value = self.constants[name]
                constants.append((name, value.tobytes() if isinstance(value, np.ndarray)
                                  else value))
        return (expr, tuple(constants), self.derived_settings)

    def _signals_read(self, *expressions: Expr) -> tuple[str, ...]:
        names: set[str] = set()
        for expr in expressions:
            names |= {n for n in names_in(expr)
                      if n not in self.constants and lookup(n) is not None}
        return tuple(sorted(names))

    # ------------------------------------------------------------------ command rules
    def check_chain(self, chain: Sequence[Command], rover: RoverGeometry | None = None
                    ) -> list[CommandViolation]:
        """Every command rule on every command (1-based numbers); the violations found."""
        rover = rover or RoverGeometry()
        violations = []
        for number, command in enumerate(chain, start=1):
            quantities = command_quantities(command, number, rover)
            frame = Frame(scope=quantities)
            for rule in self._command_rules:
                if bool(np.all(rule.test(frame))):
                    continue
                values = {n: quantities[n] for n in sorted(names_in(rule.expr))
                          if n in quantities}
                shown = ", ".join(f"{n} = {v:.6g}" for n, v in values.items())
                violations.append(CommandViolation(
                    rule.name, number, values, rule.rationale,
                    f"command {number} breaks rule '{rule.name}'" + (f" ({shown})" if shown
                                                                     else ""),
                    rule.expr.span))
        return violations

    # ------------------------------------------------------------------ runs
    def derived_signals(self, signals: Mapping[str, np.ndarray],
                        context: RunContext) -> DerivedSignals:
        """The source of signals ``evaluate`` reads (given, ``ref.*`` and derived, each
        computed once); rulebooks with equal ``derived_settings`` can share one."""
        return DerivedSignals(signals, context, self.derived_settings)

    def new_across(self, nodes: Iterable[Reduce] | None = None) -> AcrossRuns:
        """Empty accumulators of the reductions over runs (``nodes``, by default all of
        them), for :meth:`across_runs` to fold chunks into."""
        return AcrossRuns(self.runs_reductions if nodes is None else nodes,
                          self._runs_parameters)

    def across_runs(self, signals: Mapping[str, np.ndarray], context: RunContext, *,
                    source: DerivedSignals | None = None,
                    into: AcrossRuns | None = None) -> AcrossRuns:
        """Fold a batch of a path's runs into the path-level values (the first pass).

        Call it on every chunk of a path's complete runs (``into`` the same accumulator), then
        pass the accumulator to :meth:`evaluate` of each chunk. ``source`` as in
        :meth:`evaluate`. An ``into`` made for some of the reductions
        (``AcrossRuns(self.sample_runs_reductions)``) folds only those.
        """
        across = into if into is not None else self.new_across()
        if not across.accumulators:
            return across
        if source is None:
            source = self.derived_signals(signals, context)
        frame = Frame(source=source)
        finite: dict[str, np.ndarray] = {}
        with np.errstate(all="ignore"):
            for node, accumulator in across.accumulators.items():
                values = runs_first(self._runs_operands[node](frame), source.runs)
                # a number carries its NaN; a truth value lost it in a comparison: it is not
                # a number where the signals it read were not (as a run's own chance holds)
                accumulator.add(values, non_finite=values.dtype == bool and bool(
                    bad_runs(source, self._runs_reads[node], finite).any()))
        return across

    def evaluate(self, signals: Mapping[str, np.ndarray], context: RunContext, *,
                 per_sample: bool = True, source: DerivedSignals | None = None,
                 shared: dict[Any, Any] | None = None,
                 across: AcrossRuns | Mapping[Reduce, np.ndarray] | None = None
                 ) -> RunEvaluation:
        """Every index, I_max, dominant index and sample, chances, time and energy per run.

        ``per_sample=False`` skips the per-sample values (``per_sample`` arrays are
        (runs, 0), ``dominant_sample`` is 0) for callers that need per-run numbers only.
        ``source``: a :meth:`derived_signals` of the same signals and context from a rulebook
        with the same derived settings, so that two rulebooks derive signals once.
        ``shared``: a dict passed to the evaluations of several rulebooks on the same
        ``source``; an index value or chance whose expression and constants equal one already
        computed there is taken from it, not computed again.
        ``across``: the path-level values of the reductions over runs (:meth:`across_runs`
        over every chunk of the path); None when the given runs are the whole path (they are
        then computed from them).
        """
        if source is None:
            source = self.derived_signals(signals, context)
        elif source.settings != self.derived_settings:
            raise ValueError("a shared signal source needs equal derived settings")
        runs, samples = source.runs, source.samples
        if across is None and self.runs_reductions:
            across = self.across_runs(signals, context, source=source)
        frame = Frame(source=source, across=finished(across) if across is not None else {})
        # Which runs hold only finite values, per signal: shared like the values are.
        finite: dict[str, np.ndarray] = {} if shared is None else shared.setdefault(FINITE, {})
        # the path-level values that are not numbers: whoever reads one is critical (holds)
        # in every run of the path (docs/rulebook-language.md, "Non-finite data")
        not_numbers = non_finite_nodes(across)

        def critical_runs(names: tuple[str, ...], over_runs: frozenset[Reduce] = frozenset()
                          ) -> np.ndarray:
            if over_runs & not_numbers:
                return np.ones(runs, dtype=bool)
            return bad_runs(source, names, finite)

        def computed(name: str, closure: Closure) -> np.ndarray:
            if shared is None:
                return per_run(closure(frame), runs)
            key = self._value_keys[name]
            if key not in shared:
                shared[key] = per_run(closure(frame), runs)
            value: np.ndarray = shared[key]
            return value

        values, raw, sample_values, weighted = {}, {}, {}, {}
        with np.errstate(all="ignore"):
            for index in self._indices:
                value = computed(index.name, index.value)
                bad = critical_runs(index.reads, index.over_runs) | np.isnan(value)
                raw[index.name] = np.where(bad, np.nan, value)
                values[index.name] = np.where(bad, 1.0, normalise(value, index.limit,
                                                                  index.nominal))
                if per_sample:
                    sample_values[index.name] = _sample_value(index, frame, runs, samples)
                else:
                    sample_values[index.name] = np.empty((runs, 0))
                weighted[index.name] = index.weight * values[index.name]
            chances = {c.name: computed(c.name, c.test).astype(bool) |
                       critical_runs(c.reads, c.over_runs) for c in self._chances}
        frame.memo.clear()
        stacked = np.stack([weighted[n] for n in self.index_names])
        dominant = np.argmax(stacked, axis=0)
        dominant_sample = np.zeros(runs, dtype=int)
        for position, name in enumerate(self.index_names if per_sample else ()):
            chosen = dominant == position
            if chosen.any():
                dominant_sample[chosen] = np.argmax(sample_values[name][chosen], axis=1)
        time, energy = time_energy(source, runs)
        return RunEvaluation(
            index_names=self.index_names, values=values, raw=raw, per_sample=sample_values,
            weighted=weighted, i_max=stacked.max(axis=0), dominant=dominant,
            dominant_sample=dominant_sample, chance_names=self.chance_names, chances=chances,
            time=time, energy=energy)

    def per_sample_values(self, signals: Mapping[str, np.ndarray], context: RunContext, *,
                          source: DerivedSignals | None = None,
                          across: AcrossRuns | Mapping[Reduce, np.ndarray] | None = None
                          ) -> dict[str, np.ndarray]:
        """Each index's normalised per-sample value, (runs, samples): ``evaluate(...)
        .per_sample`` and nothing else (no per-run value, chance, time or energy), for
        callers that draw per sample (the report's result maps). It reads only
        :attr:`sample_signals` (and :attr:`sample_optional_signals` when given); ``across``
        is needed only for :attr:`sample_runs_reductions`. ``source`` as in
        :meth:`evaluate`."""
        if source is None:
            source = self.derived_signals(signals, context)
        elif source.settings != self.derived_settings:
            raise ValueError("a shared signal source needs equal derived settings")
        if across is None and self.sample_runs_reductions:
            across = self.across_runs(signals, context, source=source,
                                      into=self.new_across(self.sample_runs_reductions))
        frame = Frame(source=source, across=finished(across) if across is not None else {})
        with np.errstate(all="ignore"):
            values = {index.name: _sample_value(index, frame, source.runs, source.samples)
                      for index in self._indices}
        frame.memo.clear()
        return values

    # ------------------------------------------------------------------ reference run
    def prescreen(self, reference: RunEvaluation) -> list[PrescreenFinding]:
        """Prescreen rules on the reference run's evaluation; the rules it fails."""
        scope: dict[str, Any] = {"risk": reference.i_max}
        scope.update(reference.values)
        scope.update(reference.chances)
        frame = Frame(scope=scope)
        findings = []
        for rule in self._prescreens:
            holds = per_run(rule.test(frame), reference.runs).astype(bool)
            if holds.all():
                continue
            run = int(np.argmin(holds))
            values = {n: float(np.asarray(scope[n])[run]) for n in sorted(names_in(rule.expr))
                      if n in scope}
            shown = ", ".join(f"{n} = {v:.3g}" for n, v in values.items())
            findings.append(PrescreenFinding(
                rule.name, values, rule.rationale,
                f"the reference run fails prescreen '{rule.name}'"
                + (f" ({shown})" if shown else ""), rule.expr.span))
        return findings

    # ------------------------------------------------------------------ paths
    def path_statistics(self, evaluation: RunEvaluation, failed_runs: int = 0) -> PathStatistics:
        return statistics.path_statistics(evaluation, self.confidence, failed_runs)

    def verdict(self, stats: PathStatistics) -> Verdict:
        return statistics.verdict(self.rulebook, self.checked.constants, stats,
                                  self.checked.verdict_margins)

    def rank(self, stats_by_path: Mapping[str, PathStatistics]) -> list[str]:
        return statistics.rank(self.rulebook, self.checked.constants, stats_by_path,
                               self.checked.verdict_margins)


def _sample_value(index: _Index, frame: Frame, runs: int, samples: int) -> np.ndarray:
    """An index's normalised per-sample value, (runs, samples)."""
    sample = per_run_sample(index.per_sample(frame), runs, samples)
    return normalise(sample, index.limit, index.nominal)


def compile_rulebook(rulebook: Rulebook | CheckedRulebook) -> CompiledRulebook:
    """Compile a rulebook (checked first when given as a plain rule model)."""
    return CompiledRulebook(rulebook)
