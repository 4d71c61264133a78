"""A rule diff as a Markdown changelog entry (``idefix-verify diff OLD NEW --format md``).

The entry is headed by the new name and version, counts the changes by direction, then lists
them grouped *stricter*, *looser*, *unknown*, *neutral* (the reader's order of concern), each
with what changed (as written, and in SI where it differs) and its rationale.

>>> from idefix_rules.diff.rules import RuleDiff, RulebookInfo
>>> info = RulebookInfo("a.rules", "ops", "1.0.0", "0" * 64)
>>> print(changelog(RuleDiff(info, info)))
## ops 1.0.0
<BLANKLINE>
No rule changed (comments and layout aside).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from idefix_rules.diff.rules import FieldChange, RuleChange, RuleDiff

if TYPE_CHECKING:
    from idefix_rules.diff.results import ResultsDiff, SideResult

_ORDER = ("stricter", "looser", "unknown", "neutral")
_TITLES = {"stricter": "Stricter", "looser": "Looser",
           "unknown": "Direction unknown (check with the cases or --results)",
           "neutral": "Neutral (cannot change a pass or a fail)"}


def _item(field: FieldChange, kind: str) -> str:
    def code(text: str | None) -> str:
        return f"`{text}`" if text else "—"

    if kind == "added":
        return f"{field.field} {code(field.new)}"
    if kind == "removed":
        return f"{field.field} {code(field.old)}"
    text = f"{field.field} {code(field.old)}" if field.old == field.new else \
        f"{field.field} {code(field.old)} → {code(field.new)}"
    if field.old_si and field.new_si and field.old_si != field.new_si and \
            (field.old_si, field.new_si) != (field.old, field.new):
        text += f" ({field.old_si} → {field.new_si})"
    return text


def _line(change: RuleChange) -> str:
    what = "; ".join(_item(f, change.kind) for f in change.fields)
    if change.kind == "affected":
        what = "reads " + ", ".join(f"`{n}`" for n in change.reads_changed) + ", which changed"
        if set(change.upstream) != set(change.reads_changed):
            what += " (through " + ", ".join(f"`{n}`" for n in change.upstream) + ")"
    line = f"- {change.kind} {change.section} **{change.name}**"
    if what:
        line += f": {what}"
    if change.rationale:
        line += f" — _{change.rationale}_"
    return line


def changelog(diff: RuleDiff) -> str:
    """The Markdown entry (no trailing newline)."""
    old, new = diff.old, diff.new
    title = f"## {new.name} {new.version}"
    if (old.name, old.version) != (new.name, new.version):
        title += f" (from {old.name} {old.version})"
    lines = [title, ""]
    for warning in diff.warnings:
        lines.append(f"> **Warning:** {warning}")
        lines.append("")
    if diff.identical:
        lines.append("No rule changed (comments and layout aside).")
        return "\n".join(lines)
    counts = diff.directions()
    lines.append(", ".join(f"{counts[label]} {label}" for label in _ORDER if counts[label]) + ".")
    for label in _ORDER:
        chosen = [c for c in diff.changes if c.direction == label]
        if chosen:
            lines += ["", f"### {_TITLES[label]}", ""]
            lines += [_line(c) for c in chosen]
    return "\n".join(lines)


def _side(side: SideResult) -> tuple[str, str, str]:
    verdict = side.verdict + (" (not decided)" if side.undecided else "")
    risk = "—" if side.mean_risk is None else f"{100 * side.mean_risk:.1f} %"
    return verdict, risk, "—" if side.rank is None else str(side.rank)


def _cell(old: str, new: str, changed: bool) -> str:
    text = old if old == new else f"{old} → {new}"
    return f"**{text}**" if changed else text


def _escaped(text: str) -> str:
    """A table cell: its own ``|`` must not end it."""
    return text.replace("|", "\\|")


def results_markdown(results: ResultsDiff, fail_on: str, code: int) -> str:
    """What the change does to stored campaigns (``--results``), for the same changelog entry:
    a table per results file (verdict, risk and rank, old → new; the changes that set the exit
    code in bold, with the new side's reasons), then the exit code in words."""
    lines = ["### Effect on stored campaigns"]
    for file in results.files:
        lines += ["", f"`{file.results}` (campaign {file.campaign}):", "",
                  "| path | verdict | risk | rank | runs whose I_max moved |",
                  "| --- | --- | --- | --- | --- |"]
        for path in file.paths:
            (verdict_old, risk_old, rank_old), (verdict_new, risk_new, rank_new) = \
                _side(path.old), _side(path.new)
            verdict = _cell(verdict_old, verdict_new, path.verdict_changed)
            new_reasons = [r for r in path.new.reasons if r not in path.old.reasons]
            if path.verdict_changed and new_reasons:  # what changed, not what stayed open
                verdict += ": " + "; ".join(new_reasons)
            lines.append(f"| {_escaped(path.name)} | {_escaped(verdict)} | "
                         f"{_cell(risk_old, risk_new, False)} | "
                         f"{_cell(rank_old, rank_new, path.rank_changed)} | "
                         f"{path.changed_runs} of {path.new.runs or path.old.runs} |")
        lines += [f"\n> warning: {warning}" for warning in file.warnings]
    reason = results.exit_reason(fail_on, code)
    lines += ["", reason[:1].upper() + reason[1:] + "."]
    return "\n".join(lines)
