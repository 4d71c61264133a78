"""``idefix-verify``: the command line.

Each subcommand lives in its own module of this package with ``NAME``, ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. A command module imports at its top only
what reading the command line needs (argparse, :mod:`idefix_rules.limits` …); what the command
needs to run (rich, numpy, h5py, the rulebook, the campaign) it imports inside ``run``, so
``--version`` and every ``--help`` answer in a tenth of a second
(``tests/cli/test_cli_startup.py``, ``benchmarks/bench_startup.py``). The dispatcher catches only
:class:`~idefix_rules.errors.IdefixError` (rendered, exit code from the error); anything else is
an internal error (exit 3). ``idefix-verify campaign.yaml`` is short for
``idefix-verify run campaign.yaml``. A reader that closes standard output early
(``idefix-verify explain … | head -1``) ends the command quietly with exit 141, the code a shell
reports for a process ended by SIGPIPE. A standard output or error whose encoding lacks a
character the output uses gets an ASCII equivalent (:mod:`idefix_rules.cli.encoding`).
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import signal
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from idefix_rules import __version__
from idefix_rules.cli.encoding import tolerate_encodings
from idefix_rules.cli.pipes import quiet_broken_pipe
from idefix_rules.errors import IdefixError

# Module names under idefix_rules.cli, in the order --help lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "run",
    "worst",
    "evaluate",
    "check",
    "fmt",
    "explain",
    "diff",
    "test",
    "explain_error",
    "report",
    "build_fmu",
    "lsp",
)

DEFAULT_COMMAND = "run"
_TOP_LEVEL_OPTIONS = ("-h", "--help", "--version")


def _load_commands() -> dict[str, ModuleType]:
    modules = {}
    for module_name in COMMAND_MODULES:
        module = importlib.import_module(f"idefix_rules.cli.{module_name}")
        modules[module.NAME] = module
    return modules


def build_parser(commands: dict[str, ModuleType]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="idefix-verify",
        description="Verify IDEFIX driving command chains against a rulebook. "
                    "`idefix-verify CAMPAIGN.yaml` runs a campaign (same as `run`).",
    )
    parser.add_argument("--version", action="version", version=f"idefix-rules {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module in commands.items():
        command_parser = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(command_parser)
    return parser


def _looks_like_campaign(argument: str) -> bool:
    """A word that is no command is taken as a campaign file when it could be one."""
    return bool(argument) and (Path(argument).suffix.lower() in (".yaml", ".yml")
                               or Path(argument).exists())


def main(argv: Sequence[str] | None = None) -> int:
    tolerate_encodings()  # an ASCII stdout gets "-" for "–", not a traceback after the work
    try:
        code = _main(argv)
        if not sys.stdout.closed:  # the language server closes it on exit
            sys.stdout.flush()  # a pipe closed early shows here, not at the interpreter's exit
    except BrokenPipeError:
        return quiet_broken_pipe()
    return code


def process_main() -> int:
    """``idefix-verify`` as a process (the console script, ``python -m idefix_rules``):
    :func:`main`, then Ctrl-C ignored while the interpreter shuts down. The command has
    finished and said what it had to say; an interrupt arriving now (a user pressing Ctrl-C as
    a long campaign ends) would only print a traceback from the interpreter's clean-up and
    could not change the exit code.

    Under ``python -m idefix_rules`` CPython may end an interrupted command by SIGINT itself
    rather than with 130: it does so whenever a KeyboardInterrupt ended a string ``exec`` (a
    library defining a dataclass as Ctrl-C came, during a lazy import), even one caught later
    (bpo-41602). A shell's ``$?`` is 130 either way; the console script is not affected."""
    code = main()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return code


def _main(argv: Sequence[str] | None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    commands = _load_commands()
    parser = build_parser(commands)
    if args_list and args_list[0].startswith("-") and args_list[0] not in _TOP_LEVEL_OPTIONS \
            and DEFAULT_COMMAND in commands and any(map(_looks_like_campaign, args_list)):
        args_list.insert(0, DEFAULT_COMMAND)  # `idefix-verify --runs 8 c.yaml`: run's options
    elif args_list and not args_list[0].startswith("-") and args_list[0] not in commands \
            and DEFAULT_COMMAND in commands:
        if not _looks_like_campaign(args_list[0]):
            parser.print_usage(sys.stderr)
            close = difflib.get_close_matches(args_list[0], list(commands), n=1)
            print(f"idefix-verify: error: unknown command {args_list[0]!r}"
                  + (f" (did you mean {close[0]!r}?)" if close else "")
                  + f"; commands: {', '.join(commands)}; or a campaign file: "
                  "idefix-verify CAMPAIGN.yaml", file=sys.stderr)
            return 2
        args_list.insert(0, DEFAULT_COMMAND)
    try:
        args = parser.parse_args(args_list)
    except SystemExit as exit_request:  # argparse: usage errors are exit 2 already
        return int(exit_request.code or 0)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        return int(commands[args.command].run(args))
    except IdefixError as failure:
        print(failure.render(), file=sys.stderr)
        return failure.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        raise  # main() ends quietly
    except Exception as failure:  # last line of defence: report, exit 3
        if _caused_by_interrupt(failure):
            # Ctrl-C inside a C extension's initialisation (scipy imported as it came)
            # surfaces as the ImportError it caused: an interrupt, not an internal error
            print("interrupted", file=sys.stderr)
            return 130
        traceback.print_exc()
        print("idefix-verify: internal error (exit 3); please report the traceback above",
              file=sys.stderr)
        return 3


def _caused_by_interrupt(failure: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in ``failure``'s chain of causes (``raise … from``, as
    a C extension's failed initialisation raises it; not a mere context: an error raised
    while a Ctrl-C was being handled is an error of its own).

    >>> try:
    ...     try:
    ...         raise KeyboardInterrupt
    ...     except KeyboardInterrupt as interrupt:
    ...         raise ImportError("initialization failed") from interrupt
    ... except ImportError as failure:
    ...     _caused_by_interrupt(failure), _caused_by_interrupt(ValueError())
    (True, False)
    >>> try:
    ...     try:
    ...         raise KeyboardInterrupt
    ...     except KeyboardInterrupt:
    ...         raise ValueError("a bug in the handler")
    ... except ValueError as failure:
    ...     _caused_by_interrupt(failure)
    False
    """
    seen: set[int] = set()
    current: BaseException | None = failure
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__
    return False


if __name__ == "__main__":
    sys.exit(main())
