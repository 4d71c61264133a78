"""Diffs against earlier rulebook versions: what changed in the rules, and what that does to
stored results (re-scored under both rulebooks, no simulation).

>>> from idefix_rules.diff import load_source, diff_rules  # doctest: +SKIP
>>> old = load_source("rulebooks/idefix-ops.rules@HEAD~1")  # doctest: +SKIP
>>> new = load_source("rulebooks/idefix-ops.rules")  # doctest: +SKIP
>>> diff_rules(old.checked, new.checked, old.label, new.label).counts()  # doctest: +SKIP
"""

from idefix_rules.diff.rules import FieldChange, RuleChange, RuleDiff, diff_rules
from idefix_rules.diff.source import RulebookSource, load_source, split_spec

__all__ = [
    "FieldChange",
    "RuleChange",
    "RuleDiff",
    "RulebookSource",
    "diff_rules",
    "load_source",
    "split_spec",
]
