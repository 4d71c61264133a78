"""One campaign at a time per output folder: a lock file that names its owner.

A campaign (``run``, ``--resume``) and ``evaluate`` own the folder they write into while they
run. The lock file :data:`LOCK_FILE` in that folder holds the owner's pid, host, start time and
command; it is created complete or not at all (written to a temporary file, then linked to its
name, which fails when the name exists), and removed on every way out of the owner (return,
error, Ctrl-C). A second campaign is refused (``C208``, exit 2) with the owner named.

A ``kill -9`` or a power cut leaves the file behind. It is stale when its owner ran on this
host and either no longer runs or its pid now belongs to a process started at another time; a
stale lock is taken over, with a one-line note. A lock from another host cannot be checked
from here: it is refused, and the message says which file to delete once that owner is gone.

>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> with own_folder(folder, "example") as lock:
...     (folder / LOCK_FILE).exists(), lock.note
(True, None)
>>> (folder / LOCK_FILE).exists()
False
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import json
import os
import secrets
import socket
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from idefix_rules.campaign.storage import diskspace
from idefix_rules.errors import Diagnostic, Span, UserInputError, error

LOCK_FILE = ".idefix.lock"
FOLDER_IN_USE = "C208"
FOLDER_UNUSABLE = "C205"

# A lock file that cannot be read yet may be one being written by a file system without hard
# links (created empty, then filled): it is waited for this long before it counts as garbage.
UNREADABLE_GRACE_SECONDS = 5.0
ELSEWHERE = "give this one another output folder with --out DIR"
_ATTEMPTS = 50


@dataclass(frozen=True)
class Owner:
    """Who holds a folder: enough to name it to a person and to tell whether it still runs."""

    pid: int
    host: str
    started: str  # local time with its offset, to the second
    command: str
    # The kernel's start time of the pid (Linux: boot id and clock ticks since boot); tells a
    # pid reused by a later process from the owner. None where it cannot be read.
    process_start: str | None = None
    # The JUnit file the owner writes (absolute), so that a command refused for the folder
    # (C208) leaves it to its owner. None: it writes none.
    junit: str | None = None

    def to_json(self) -> str:
        return json.dumps({"format": "idefix-lock", "pid": self.pid, "host": self.host,
                           "started": self.started, "command": self.command,
                           "process_start": self.process_start, "junit": self.junit},
                          indent=1) + "\n"

    @classmethod
    def from_json(cls, data: bytes) -> Owner | None:
        """The owner a lock file names, or None when it is not a complete lock file."""
        try:
            record = json.loads(data.decode("utf-8"))
            owner = cls(int(record["pid"]), str(record["host"]), str(record["started"]),
                        str(record.get("command", "")), record.get("process_start"),
                        record.get("junit"))
        except (ValueError, KeyError, TypeError, AttributeError):
            return None
        if any(value is not None and not isinstance(value, str)
               for value in (owner.process_start, owner.junit)):
            return None
        return owner

    def describe(self) -> str:
        """``pid 4242 on host node7, started 2025-05-01 12:00:03+02:00 (idefix-verify …)``."""
        started = self.started.replace("T", " ")
        command = f" ({self.command})" if self.command else ""
        return f"pid {self.pid} on host {self.host}, started {started}{command}"


def this_process(command: str | None = None, junit: Path | None = None) -> Owner:
    """The owner record of the running process (``junit``: the JUnit file it writes)."""
    if command is None:
        program = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"
        if program == "__main__.py":
            program = "python -m idefix_rules"
        command = " ".join([program, *sys.argv[1:]])
    started = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
    return Owner(os.getpid(), socket.gethostname(), started, command[:300],
                 process_start(os.getpid()),
                 None if junit is None else str(Path(junit).resolve()))


def process_start(pid: int) -> str | None:
    """When the kernel started ``pid`` (Linux), or None where that cannot be read."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[-1].split()  # the command name may hold spaces and ')'
    return f"{boot}:{fields[19]}" if len(fields) > 19 else None


