"""Argument types for where the command line writes: refused at parse time (usage error,
exit 2) when the file or folder cannot be written, so a long campaign never ends in a crash
at its last step. Nothing is created here; the commands create what they need.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path


def _named(text: str) -> None:
    """An empty name (``--out "$UNSET"``) would mean the current folder: refused."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty name (is the variable that gives it unset?)")


def output_folder(text: str) -> Path:
    """A folder to write into: an existing writable folder, or one that can be created."""
    _named(text)
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, not a folder")
    _creatable(path, text)
    return path


def output_file(text: str) -> Path:
    """A file to (over)write: not a folder, inside a folder that exists or can be created."""
    _named(text)
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder; give a file name")
    _creatable(path.parent, text)
    return path


def writable_folder(folder: Path) -> str | None:
    """Why this user cannot write into ``folder`` (or create it), or None."""
    try:
        _creatable(folder, str(folder))
    except argparse.ArgumentTypeError as failure:
        return str(failure)
    return None


def _creatable(folder: Path, text: str) -> None:
    existing = folder.absolute()
    while not existing.exists():  # the first existing ancestor decides
        existing = existing.parent
    if not existing.is_dir():
        raise argparse.ArgumentTypeError(f"cannot write {text}: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"cannot write {text}: {existing} is not writable")


def scheduler_address(text: str) -> str:
    """A Dask scheduler address (``tcp://host:port``, ``host:port``): its scheme one Dask
    knows and a location given, checked when the arguments are read (nothing is connected:
    an address no scheduler answers at is the campaign's infrastructure error)."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, location = parse_address(text)
        get_backend(scheme)
        # a network address names a host and a port that is a number (inproc:// does not);
        # without a port Dask's client refuses it once the campaign has started
        host = location if scheme == "inproc" else parse_host_port(location, 8786)[0]
        if not str(host).strip():
            raise argparse.ArgumentTypeError(f"{text!r} is not a Dask scheduler address: it "
                                             "names no host (tcp://HOST:PORT)")
        port = None if scheme == "inproc" else parse_host_port(location)[1]
    except (ValueError, TypeError) as failure:
        raise argparse.ArgumentTypeError(f"{text!r} is not a Dask scheduler address: "
                                         f"{failure} (tcp://HOST:PORT)") from None
    if port is not None and not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"{text!r} is not a Dask scheduler address: port "
                                         f"{port} is not from 1 to 65535 (tcp://HOST:PORT)")
    return text
