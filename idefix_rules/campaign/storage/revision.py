"""A new version of a results file, written beside it and swapped in whole: how the
evaluation writes (docs/results-format.md, "Write protocol").

HDF5 changes a file's structure in place (object headers, link tables, heaps, chunk
indexes). A structural change cut off by a full disk or a kill can leave a file that no tool
opens again, and the simulated runs with it. The evaluation therefore never writes into the
results file it reads:

1. HDF5 opens a :class:`Revision`: a view of the results file whose reads come from the
   untouched original and whose writes are kept in memory, so HDF5 itself never meets a
   failed write (which would leave its caches in a state no close can flush);
2. the evaluation is written into that view and HDF5 closes it;
3. :meth:`Revision.commit` makes the new file beside the original (``.results.h5.*.tmp``: a
   clone of the original where the file system shares extents, else a copy), patches the
   written bytes in, ``fsync``\\ s it and renames it over ``results.h5`` (``os.replace``).

A failure at any point before the rename (full disk, kill, error) leaves the original file as
it was; a temporary file left by a kill is removed by the next evaluation. The price is room
for a copy of the results file while it is written (none on file systems that clone) and
memory for what the evaluation writes.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import struct
import tempfile
from pathlib import Path
from typing import IO, TYPE_CHECKING

import h5py

from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.journal import stale_end
from idefix_rules.campaign.storage.store import ResultStore

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer, WriteableBuffer

PAGE = 4096
TEMPORARY_SUFFIX = ".tmp"
_FICLONE = 0x40049409  # Linux ioctl: share the extents of another file (btrfs, XFS, …)


class _Overlay(io.RawIOBase):
    """The file HDF5 sees: the original's bytes, with every page written kept in memory."""

    def __init__(self, base: IO[bytes], size: int) -> None:
        super().__init__()
        self.base = base
        self.size = size
        self.base_end = size  # bytes of the original still visible (a truncation hides more)
        self.pages: dict[int, bytearray] = {}
        self.position = 0

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        start = {os.SEEK_SET: 0, os.SEEK_CUR: self.position, os.SEEK_END: self.size}[whence]
        self.position = start + offset
        return self.position

    def tell(self) -> int:
        return self.position

    def _page(self, number: int) -> bytearray:
        page = self.pages.get(number)
        if page is None:
            start = number * PAGE
            page = bytearray(PAGE)
            if start < self.base_end:
                data = self._read_base(start, min(PAGE, self.base_end - start))
                page[:len(data)] = data
            self.pages[number] = page
        return page

    def _read_base(self, offset: int, count: int) -> bytes:
        self.base.seek(offset)
        return self.base.read(count)

    def readinto(self, buffer: WriteableBuffer) -> int:
        view = memoryview(buffer).cast("B")
        start = self.position
        end = min(start + len(view), self.size)
        done = 0
        while start + done < end:
            offset = start + done
            number, within = divmod(offset, PAGE)
            count = min(PAGE - within, end - offset)
            page = self.pages.get(number)
            if page is not None:
                view[done:done + count] = page[within:within + count]
            else:
                visible = max(0, min(count, self.base_end - offset))
                data = self._read_base(offset, visible) if visible else b""
                view[done:done + len(data)] = data
                view[done + len(data):done + count] = bytes(count - len(data))
            done += count
        self.position = start + done
        return done

    def write(self, data: ReadableBuffer) -> int:
        view = memoryview(data).cast("B")
        done = 0
        while done < len(view):
            number, within = divmod(self.position + done, PAGE)
            count = min(PAGE - within, len(view) - done)
            self._page(number)[within:within + count] = view[done:done + count]
            done += count
        self.position += done
        self.size = max(self.size, self.position)
        return done

    def truncate(self, size: int | None = None) -> int:
        size = self.position if size is None else size
        if size < self.size:
            self.base_end = min(self.base_end, size)
            last, within = divmod(size, PAGE)
            for number in [n for n in self.pages if n > last or (n == last and within == 0)]:
                del self.pages[number]
            if within and last in self.pages:
                self.pages[last][within:] = bytes(PAGE - within)
        self.size = size
        return size

    def flush(self) -> None:
        pass

    def written(self) -> int:
        """Bytes of the pages written (what a clone of the original needs besides)."""
        return len(self.pages) * PAGE


