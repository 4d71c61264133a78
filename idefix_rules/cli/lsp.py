"""``idefix-verify lsp``: the rulebook language server, over stdin and stdout.

Editors start it (see ``docs/editor.md``); it needs the optional extra
``pip install 'idefix-rules[lsp]'`` (pygls). Without it the command says so and exits 3 (the
installation, not the input, is incomplete).
"""

from __future__ import annotations

import argparse
import math

from idefix_rules.errors import InfrastructureError

NAME = "lsp"
HELP = ("Run the rulebook language server over stdio for editors: diagnostics as `check "
        "--strict`, hover, go to definition, references, completion, formatting as `fmt`, "
        "quick fixes. Needs `pip install 'idefix-rules[lsp]'`; see docs/editor.md.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--stdio", action="store_true",
                        help="talk over stdin/stdout (the default and only transport; accepted "
                             "because editors pass it)")
    parser.add_argument("--debounce", type=_seconds, default=None, metavar="SECONDS",
                        help="wait this long after the last change before checking a document "
                             "(default 0.3)")


def _seconds(text: str) -> float:
    """A finite, non-negative number of seconds (argparse turns the error into exit 2)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds >= 0, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    try:
        from idefix_rules.lsp.server import DEBOUNCE_SECONDS, serve
    except ImportError as missing:
        raise InfrastructureError(
            f"the language server needs the optional extra: pip install 'idefix-rules[lsp]' "
            f"({missing})") from None
    debounce = DEBOUNCE_SECONDS if args.debounce is None else args.debounce
    serve(debounce)
    return 0
