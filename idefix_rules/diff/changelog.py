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

from idefix_rules.diff.rules import FieldChange, RuleChange, RuleDiff

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
