"""The explanation of a diagnostic code, shown when the editor hovers over a problem.

:func:`code_explanation` is the one place the language server asks; it reads the table of
codes of ``docs/rulebook-language.md`` (kept here as data, because an installed package has no
docs folder). When the checker grows long per-code explanations (``explain-error``), point
this function at them.

>>> code_explanation("E201")
'dimensions do not match (`5 cm + 2 deg`)'
"""

from __future__ import annotations

# code -> meaning, as in the "Diagnostics" table of docs/rulebook-language.md
CODE_MEANINGS: dict[str, str] = {
    "E000": "not text / invalid input",
    "E001": "syntax error: unexpected token or character (what was expected is named); "
            "several per file are reported",
    "E002": "rulebook file missing, unreadable or not UTF-8",
    "E003": "number too large",
    "E004": "a section (`settings`, `obstacles`, `combine`, `rank by`, the header) appears twice",
    "E006": "an index lacks `value`, `limit` or `weight`, or gives one twice",
    "E007": "unknown domain after `over` (with 'did you mean')",
    "E008": "unknown `run`/`path` combination",
    "E009": "too many syntax errors: checking stopped",
    "E010": "`fmt` cannot write the file (it is left as it was)",
    "E101": "unknown name, or a name not visible in this context (with 'did you mean')",
    "E102": "declared twice",
    "E103": "a declaration hides a built-in name",
    "E104": "unknown label or obstacle level; selection on an axis the expression lacks",
    "E105": "unknown function",
    "E106": "wrong number of arguments; reducer parameter missing or not allowed",
    "E201": "dimensions do not match (`5 cm + 2 deg`)",
    "E202": "invalid power or square root of a dimension",
    "E204": "wrong dimension (a limit, a setting, a window, an obstacle size)",
    "E205": "unknown unit",
    "E301": "reduction over an axis the operand does not have; reducer that only works over time",
    "E302": "a value still has axes where one value per run (or per command) is needed",
    "E303": "a condition is needed",
    "E304": "a quantity is needed, not a condition",
    "E305": "a window on a reduction that is not over time",
    "E306": "malformed table",
    "E307": "malformed `map`",
    "E308": "percentile outside 0–100",
    "E401": "weight outside [0, 1]",
    "E402": "value out of range (negative buffer or setting, limit not above zero, "
            "slip ≥ 100 %, a constant or limit that is not finite, e.g. a division by zero)",
    "E403": "constants depend on each other in a circle",
    "E405": "obstacle levels missing or thresholds not increasing",
    "E406": "confidence outside [50 %, 100 %)",
    "E500": "no header",
    "E501": "no index",
    "E502": "no verdict rule",
    "E503": "version is not a semantic version",
    "E504": "empty name or purpose",
    "E505": "unknown setting",
    "W601": "(`--strict`) constant never used",
    "W602": "(`--strict`) index with weight 0",
}


def code_explanation(code: str) -> str | None:
    """What a diagnostic code means (Markdown), or ``None`` for a code without explanation."""
    return CODE_MEANINGS.get(code)
