"""``idefix-verify check RULEBOOK…``: parse and check rulebooks, print every diagnostic.

Exit 0 when every file is valid, 2 when any file has a diagnostic (with ``--strict``, the
warnings W601–W616 count too: unused constants, zero-weight indices and the lints of
:mod:`idefix_rules.rulebook.lints`). ``--format json`` prints the diagnostics' ``to_dict()``
records instead of text (start and end of each span; the end column is exclusive). The language
server (``idefix-verify lsp``) publishes the same diagnostics through
:func:`idefix_rules.rulebook.checking.check_source`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from idefix_rules.cli.encoding import json_text
from idefix_rules.errors import render_diagnostics

if TYPE_CHECKING:
    from idefix_rules.rulebook.checking import FileReport

NAME = "check"
HELP = ("Check rulebooks: syntax, names, units and dimensions, weights, required sections. "
        "Exit 0 when all are valid, 2 otherwise (every problem of every file is printed as "
        "path:line:col with the source line).")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("rulebooks", nargs="+", type=Path, metavar="RULEBOOK",
                        help="rulebook files (.rules)")
    parser.add_argument("--strict", action="store_true",
                        help="also warn about unused constants, indices with zero weight, "
                             "ratios written as bare numbers above 1, comparisons that are "
                             "always true or false, rationales that disagree with their value, "
                             "numbers too small for a double's precision, a nominal nearly "
                             "at 0 or at its limit, windows that hold no sample and "
                             "percentiles written as fractions (W601-W616); "
                             "warnings then fail the check (exit 2)")
    parser.add_argument("--format", choices=("text", "json"), default="text",
                        help="text (default) or json: a list of diagnostics (code, severity, "
                             "message, path, line, column, end_line, end_column, hint)")


def check_file(path: str | Path, strict: bool = False) -> FileReport:
    """Read, parse and check one rulebook; never raises for a user mistake
    (:func:`idefix_rules.rulebook.checking.check_file`, imported when used)."""
    from idefix_rules.rulebook.checking import check_file as check

    return check(path, strict)


def check_source(source: str, name: str, strict: bool = False) -> FileReport:
    """Parse and check rulebook text read from ``name``
    (:func:`idefix_rules.rulebook.checking.check_source`, imported when used)."""
    from idefix_rules.rulebook.checking import check_source as check

    return check(source, name, strict)


def render_report(report: FileReport) -> str:
    """Diagnostics as ``path:line:col: severity[code]: message`` + source line + caret, then a
    summary line for the file."""
    lines = []
    if report.diagnostics:
        lines.append(render_diagnostics(report.diagnostics, {report.path: report.source}))
    if report.errors or report.warnings:
        counts = [f"{report.errors} error{'s' if report.errors != 1 else ''}"]
        if report.warnings:
            counts.append(f"{report.warnings} warning{'s' if report.warnings != 1 else ''}")
        lines.append(f"{report.path}: {', '.join(counts)}")
    else:
        lines.append(f"{report.path}: ok")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    reports = [check_file(path, strict=args.strict) for path in args.rulebooks]
    failed = _failed(reports)
    if args.format == "json":
        records = [d.to_dict() for report in reports for d in report.diagnostics]
        print(json_text(records, indent=2))
        return 2 if failed else 0
    from idefix_rules.cli.console import make_console

    console = make_console(soft_wrap=True)
    for report in reports:
        style = "red" if report.errors else "yellow" if report.warnings else "green"
        text = render_report(report)
        body, _, summary = text.rpartition("\n")
        if body:
            console.print(body, markup=False)
        console.print(summary, style=style, markup=False)
    return 2 if failed else 0


def _failed(reports: Sequence[FileReport]) -> bool:
    return any(report.diagnostics for report in reports)
