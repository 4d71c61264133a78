"""``idefix-verify explain-error CODE``: the long explanation of a diagnostic code.

Prints what the code means, an example of the mistake and its fix; ``--list`` prints every
code with its title. Exit 0, or 2 for a code that does not exist (with close codes named).
"""

from __future__ import annotations

import argparse
import difflib

from idefix_rules.diagnostic_codes import CODES, explain
from idefix_rules.errors import UserInputError, error

NAME = "explain-error"
HELP = ("Explain a diagnostic code (e.g. E201, W610, T005): what it means, an example of the "
        "mistake and its fix. --list prints every code.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("code", nargs="?", metavar="CODE", help="a code such as E201")
    parser.add_argument("--list", action="store_true", help="list every code with its title")


def run(args: argparse.Namespace) -> int:
    if args.list:
        for code, item in sorted(CODES.items()):
            print(f"{code}  {item.title}")
        return 0
    if not args.code:
        raise UserInputError(error("E000", "name a code, e.g. 'idefix-verify explain-error "
                                           "E201', or --list"))
    entry = explain(args.code)
    if entry is None:
        close = difflib.get_close_matches(args.code.strip().upper(), list(CODES), n=3)
        raise UserInputError(error(
            "E000", f"unknown diagnostic code {args.code!r}",
            hint=(f"did you mean {', '.join(close)}?" if close else None)
            or "idefix-verify explain-error --list prints every code"))
    print(entry.render())
    return 0
