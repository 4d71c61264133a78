"""``idefix-verify lsp``: the rulebook language server, over stdin and stdout.

Editors start it (see ``docs/editor.md``); it needs the optional extra
``pip install 'idefix-rules[lsp]'`` (pygls). Without it the command says so and exits 3 (the
installation, not the input, is incomplete).
"""

from __future__ import annotations

import argparse

from idefix_rules.errors import InfrastructureError

NAME = "lsp"
HELP = ("Run the rulebook language server over stdio for editors: diagnostics as `check "
        "--strict`, hover, go to definition, references, completion, formatting as `fmt`, "
        "quick fixes. Needs `pip install 'idefix-rules[lsp]'`; see docs/editor.md.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--stdio", action="store_true",
                        help="talk over stdin/stdout (the default and only transport; accepted "
                             "because editors pass it)")
    parser.add_argument("--debounce", type=float, default=None, metavar="SECONDS",
                        help="wait this long after the last change before checking a document "
                             "(default 0.3)")


def run(args: argparse.Namespace) -> int:
    try:
        from idefix_rules.lsp.server import DEBOUNCE_SECONDS, serve
    except ImportError as missing:
        raise InfrastructureError(
            f"the language server needs the optional extra: pip install 'idefix-rules[lsp]' "
            f"({missing})") from None
    debounce = DEBOUNCE_SECONDS if args.debounce is None else max(0.0, args.debounce)
    serve(debounce)
    return 0
