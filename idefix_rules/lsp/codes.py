"""The explanation of a diagnostic code, shown when the editor hovers over a problem.

:func:`code_explanation` is the one place the language server asks; it renders the entry of
:mod:`idefix_rules.diagnostic_codes`, the same catalogue ``idefix-verify explain-error`` prints.

>>> code_explanation("E201").splitlines()[0]
'dimensions do not match'
"""

from __future__ import annotations

from idefix_rules.diagnostic_codes import explain


def code_explanation(code: str) -> str | None:
    """What a diagnostic code means (Markdown), or ``None`` for a code without explanation."""
    entry = explain(code)
    if entry is None:
        return None
    example = "\n".join("    " + line for line in entry.example.splitlines())
    return (f"{entry.title}\n\n{entry.explanation}\n\nFor example:\n\n{example}\n\n"
            f"Fix: {entry.fix}")
