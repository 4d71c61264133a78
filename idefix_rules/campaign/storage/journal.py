"""An undo journal for the few writes of the simulation that change the structure of
``results.h5`` (a path's run datasets created, a block of rows allocated, rows marked not
needed).

HDF5 changes a file's structure in place: a chunk index node split, a parent node rewritten,
new nodes written elsewhere. Cut off between those writes (a kill, a full disk) it can leave
an index pointing at nodes that were never written, and with it runs stored long before. The
simulation's HDF5 therefore makes such a change through a :class:`JournaledFile`: from
:meth:`JournaledFile.begin` on, the old bytes of every page about to be overwritten are
appended to ``.results.h5.undo`` first; the journal is deleted once the change is complete on
disk. Whoever opens the file to write it next (``--resume``, an evaluation) calls
:func:`roll_back`, which puts those pages back and cuts the file to its old size: the file is
again exactly what it was before the change began, every run stored before it included. A
full disk met inside such a change is not passed to HDF5 (which could not close the file
cleanly after it): the writes go on in memory, the change is rolled back and
:attr:`JournaledFile.failure` says why.

Outside a journaled change the file is read and written as is: writing a run replaces its own
chunks and index entries in place (``store.py``); a kill in the middle leaves at most that
run's entries pointing past the end the superblock records, which :func:`repair_end` fixes
before the file is written again (the run itself is not marked complete and is run again).
"""

from __future__ import annotations

import contextlib
import io
import os
import struct
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer, WriteableBuffer

PAGE = 4096
MAGIC = b"IDEFIX-UNDO 1\n"
_HEADER = struct.Struct("<Q")  # the file's size when the change began
_RECORD = struct.Struct("<QI")  # offset and length of the old bytes that follow


def undo_path(path: Path) -> Path:
    """The undo journal of the results file ``path``."""
    return path.with_name(f".{path.name}.undo")