def _zombie(pid: int) -> bool:
    """Whether ``pid`` has ended and only waits for its parent to collect it (Linux)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    fields = stat.rsplit(")", 1)[-1].split()
    return bool(fields) and fields[0] in ("Z", "X")


def _running(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by another user
    except OSError:
        return True  # cannot tell: keep the lock
    return not _zombie(pid)


def stale_reason(owner: Owner, me: Owner) -> str | None:
    """Why ``owner`` no longer holds its lock, or None while it may (or when that cannot be
    told from this host)."""
    if owner.host != me.host:
        return None
    if not _running(owner.pid):
        return "that process no longer runs"
    if owner.process_start is not None:
        now = process_start(owner.pid)
        if now is not None and now != owner.process_start:
            return "its pid now belongs to another process"
    if owner.pid == me.pid:
        return "this process left it"  # not in _HELD: a lock never released
    return None


@dataclass
class FolderLock:
    """A folder this process owns; :meth:`release` gives it up (only its creator can)."""

    folder: Path
    path: Path
    owner: Owner
    data: bytes
    note: str | None = None  # set when a stale lock was taken over

    def release(self) -> None:
        if os.getpid() != self.owner.pid:
            return  # a forked child never frees its parent's folder
        try:
            if self.path.read_bytes() == self.data:
                self.path.unlink()
        except OSError:
            pass  # gone already, or taken over: not ours to remove any more


# Folders this process owns, so that the command line and the campaign it runs can both ask.
_HELD: dict[Path, FolderLock] = {}


class FolderInUse(UserInputError):
    """``C208``: another process owns the folder; ``owner`` names it (None when its lock
    file cannot be read, or changed hands too often to tell)."""

    def __init__(self, diagnostic: Diagnostic, owner: Owner | None,
                 sources: dict[str, str] | None = None) -> None:
        super().__init__(diagnostic, sources=sources)
        self.owner = owner

    def may_write(self, path: Path) -> bool:
        """Whether the owner may write ``path`` as its JUnit file (True when it cannot be
        told: another process's output is never taken from it)."""
        return self.owner is None or self.owner.junit == str(Path(path).resolve())


@contextlib.contextmanager
def own_folder(folder: Path, command: str | None = None, span: Span | None = None,
               sources: dict[str, str] | None = None,
               elsewhere: str | None = ELSEWHERE,
               junit: Path | None = None) -> Iterator[FolderLock]:
    """Own ``folder`` (which must exist) for the ``with`` block; :class:`FolderInUse`
    ``C208`` when another live process owns it (``elsewhere``: how the refused command could
    write somewhere else, for the hint). The lock names ``junit``, the JUnit file this
    process writes. A process may own a folder more than once (nested), the lock goes with
    the outermost block."""
    key = folder.resolve()
    held = _HELD.get(key)
    if held is not None and held.owner.pid == os.getpid():
        yield FolderLock(held.folder, held.path, held.owner, held.data)  # the outer one frees it
        return
    lock = acquire(folder, command, span, sources, elsewhere, junit)
    _HELD[key] = lock
    try:
        yield lock
    finally:
        _HELD.pop(key, None)
        lock.release()


def acquire(folder: Path, command: str | None = None, span: Span | None = None,
            sources: dict[str, str] | None = None,
            elsewhere: str | None = ELSEWHERE, junit: Path | None = None) -> FolderLock:
    """Create the lock file in ``folder``, taking over a stale one; refuse a live owner."""
    path = folder / LOCK_FILE
    me = this_process(command, junit)
    data = me.to_json().encode("utf-8")
    notes: list[str] = []
    unreadable_since: float | None = None
    attempts = 0
    while attempts < _ATTEMPTS:
        attempts += 1
        try:
            _create(path, data)
            return FolderLock(folder, path, me, data, notes[-1] if notes else None)
        except FileExistsError:
            pass
        except OSError as failure:
            if diskspace.is_disk_full(failure):  # exit 3 as every full disk (operations.md)
                raise diskspace.DiskFull(folder, diskspace.free_bytes(folder), len(data),
                                         f"create {path.name}", "free space, then run again"
                                         ) from None
            raise UserInputError(error(
                FOLDER_UNUSABLE, f"output folder {folder} cannot be used: cannot create "
                                 f"{path.name}: {failure.strerror or failure}",
                span or Span(str(folder))), sources=sources) from None
        try:
            seen = path.read_bytes()
        except FileNotFoundError:
            continue  # released meanwhile: try again
        except OSError as failure:
            raise FolderInUse(error(
                FOLDER_IN_USE, f"output folder {folder} may be in use: its lock file cannot "
                               f"be read ({failure.strerror or failure})", Span(str(path)),
                hint=f"delete {path} once no campaign writes into {folder}"), None,
                sources=sources) from None
        owner = Owner.from_json(seen)
        if owner is None:
            # Being written by a process on a file system without hard links, or garbage
            # left by one killed while it wrote it.
            unreadable_since = unreadable_since or time.monotonic()
            if not _old(path) and time.monotonic() - unreadable_since < UNREADABLE_GRACE_SECONDS:
                attempts -= 1  # waiting for it to be written is no attempt
                time.sleep(0.05)
                continue
            reason, named = "it is not a complete lock file", "an unknown owner"
        else:
            stale = stale_reason(owner, me)
            if stale is None:
                raise FolderInUse(_in_use(folder, path, owner, me, elsewhere), owner,
                                  sources=sources)
            reason, named = stale, owner.describe()
        if _take_away(path, seen):
            notes.append(f"{path}: took over the lock of {named}: {reason}")
    raise FolderInUse(error(
        FOLDER_IN_USE, f"output folder {folder} is contended: its lock changed hands "
                       f"{_ATTEMPTS} times while this campaign tried to take it",
        Span(str(path)), hint="more than one campaign is starting on this folder: run one "
                              "at a time, or give each its own --out"), None, sources=sources)


def _in_use(folder: Path, path: Path, owner: Owner, me: Owner,
            elsewhere: str | None) -> Diagnostic:
    other = f", or {elsewhere}" if elsewhere else ""
    if owner.host == me.host:
        hint = f"wait until it ends (or stop it: kill {owner.pid}){other}"
    else:
        hint = (f"wait until it ends{other}; a process on another host cannot be checked from "
                f"here: if it no longer runs, delete {path}")
    return error(FOLDER_IN_USE, f"output folder {folder} is in use by another campaign: "
                                f"{owner.describe()}", Span(str(path)), hint=hint)


def _old(path: Path) -> bool:
    try:
        return time.time() - path.stat().st_mtime > UNREADABLE_GRACE_SECONDS
    except OSError:
        return False


def _create(path: Path, data: bytes) -> None:
    """Give ``path`` the content ``data``, complete, unless it exists (FileExistsError)."""
    fd, temporary = tempfile.mkstemp(prefix=f"{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        try:
            os.link(temporary, path)  # atomic, and fails when the name exists (NFS too)
        except FileExistsError:
            raise
        except OSError as failure:
            if failure.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP,
                                     errno.EMLINK, errno.ENOSYS):
                raise
            _create_exclusive(path, data)  # no hard links here: create, then fill
    finally:
        Path(temporary).unlink(missing_ok=True)


def _create_exclusive(path: Path, data: bytes) -> None:
    fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)


def _take_away(path: Path, seen: bytes) -> bool:
    """Remove the stale lock ``path`` if it still holds ``seen``; False when another process
    changed it first (its new lock is put back)."""
    aside = path.with_name(f"{path.name}.stale-{os.getpid()}-{secrets.token_hex(4)}")
    try:
        os.rename(path, aside)  # atomic: of two processes taking over, one gets it
    except FileNotFoundError:
        return False
    try:
        if aside.read_bytes() == seen:
            return True
        with contextlib.suppress(OSError):  # a fresh lock was moved: give it back
            os.link(aside, path)
        return False
    finally:
        aside.unlink(missing_ok=True)
