"""Quick fixes: the diagnostics that have one obvious fix, as text edits.

Those are the "did you mean" cases: an unknown name, function, label, setting, domain or keyword
that is close to one the language knows. The checker's hint names the replacement and its
message quotes the word written; the fix replaces that word inside the diagnostic's range.

>>> from idefix_rules.lsp.analysis import analyse
>>> text = '''rulebook "r" version "1.0.0" purpose "p"
... index I_s { value = max over time (max over wheels (abs(wheel.slp))) limit = 1 weight = 1 }
... verdict ok: require risk <= 0.7
... '''
>>> [(fix.title, fix.new_text) for fix in quick_fixes(analyse(text, "r.rules"))]
[("replace 'wheel.slp' with 'wheel.slip'", 'wheel.slip')]
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from idefix_rules.errors import Diagnostic
from idefix_rules.lsp.analysis import Analysis
from idefix_rules.lsp.positions import Range, span_range

_SUGGESTION = re.compile(r"^did you mean '([^']+)'\?$")
_WRITTEN = re.compile(r"'([^']+)'")


@dataclass(frozen=True)
class Fix:
    title: str
    range: Range
    new_text: str
    diagnostic: Diagnostic


def quick_fix(analysis: Analysis, diagnostic: Diagnostic) -> Fix | None:
    """The fix of one diagnostic, when it has a single obvious one."""
    suggestion = _SUGGESTION.match(diagnostic.hint or "")
    written = _WRITTEN.search(diagnostic.message)
    if suggestion is None or written is None:
        return None
    wrong, right = written.group(1), suggestion.group(1)
    covered = span_range(diagnostic.span)
    lines = analysis.lines
    start, end = lines.offset(covered.start), lines.offset(covered.end)
    found = re.search(rf"(?<![\w.]){re.escape(wrong)}(?![\w.])", lines.text[start:end])
    if found is None:
        return None
    return Fix(f"replace '{wrong}' with '{right}'",
               lines.range(start + found.start(), start + found.end()), right, diagnostic)


def quick_fixes(analysis: Analysis) -> list[Fix]:
    """Every quick fix of the document, in the order of its diagnostics."""
    return [fix for fix in (quick_fix(analysis, d) for d in analysis.diagnostics)
            if fix is not None]
