"""The rule diff: what changed between two checked rulebooks, declaration by declaration.

Each declaration of the canonical order (header, constants, settings, obstacle levels, command
rules, indices, chances, combine, prescreens, verdicts, ranking) is compared by name. A change
lists the fields that differ, each as written (printed by the formatter) and, where a value has
one, in SI: so ``limit = critical_tilt`` shows ``0.3491 rad → 0.2618 rad`` when only the
constant it reads changed. A declaration whose text is the same but that reads a changed
constant, index or chance (directly or through others: a prescreen reading ``I_obs`` when
``f_obs`` changed; a verdict reading ``risk`` when any index changed) is listed as ``affected``,
with the changed names it reads and the changes it comes from (``upstream``). Spans and
comments never count (the model's equality).

>>> from idefix_rules.rulebook import check_text
>>> old = check_text(TEXT_A).checked  # doctest: +SKIP
>>> diff = diff_rules(old, new)  # doctest: +SKIP
>>> [(c.section, c.name, c.kind) for c in diff.changes]  # doctest: +SKIP
[('constant', 'critical_slip', 'changed'), ('index', 'I_beta', 'added')]
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from idefix_rules.diff.collisions import PER_LEVEL, area_moves, level_reads, moved_signals
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.derived import SETTING_SIGNALS
from idefix_rules.rulebook.format import format_expr, format_number, format_string
from idefix_rules.rulebook.model import (
    Chance,
    Combine,
    CommandRule,
    Expr,
    Prescreen,
    Ranking,
    VerdictRule,
)
from idefix_rules.rulebook.semantics import names_in
from idefix_rules.rulebook.types import SETTINGS
from idefix_rules.units import ANGLE, DIMENSIONLESS, LENGTH, Dimension

ChangeKind = Literal["added", "removed", "changed", "affected"]

# Section names in the formatter's canonical order (combine comes before prescreens there).
SECTIONS = ("header", "constant", "setting", "obstacle level", "area", "command", "index",
            "chance", "combine", "prescreen", "verdict", "ranking")

# One field of a declaration: (text as written, SI text or None).
Fields = dict[str, tuple[str, str | None]]


@dataclass(frozen=True)
class FieldChange:
    """One item of a declaration that differs: as written and in SI (``None`` = absent)."""

    field: str
    old: str | None
    new: str | None
    old_si: str | None = None
    new_si: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class RuleChange:
    """A declaration added, removed, changed, or affected (same text, reads a changed constant).

    ``rationale`` is the new rationale (the old one for a removed declaration);
    ``old_rationale`` is set when the rationale itself changed.
    """

    section: str
    name: str
    kind: ChangeKind
    fields: tuple[FieldChange, ...] = ()
    rationale: str | None = None
    old_rationale: str | None = None
    rationale_changed: bool = False
    reads_changed: tuple[str, ...] = ()
    # stricter / looser / neutral / unknown (idefix_rules.diff.direction)
    direction: str = "neutral"
    # an affected declaration: the changed declarations it depends on, however indirectly
    upstream: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {"section": self.section, "name": self.name, "kind": self.kind,
                "direction": self.direction,
                "fields": [f.to_dict() for f in self.fields], "rationale": self.rationale,
                "old_rationale": self.old_rationale,
                "rationale_changed": self.rationale_changed,
                "reads_changed": list(self.reads_changed), "upstream": list(self.upstream)}


@dataclass(frozen=True)
class RulebookInfo:
    """Which rulebook a side of a diff is: the label the user gave, header, hash of the text."""

    label: str
    name: str
    version: str
    sha256: str

    @classmethod
    def of(cls, checked: CheckedRulebook, label: str) -> RulebookInfo:
        header = checked.rulebook.header
        digest = hashlib.sha256(checked.rulebook.source.encode("utf-8")).hexdigest()
        return cls(label, header.name, header.version, digest)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class RuleDiff:
    """Every change from ``old`` to ``new``, in canonical section order."""

    old: RulebookInfo
    new: RulebookInfo
    changes: tuple[RuleChange, ...] = field(default=())
    warnings: tuple[str, ...] = field(default=())

    @property
    def identical(self) -> bool:
        return not self.changes

    def directions(self) -> dict[str, int]:
        """How many changes go each way."""
        labels = ("stricter", "looser", "neutral", "unknown")
        return {label: sum(1 for c in self.changes if c.direction == label)
                for label in labels}

    def counts(self) -> dict[str, int]:
        kinds = ("added", "removed", "changed", "affected")
        return {kind: sum(1 for c in self.changes if c.kind == kind) for kind in kinds}

    def to_dict(self) -> dict[str, Any]:
        return {"old": self.old.to_dict(), "new": self.new.to_dict(),
                "identical": self.identical, "counts": self.counts(),
                "directions": self.directions(), "warnings": list(self.warnings),
                "changes": [c.to_dict() for c in self.changes]}


# ----------------------------------------------------------------------------- SI texts

def si_text(value: Any, dimension: Dimension | None = None) -> str:
    """``0.2618 rad``, ``{L1: 0.2, L2: 0.6, L3: 1}``: a checked value, 6 significant digits."""
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {si_text(v, dimension)}" for k, v in value.items()) + "}"
    number = format_number(float(f"{float(value):.6g}"))
    if dimension is None or dimension.is_dimensionless:
        return number
    return f"{number} {dimension}"


def _dimension(types: Mapping[str, Any], name: str) -> Dimension | None:
    found = types.get(name)
    return getattr(found, "dimension", None)


def _item(expr: Expr | None, si: str | None = None) -> tuple[str, str | None]:
    return (format_expr(expr) if expr is not None else "", si)


# ----------------------------------------------------------------------------- declarations

@dataclass(frozen=True)
class _Declaration:
    name: str
    fields: Fields
    rationale: str | None
    expressions: tuple[Expr, ...]


def _declarations(checked: CheckedRulebook, section: str) -> dict[str, _Declaration]:
    """The declarations of one section by name, with their fields as text."""
    model = checked.rulebook
    found: dict[str, _Declaration] = {}
    if section == "header":
        header = model.header
        found["header"] = _Declaration("header", {
            "name": (format_string(header.name), None),
            "version": (format_string(header.version), None),
            "purpose": (format_string(header.purpose), None)}, None, ())
    elif section == "constant":
        for constant in model.constants:
            si = si_text(checked.constants[constant.name],
                         _dimension(checked.constant_types, constant.name))
            found[constant.name] = _Declaration(constant.name, {"value": _item(constant.value, si)},
                                                constant.rationale, (constant.value,))
    elif section == "setting":
        for setting in model.settings:
            setting_dimension = SETTINGS.get(setting.name, (DIMENSIONLESS, 0.0))[0]
            setting_si = si_text(checked.settings[setting.name], setting_dimension) \
                if setting.name in checked.settings else None
            found[setting.name] = _Declaration(setting.name,
                                               {"value": _item(setting.value, setting_si)},
                                               None, (setting.value,))
    elif section == "obstacle level":
        specs = {spec.level: spec for spec in checked.obstacle_levels}
        for level in model.obstacle_levels:
            spec = specs.get(level.level)
            below_si = si_text(spec.below, LENGTH) if spec and spec.below is not None else None
            buffer_si = si_text(spec.buffer, LENGTH) if spec else None
            found[level.level] = _Declaration(level.level, {
                "below": _item(level.below, below_si), "buffer": _item(level.buffer, buffer_si)},
                None, tuple(e for e in (level.below, level.buffer) if e is not None))
    elif section == "area":
        area_specs = {spec.name: spec for spec in checked.areas}
        for area in model.areas:
            area_spec = area_specs.get(area.name)
            found[area.name] = _Declaration(area.name, {
                "kind": (area.kind, None),
                "above": _item(area.above, si_text(area_spec.above, ANGLE)
                               if area_spec and area_spec.above is not None else None),
                "level": (area.level, None),
                "buffer": _item(area.buffer, si_text(area_spec.buffer, LENGTH)
                                if area_spec else None)},
                area.rationale,
                tuple(e for e in (area.above, area.buffer) if e is not None))
    elif section in ("command", "chance", "prescreen", "verdict"):
        sections: dict[str, Sequence[CommandRule | Chance | Prescreen | VerdictRule]] = {
            "command": model.command_rules, "chance": model.chances,
            "prescreen": model.prescreens, "verdict": model.verdicts}
        rules = sections[section]
        for rule in rules:
            rule_fields: Fields = {"condition": _item(rule.condition)}
            margin = getattr(rule, "indifference", None)
            if section == "verdict":
                rule_fields["indifference"] = _item(margin, si_text(
                    checked.verdict_margins[rule.name])
                    if rule.name in checked.verdict_margins and margin is not None else None)
            found[rule.name] = _Declaration(rule.name, rule_fields, rule.rationale,
                                            tuple(e for e in (rule.condition, margin)
                                                  if e is not None))
    elif section == "index":
        for index in model.indices:
            index_dimension = _dimension(checked.index_types, index.name)
            items: Fields = {
                "title": (format_string(index.title) if index.title is not None else "", None),
                "value": _item(index.value),
                "nominal": _item(index.nominal, si_text(checked.nominals[index.name],
                                                        index_dimension)
                                 if index.name in checked.nominals else None),
                "limit": _item(index.limit, si_text(checked.limits[index.name], index_dimension)),
                "weight": _item(index.weight, si_text(checked.weights[index.name])),
                "map": _item(index.map)}
            found[index.name] = _Declaration(
                index.name, items, index.rationale,
                tuple(e for e in (index.value, index.nominal, index.limit, index.weight,
                                  index.map) if e is not None))
    elif section == "combine":
        combine: Combine = model.combine
        found["combine"] = _Declaration("combine", {
            "run": (str(combine.run), None), "path": (str(combine.path), None),
            "confidence": (format_expr(combine.confidence) if combine.confidence is not None
                           else "", si_text(checked.confidence)),
            "indifference": (format_expr(combine.indifference)
                             if combine.indifference is not None else "",
                             si_text(checked.indifference)),
            "verdict_indifference": _item(combine.verdict_indifference)}, None,
            tuple(e for e in (combine.confidence, combine.indifference,
                              combine.verdict_indifference) if e is not None))
    elif section == "ranking":
        ranking: Ranking = model.ranking
        keys = ", ".join(format_expr(key.expr) + (" desc" if key.descending else "")
                         for key in ranking.keys)
        found["ranking"] = _Declaration("ranking", {"keys": (keys, None)}, None,
                                        tuple(key.expr for key in ranking.keys))
    return found


def _present(fields: Fields) -> tuple[FieldChange, ...]:
    return tuple(FieldChange(name, text, None, si, None)
                 for name, (text, si) in fields.items() if text)


def _compare(old: _Declaration, new: _Declaration) -> tuple[FieldChange, ...]:
    changes = []
    for name in dict.fromkeys([*old.fields, *new.fields]):
        old_text, old_si = old.fields.get(name, ("", None))
        new_text, new_si = new.fields.get(name, ("", None))
        if old_text != new_text or (old_si is not None and new_si is not None
                                    and old_si != new_si):
            changes.append(FieldChange(name, old_text or None, new_text or None, old_si, new_si))
    return tuple(changes)


def _reads(declaration: _Declaration) -> set[str]:
    """The names it reads, and the collision signals per level at each level it reads
    (``collision.hits[L1]``: what a named area of that level moves)."""
    names: set[str] = set()
    for expr in declaration.expressions:
        names |= names_in(expr) | level_reads(expr)
    return names


# What a changed obstacle level moves: its buffer the buffer signal; its size threshold which
# rocks are of it, so every signal per level (the clearance is per part, of every obstacle).
LEVEL_SIGNALS: dict[str, tuple[str, ...]] = {
    "buffer": ("collision.buffer",),
    "below": PER_LEVEL,
}

_RULE_SECTIONS = frozenset({"command", "index", "chance", "prescreen", "verdict"})

# Items whose change moves what a declaration evaluates to (a weight moves the risk only; a
# title, a risk map or a rationale move nothing).
_OUTCOME_FIELDS = frozenset({"value", "limit", "nominal", "condition"})


def _upstream(old: CheckedRulebook, new: CheckedRulebook, changed_constants: set[str],
              seeds: Mapping[str, set[str]] | None = None) -> dict[str, set[str]]:
    """Every name whose value moved, with the changed declarations it comes from: the changed
    constants (and ``seeds``: the signals of changed areas), then, to a fixed point, every
    index or chance that changed or reads one of them, and ``risk`` when an index moved, was
    added or removed, or its weight changed."""
    upstream = {name: {name} for name in changed_constants}
    for name, roots in (seeds or {}).items():
        upstream[name] = set(roots)
    while True:
        grown = False
        for section in ("index", "chance"):
            for change in _section_changes(section, old, new, upstream):
                fields = {f.field for f in change.fields}
                own = change.kind in ("added", "removed") or bool(fields & _OUTCOME_FIELDS)
                roots = set().union(*(upstream[read] for read in change.reads_changed))
                if own:
                    roots.add(change.name)
                if roots:
                    grown |= _extend(upstream, change.name, roots)
                if section == "index":
                    if own or "weight" in fields:
                        roots.add(change.name)
                    if roots:
                        grown |= _extend(upstream, "risk", roots)
        if not grown:
            return upstream


def _extend(upstream: dict[str, set[str]], name: str, roots: set[str]) -> bool:
    before = upstream.get(name, set())
    if roots <= before:
        return False
    upstream[name] = before | roots
    return True


def _section_changes(section: str, old: CheckedRulebook, new: CheckedRulebook,
                     upstream: Mapping[str, set[str]]) -> list[RuleChange]:
    """The changes of one section; ``upstream`` maps the names whose value moved to the
    changes they come from (a declaration with the same text that reads one is affected)."""
    before, after = _declarations(old, section), _declarations(new, section)
    changes: list[RuleChange] = []
    for name in dict.fromkeys([*before, *after]):
        was, now = before.get(name), after.get(name)
        if now is None and was is not None:
            swapped = tuple(FieldChange(f.field, f.old, None, f.old_si, None)
                            for f in _present(was.fields))
            changes.append(RuleChange(section, name, "removed", swapped, was.rationale))
            continue
        if was is None and now is not None:
            added = tuple(FieldChange(f.field, None, f.old, None, f.old_si)
                          for f in _present(now.fields))
            changes.append(RuleChange(section, name, "added", added, now.rationale))
            continue
        assert was is not None and now is not None
        fields = _compare(was, now)
        rationale_changed = was.rationale != now.rationale
        reads = tuple(sorted((_reads(was) | _reads(now)) & set(upstream) - {name}))
        if fields or rationale_changed:
            kind: ChangeKind = "changed"
        elif reads:
            kind = "affected"
        else:
            continue
        roots = set().union(*(upstream[read] for read in reads)) - {name}
        changes.append(RuleChange(section, name, kind, fields, now.rationale,
                                  was.rationale if rationale_changed else None,
                                  rationale_changed, reads,
                                  upstream=tuple(sorted(roots)) if kind == "affected" else ()))
    return changes


def _with_direction(change: RuleChange, old: CheckedRulebook, new: CheckedRulebook
                    ) -> RuleChange:
    from dataclasses import replace

    from idefix_rules.diff.direction import change_direction

    direction = change_direction(old, new, change.section, change.name, change.kind,
                                 [f.field for f in change.fields], change.upstream)
    return replace(change, direction=direction)


def diff_rules(old: CheckedRulebook, new: CheckedRulebook, old_label: str = "old",
               new_label: str = "new") -> RuleDiff:
    """Compare two checked rulebooks; see the module docstring."""
    constants = _section_changes("constant", old, new, {})
    changed_constants = {c.name for c in constants if c.kind != "changed" or c.fields}
    only_constants = {name: {name} for name in changed_constants}
    # an area added, removed or changed (or whose constants moved) moves its own signals and,
    # as an obstacle of its level, the collision signals of that level (diff/collisions.py)
    seeds: dict[str, set[str]] = {}
    areas = {a.name: a for a in old.areas}, {a.name: a for a in new.areas}
    for change in _section_changes("area", old, new, only_constants):
        if change.kind == "changed" and not change.fields:
            continue  # its rationale alone
        roots = {change.name} if change.kind != "affected" else set(change.upstream)
        moves = area_moves(areas[0].get(change.name), areas[1].get(change.name))
        for signal in moved_signals(moves):
            seeds[signal] = seeds.get(signal, set()) | roots
    # a changed setting or obstacle level moves the derived or collision signals it shapes
    for section, signals_of in (("setting", SETTING_SIGNALS), ("obstacle level", None)):
        for change in _section_changes(section, old, new, only_constants):
            if change.kind == "changed" and not change.fields:
                continue  # its rationale alone
            roots = {change.name} if change.kind != "affected" else set(change.upstream)
            if signals_of is not None:
                moved = signals_of.get(change.name, ())
            else:  # a level added or removed, or its constants moved: any of its signals
                fields = {f.field for f in change.fields} if change.kind == "changed" \
                    else set(LEVEL_SIGNALS)
                moved = tuple(dict.fromkeys(signal for field in sorted(fields)
                                            for signal in LEVEL_SIGNALS.get(field, ())))
            for signal in moved:
                seeds[signal] = seeds.get(signal, set()) | roots
    upstream = _upstream(old, new, changed_constants, seeds)
    changes: list[RuleChange] = []
    for section in SECTIONS:
        # settings, levels and the ranking are affected by constants only (``rank by risk``
        # orders the paths, it decides no pass or fail)
        reads = upstream if section in _RULE_SECTIONS else only_constants
        changes += constants if section == "constant" else \
            _section_changes(section, old, new, reads)
    from idefix_rules.diff.versions import version_warnings

    changes = [_with_direction(change, old, new) for change in changes]
    return RuleDiff(RulebookInfo.of(old, old_label), RulebookInfo.of(new, new_label),
                    tuple(changes), tuple(version_warnings(old.rulebook, new.rulebook,
                                                           bool(changes))))


def changed_names(diff: RuleDiff, sections: Iterable[str]) -> set[str]:
    """Names of the declarations of ``sections`` that a diff lists."""
    wanted = set(sections)
    return {c.name for c in diff.changes if c.section in wanted}
