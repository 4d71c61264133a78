"""``idefix-verify build-fmu``: (re)build the rover FMU and print its path as the last line."""

from __future__ import annotations

import argparse
import zipfile
from pathlib import Path

from idefix_rules.cli.destinations import output_file

NAME = "build-fmu"
HELP = "build the rover FMU from its C sources for this platform and print the .fmu path"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cached", action="store_true",
                        help="reuse the cached FMU when one was built from these sources "
                             "(default: always rebuild)")
    parser.add_argument("--output", "-o", type=fmu_file, default=None,
                        help="write the .fmu here instead of the cache "
                             "($IDEFIX_CACHE or ~/.cache/idefix-rules); an existing file is "
                             "replaced only when it is an FMU")
    parser.add_argument("--validate", action="store_true",
                        help="also run fmpy's validation on the built FMU")


def fmu_file(text: str) -> Path:
    """Where the FMU goes (:func:`output_file`): a file there already is replaced only when
    it is an FMU (a zip holding ``modelDescription.xml``), never a rulebook or campaign named
    by mistake."""
    path = output_file(text)
    if path.exists() and not _is_fmu(path):
        raise argparse.ArgumentTypeError(f"{text} exists and is not an FMU: building would "
                                         "replace it; name another file or remove it first")
    return path


def _is_fmu(path: Path) -> bool:
    try:
        with zipfile.ZipFile(path) as archive:
            return "modelDescription.xml" in archive.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def run(args: argparse.Namespace) -> int:
    from idefix_rules.cli.console import make_console
    from idefix_rules.fmu.build import build_fmu, source_dir

    console = make_console(stderr=True)
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
