"""Free space in an output folder: checked before each stage that writes, and a full disk
reported as one line (exit 3) naming the folder, what is free and what is needed.

Every stage that writes estimates what it needs (``docs/operations.md``, "Full disk") and
calls :func:`require` first, so a results file is never left with a structural change cut
off by a full disk. A disk that fills anyway (another program writing, an estimate too low)
surfaces as ``ENOSPC`` from the operating system or from HDF5; :func:`guard` turns it into
the same one-line :class:`DiskFull`.

>>> DiskFull("/data/out", 1_200_000, 5_000_000, "store 200 runs", "free space").render()
'disk full: /data/out has 1.2 MB free, about 5.0 MB needed to store 200 runs; free space'
"""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Callable, Iterator
from pathlib import Path

from idefix_rules.errors import InfrastructureError

# Kept free beyond every estimate: room for the HDF5 metadata (object headers, chunk index
# nodes, heaps) a structural change writes with its data, and for the small files around it.
MARGIN = 1 << 20

_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
_FULL_TEXTS = ("errno = 28,", "No space left on device", "errno = 122,", "Disk quota exceeded")


class DiskFull(InfrastructureError):
    """The output folder's file system has not enough free space for a stage: exit code 3."""

    def __init__(self, folder: Path | str, free: int, needed: int | None, doing: str,
                 then: str = "") -> None:
        self.folder = Path(folder).absolute()
        self.free = free
        self.needed = needed
        self.doing = doing
        self.then = then
        wanted = "more space is needed" if needed is None else \
            f"about {megabytes(needed)} needed"
        text = f"disk full: {self.folder} has {megabytes(free)} free, {wanted} to {doing}"
        super().__init__(f"{text}; {then}" if then else text)

    def with_hint(self, then: str) -> DiskFull:
        """The same failure, saying what to do next (``then``) unless it says so already."""
        if self.then:
            return self
        return DiskFull(self.folder, self.free, self.needed, self.doing, then)


def megabytes(size: int) -> str:
    """``1.2 MB`` (decimal megabytes, one decimal; ``0.1 MB`` at least when not zero)."""
    value = size / 1e6
    return f"{max(value, 0.1) if size > 0 else 0.0:.1f} MB"


def free_bytes(folder: Path) -> int:
    """Bytes an unprivileged writer may still use in ``folder`` (its nearest existing
    parent when it does not exist yet)."""
    folder = Path(folder)
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    stats = os.statvfs(folder)
    return int(stats.f_bavail) * int(stats.f_frsize)


def require(folder: Path, needed: int, doing: str, then: str = "") -> None:
    """:class:`DiskFull` unless ``folder`` has ``needed`` bytes plus :data:`MARGIN` free."""
    free = free_bytes(folder)
    if free < needed + MARGIN:
        raise DiskFull(folder, free, needed + MARGIN, doing, then)


def is_disk_full(failure: BaseException | None) -> bool:
    """Whether ``failure`` (or an exception it was raised from) is a full disk or quota,
    as the operating system or HDF5 (inside h5py's messages) says it."""
    seen: set[int] = set()
    while failure is not None and id(failure) not in seen:
        seen.add(id(failure))
        if isinstance(failure, DiskFull):
            return True
        if isinstance(failure, OSError) and failure.errno in _FULL_ERRNOS:
            return True
        if any(text in str(failure) for text in _FULL_TEXTS):
            return True
        failure = failure.__cause__ or failure.__context__
    return False


@contextlib.contextmanager
def guard(folder: Path, doing: str | Callable[[], str], then: str = "",
          needed: Callable[[], int | None] | None = None) -> Iterator[None]:
    """Turn a full disk met inside the block into :class:`DiskFull` (``needed()`` says how
    much the stage still needed, when it can tell; ``doing`` may be a function of the
    progress too), and give a :class:`DiskFull` from inside the hint ``then``; any other
    error passes unchanged."""
    try:
        yield
    except DiskFull as failure:
        if then and not failure.then:
            raise failure.with_hint(then) from None
        raise
    except Exception as failure:
        if not is_disk_full(failure):
            raise
        wanted = needed() if needed is not None else None
        what = doing() if callable(doing) else doing
        raise DiskFull(folder, free_bytes(folder), wanted, what, then) from None
