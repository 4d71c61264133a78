"""One analysis of an editor buffer: the checker's diagnostics, the rule model and its symbols.

The diagnostics are those of ``idefix-verify check --strict`` on the same text, from the same
function (:func:`idefix_rules.rulebook.checking.check_source`): the editor and the command line
never disagree. The rule model (when the text parses) and the checked rulebook (when it also checks)
feed hover, go to definition, references and completion.

>>> analysis = analyse('rulebook "r" version "1" purpose "p"\\n', "r.rules")
>>> [d.code for d in analysis.diagnostics]
['E501', 'E502', 'E503']
"""

from __future__ import annotations

from dataclasses import dataclass

from idefix_rules.errors import Diagnostic, UserInputError
from idefix_rules.lsp.positions import LineIndex
from idefix_rules.lsp.symbols import SymbolIndex, symbol_index
from idefix_rules.rulebook import check, parse_text
from idefix_rules.rulebook.check import CheckedRulebook
from idefix_rules.rulebook.checking import check_source
from idefix_rules.rulebook.model import Rulebook

# ``check --strict``: the editor shows the warnings too (unused constants, zero weights).
STRICT = True


@dataclass(frozen=True)
class Analysis:
    """What the server knows about one version of a document."""

    path: str
    text: str
    diagnostics: tuple[Diagnostic, ...]
    rulebook: Rulebook | None
    checked: CheckedRulebook | None
    symbols: SymbolIndex
    lines: LineIndex


def analyse(text: str, path: str) -> Analysis:
    """Check ``text`` (the buffer of the file ``path``) and index its symbols."""
    report = check_source(text, path, strict=STRICT)
    rulebook: Rulebook | None
    try:
        rulebook = parse_text(text, path)
    except UserInputError:
        rulebook = None
    checked = check(rulebook).checked if rulebook is not None else None
    lines = LineIndex(text)
    return Analysis(path, text, report.diagnostics, rulebook, checked,
                    symbol_index(rulebook, lines), lines)
