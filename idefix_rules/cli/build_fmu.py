"""``idefix-verify build-fmu``: (re)build the rover FMU and print its path as the last line."""

from __future__ import annotations

import argparse

from idefix_rules.cli.destinations import output_file

NAME = "build-fmu"
HELP = "build the rover FMU from its C sources for this platform and print the .fmu path"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cached", action="store_true",
                        help="reuse the cached FMU when one was built from these sources "
                             "(default: always rebuild)")
    parser.add_argument("--output", "-o", type=output_file, default=None,
                        help="write the .fmu here instead of the cache "
                             "($IDEFIX_CACHE or ~/.cache/idefix-rules)")
    parser.add_argument("--validate", action="store_true",
                        help="also run fmpy's validation on the built FMU")


def run(args: argparse.Namespace) -> int:
    from rich.console import Console

    from idefix_rules.fmu.build import build_fmu, source_dir

    console = Console(stderr=True)
    console.print(f"[dim]sources:[/] {source_dir()}")
    path = build_fmu(force=not args.cached or args.output is not None, output=args.output)
    if args.validate:
        from fmpy.validation import validate_fmu

        problems = validate_fmu(str(path))
        for problem in problems:
            console.print(f"[red]problem:[/] {problem}")
        if problems:
            print(path)
            return 3
        console.print("[green]fmpy validate: no problems[/]")
    print(path)
    return 0