class JournaledFile(io.RawIOBase):
    """The results file as the simulation's HDF5 reads and writes it (h5py's ``fileobj``
    driver)."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = Path(path)
        self._fd = os.open(self.path, os.O_RDWR)
        self.position = 0
        self._undo: int | None = None
        self._base = 0
        self._saved: set[int] = set()
        # After a failed write inside a change: the pages written since, kept in memory.
        self._memory: dict[int, bytearray] | None = None
        self.failure: OSError | None = None

    # --- the file as HDF5 sees it ---------------------------------------------------------

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        start = {os.SEEK_SET: 0, os.SEEK_CUR: self.position, os.SEEK_END: self._size()}[whence]
        self.position = start + offset
        return self.position

    def tell(self) -> int:
        return self.position

    def _size(self) -> int:
        size = os.fstat(self._fd).st_size
        if self._memory:
            size = max(size, max(self._memory) * PAGE + PAGE)
        return size

    def readinto(self, buffer: WriteableBuffer) -> int:
        view = memoryview(buffer).cast("B")
        done = 0
        while done < len(view):
            data = os.pread(self._fd, len(view) - done, self.position + done)
            if not data:
                break
            view[done:done + len(data)] = data
            done += len(data)
        if self._memory:
            view[done:] = bytes(len(view) - done)
            self._overlay(view, self.position)
            done = len(view)
        self.position += done
        return done

    def _overlay(self, view: memoryview, offset: int) -> None:
        assert self._memory is not None
        end = offset + len(view)
        for number in range(offset // PAGE, (end - 1) // PAGE + 1):
            page = self._memory.get(number)
            if page is None:
                continue
            start = max(offset, number * PAGE)
            stop = min(end, number * PAGE + PAGE)
            view[start - offset:stop - offset] = page[start - number * PAGE:stop - number * PAGE]

    def write(self, data: ReadableBuffer) -> int:
        view = memoryview(data).cast("B")
        if self._memory is None:
            try:
                if self._undo is not None:
                    self._save(self.position, len(view))
                _write_at(self._fd, view, self.position)
            except OSError as failure:
                if self._undo is None:
                    raise  # outside a change: HDF5 reports it (a run not stored)
                self.failure = failure
                self._memory = {}
        if self._memory is not None:
            self._remember(view, self.position)
        self.position += len(view)
        return len(view)

    def _remember(self, view: memoryview, offset: int) -> None:
        assert self._memory is not None
        end = offset + len(view)
        for number in range(offset // PAGE, (end - 1) // PAGE + 1):
            page = self._memory.get(number)
            if page is None:
                page = bytearray(os.pread(self._fd, PAGE, number * PAGE).ljust(PAGE, b"\0"))
                self._memory[number] = page
            start = max(offset, number * PAGE)
            stop = min(end, number * PAGE + PAGE)
            page[start - number * PAGE:stop - number * PAGE] = view[start - offset:stop - offset]

    def truncate(self, size: int | None = None) -> int:
        size = self.position if size is None else size
        if self._memory is not None:
            return size  # the change is rolled back anyway
        if self._undo is not None and size < self._base:
            self._save(size, self._base - size)
        os.ftruncate(self._fd, size)
        return size

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
        if self._undo is not None:
            os.close(self._undo)
            self._undo = None
        super().close()

    # --- the journal ----------------------------------------------------------------------

    def _save(self, offset: int, count: int) -> None:
        """Append the old bytes of the pages ``offset … offset + count`` below the size the
        file had when the change began (each page once) to the undo journal."""
        assert self._undo is not None
        end = min(offset + count, self._base)
        for number in range(offset // PAGE, (end - 1) // PAGE + 1 if end > offset else 0):
            if number in self._saved:
                continue
            old = os.pread(self._fd, min(PAGE, self._base - number * PAGE), number * PAGE)
            _write_all(self._undo, _RECORD.pack(number * PAGE, len(old)) + old)
            self._saved.add(number)

    def begin(self) -> None:
        """Start a change: from now on every page overwritten is saved first."""
        undo = os.open(undo_path(self.path), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._base = os.fstat(self._fd).st_size
        self._saved = set()
        self.failure = None
        try:
            _write_all(undo, MAGIC + _HEADER.pack(self._base))
        except BaseException:
            os.close(undo)
            undo_path(self.path).unlink(missing_ok=True)
            raise
        self._undo = undo

    def discard(self) -> None:
        """Keep every further write in memory (the change is being abandoned)."""
        if self._memory is None:
            self._memory = {}


def roll_back(path: Path, journal: Path | None = None) -> bool:
    """Undo a change of ``path`` that was cut off (its journal, ``journal`` or the one of
    ``path``, is still there): the file is again what it was before the change began. True
    when there was one."""
    undo = journal if journal is not None else undo_path(Path(path))
    try:
        data = undo.read_bytes()
    except FileNotFoundError:
        return False
    start = len(MAGIC) + _HEADER.size
    if data.startswith(MAGIC) and len(data) >= start:
        (base,) = _HEADER.unpack_from(data, len(MAGIC))
        records = []
        offset = start
        while offset + _RECORD.size <= len(data):
            where, length = _RECORD.unpack_from(data, offset)
            offset += _RECORD.size
            if offset + length > len(data):
                break  # cut off while being saved: its page was not written yet
            records.append((where, data[offset:offset + length]))
            offset += length
        try:
            handle = os.open(path, os.O_RDWR)
        except FileNotFoundError:  # the file it was kept for is gone
            undo.unlink(missing_ok=True)
            return False
        try:
            for where, old in records:
                _write_all(handle, old, where)
            os.ftruncate(handle, base)
            os.fsync(handle)
        finally:
            os.close(handle)
    # a journal without its header was cut off before the change wrote anything
    with contextlib.suppress(FileNotFoundError):
        undo.unlink()
    return True


# HDF5 superblocks version 0 and 1 (what h5py writes by default) with 8-byte addresses: the
# offset of their end-of-allocation address (no checksum to update).
_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_END_OF_ALLOCATION = {0: 40, 1: 44}


def stale_end(header: bytes, size: int) -> int | None:
    """Where the end-of-allocation address of a file beginning with ``header`` (its first 64
    bytes) is stored, when it lies below the file's ``size``; else None.

    HDF5 writes a file's index nodes before its superblock: a writer killed in between leaves
    nodes pointing at space (the run it was writing) beyond the end the superblock records,
    and HDF5 would allocate that space again. Raising the end to the file's size makes it
    count as used (what ``h5clear --increment`` does)."""
    if not header.startswith(_SIGNATURE) or len(header) < 52 or header[13] != 8:
        return None
    offset = _END_OF_ALLOCATION.get(header[8])
    if offset is None:
        return None
    (end,) = struct.unpack_from("<Q", header, offset)
    return offset if end < size else None


def repair_end(path: Path) -> bool:
    """Raise the end of allocation recorded in ``path`` to its size (:func:`stale_end`).
    True when it was below."""
    with open(path, "r+b") as handle:
        offset = stale_end(handle.read(64), os.fstat(handle.fileno()).st_size)
        if offset is None:
            return False
        handle.seek(offset)
        handle.write(struct.pack("<Q", os.fstat(handle.fileno()).st_size))
        handle.flush()
        os.fsync(handle.fileno())
    return True


def _write_at(handle: int, view: memoryview, offset: int) -> None:
    """Write what HDF5 writes (a full disk raises here)."""
    written = 0
    while written < len(view):
        written += os.pwrite(handle, view[written:], offset + written)


def _write_all(handle: int, data: bytes | bytearray | memoryview, offset: int | None = None
               ) -> None:
    view = memoryview(data)
    while view:
        written = os.write(handle, view) if offset is None else os.pwrite(handle, view, offset)
        view = view[written:]
        if offset is not None:
            offset += written