class Revision:
    """A new version of the results file at ``path``: :attr:`store` writes into it,
    :meth:`commit` puts it in place of the original, :meth:`discard` (also on leaving a
    ``with`` block) drops it. The original is only read until the commit renames over it."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        remove_stale_temporaries(self.path)
        self._base: IO[bytes] | None = open(self.path, "rb")  # noqa: SIM115 (closed by discard)
        self._overlay = _Overlay(self._base, os.fstat(self._base.fileno()).st_size)
        end = stale_end(self._base.read(64), self._overlay.size)
        if end is not None:  # a writer was killed mid-flush: the new version counts its bytes
            self._overlay.seek(end)
            self._overlay.write(struct.pack("<Q", self._overlay.size))
        self._temporary: Path | None = None
        self.cloned = False
        try:
            self._start_copy()
            file = h5py.File(self._overlay, "r+")
        except BaseException:
            self.discard()
            raise
        self.store = ResultStore(file, self.path)

    def _start_copy(self) -> None:
        """Create the temporary file beside the original, as a clone of it where the file
        system can share extents (free, instant); else it is copied at the commit."""
        handle, name = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=TEMPORARY_SUFFIX,
                                        dir=self.path.parent)
        self._temporary = Path(name)
        try:
            self.cloned = _clone(self._open_base().fileno(), handle)
        finally:
            os.close(handle)

    def _open_base(self) -> IO[bytes]:
        assert self._base is not None, "the revision was discarded"
        return self._base

    def needed(self, extra: int) -> int:
        """Bytes the commit needs on disk when the evaluation writes ``extra`` bytes: a copy
        of the original unless it was cloned."""
        return extra + (0 if self.cloned else self._overlay.base_end)

    def commit(self, doing: str, then: str = "") -> None:
        """Close the store, write the new file beside the original and rename it over the
        original. :class:`~idefix_rules.campaign.storage.diskspace.DiskFull` (the original
        untouched) when the disk cannot hold it."""
        self.store.close()  # HDF5 writes everything into the overlay
        assert self._temporary is not None
        folder = self.path.parent
        with diskspace.guard(folder, doing, then, lambda: self.needed(self._overlay.written())):
            diskspace.require(folder, self.needed(self._overlay.written()), doing, then)
            base = self._open_base()
            with open(self._temporary, "r+b") as target:
                if not self.cloned:
                    _copy(base, target, self._overlay.base_end)
                size = self._overlay.size
                target.truncate(size)
                for number in sorted(self._overlay.pages):
                    start = number * PAGE
                    if start < size:
                        target.seek(start)
                        target.write(self._overlay.pages[number][:size - start])
                target.flush()
                os.fsync(target.fileno())
            os.chmod(self._temporary, os.fstat(base.fileno()).st_mode & 0o777)
            base.close()  # (a file open elsewhere cannot be replaced on every system)
            self._base = None
            os.replace(self._temporary, self.path)
            self._temporary = None
            _sync_folder(folder)
        self.discard()

    def discard(self) -> None:
        """Drop the new version (nothing of it stays on disk); the original is unchanged."""
        store = getattr(self, "store", None)
        if store is not None:
            with contextlib.suppress(Exception):
                store.close()
        if self._temporary is not None:
            self._temporary.unlink(missing_ok=True)
            self._temporary = None
        if self._base is not None:
            self._base.close()
            self._base = None
        self._overlay.pages.clear()

    def __enter__(self) -> Revision:
        return self

    def __exit__(self, *exc: object) -> None:
        self.discard()


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Remove new versions of ``path`` a killed evaluation left beside it (the folder is
    owned by this process: no other one writes them now)."""
    removed = []
    for candidate in path.parent.glob(f".{path.name}.*{TEMPORARY_SUFFIX}"):
        with contextlib.suppress(OSError):
            candidate.unlink()
            removed.append(candidate)
    return removed


def _clone(source: int, target: int) -> bool:
    """Make ``target`` share the extents of ``source`` (Linux ``FICLONE``: btrfs, XFS, …);
    False where the file system or the system cannot."""
    try:
        import fcntl
    except ImportError:
        return False
    try:
        fcntl.ioctl(target, _FICLONE, source)
    except OSError:
        return False
    return True


def _copy(source: IO[bytes], target: IO[bytes], size: int) -> None:
    """Copy the first ``size`` bytes in the kernel where it can (``copy_file_range``, which
    also clones or copies on the server where the file system can), else through user space."""
    offset = 0
    copy_range = getattr(os, "copy_file_range", None)
    if copy_range is not None:
        try:
            while offset < size:
                copied = copy_range(source.fileno(), target.fileno(), size - offset, offset,
                                    offset)
                if copied == 0:
                    break
                offset += copied
        except OSError as failure:
            if failure.errno not in (errno.EXDEV, errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP,
                                     errno.ENOTSUP, errno.EBADF):
                raise
    source.seek(offset)
    target.seek(offset)
    remaining = size - offset
    while remaining > 0:
        block = source.read(min(remaining, 1 << 20))
        if not block:
            break
        target.write(block)
        remaining -= len(block)


def _sync_folder(folder: Path) -> None:
    """Make the rename durable (where a folder can be opened and synced)."""
    with contextlib.suppress(OSError):
        handle = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(handle)
        finally:
            os.close(handle)
