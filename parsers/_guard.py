"""Guards around third-party log readers (pymavlink, pyulog, mcap): they print, and on damaged
files some of them loop.

* :func:`captured_output` takes everything written to stdout and stderr while a reader runs,
  at the Python level (``print``) AND at the file-descriptor level (pymavlink's compiled
  DataFlash indexer writes one "bad header" line per damaged byte straight to fd 2). The text
  is kept as data, so the terminal stays quiet and the lines can be counted. File descriptors are
  process-wide: a lock serialises captures between threads (other threads' prints during a
  capture land in the captured text, never lost in a traceback).
* :class:`BoundedReader` wraps a binary file handle and raises :class:`ReaderLoopError` once
  more than ``limit_bytes`` have been read through it, or when ``read`` is called many times
  without the position ever passing its previous maximum: a pure progress check, independent
  of time, threads and signals (pyulog can seek back and re-read the same bytes forever on a
  damaged ULog).
"""
from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
import threading

__all__ = ["captured_output", "Captured", "BoundedReader", "ReaderLoopError"]

_LOCK = threading.RLock()


class ReaderLoopError(RuntimeError):
    """A third-party reader stopped making progress through the file (a loop on damage)."""


class Captured:
    """What a guarded call wrote to stdout / stderr (filled when the ``with`` block exits)."""

    def __init__(self):
        self.text = ""

    @property
    def lines(self) -> list[str]:
        return [ln for ln in self.text.splitlines() if ln.strip()]


@contextlib.contextmanager
def captured_output():
    """``with captured_output() as cap: ...``; afterwards ``cap.lines`` holds the output."""
    cap = Captured()
    with _LOCK:
        py_buf = io.StringIO()
        saved = []
        tmp = tempfile.TemporaryFile(mode="w+b")
        try:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except (AttributeError, ValueError, OSError):
                    pass
            for fd in (1, 2):
                try:
                    saved.append((fd, os.dup(fd)))
                    os.dup2(tmp.fileno(), fd)
                except OSError:      # no such descriptor (embedded interpreters): Python level only
                    pass
            with contextlib.redirect_stdout(py_buf), contextlib.redirect_stderr(py_buf):
                yield cap
        finally:
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            tmp.seek(0)
            native = tmp.read().decode("utf-8", "replace")
            tmp.close()
            cap.text = py_buf.getvalue() + native


class BoundedReader(io.RawIOBase):
    """A read-only file wrapper that refuses to read more than ``limit_bytes`` in total, or to
    call ``read`` more than ``max_stalled_reads`` times in a row without passing the furthest
    position reached so far (see the module doc)."""

    def __init__(self, raw, limit_bytes: int, max_stalled_reads: int = 1_000_000):
        super().__init__()
        self._f = raw
        self.limit_bytes = int(limit_bytes)
        self.max_stalled_reads = int(max_stalled_reads)
        self.bytes_read = 0
        self._furthest = 0
        self._stalled = 0

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def read(self, n: int = -1) -> bytes:
        data = self._f.read(n)
        self.bytes_read += len(data)
        pos = self._f.tell()
        if pos > self._furthest:
            self._furthest = pos
            self._stalled = 0
        else:
            self._stalled += 1
        if self.bytes_read > self.limit_bytes or self._stalled > self.max_stalled_reads:
            raise ReaderLoopError(
                f"read {self.bytes_read} bytes (budget {self.limit_bytes}) "
                f"without getting past byte {self._furthest}")
        return data

    def readinto(self, b) -> int:
        data = self.read(len(b))
        b[:len(data)] = data
        return len(data)

    def seek(self, offset: int, whence: int = 0) -> int:
        return self._f.seek(offset, whence)

    def tell(self) -> int:
        return self._f.tell()

    def close(self) -> None:
        self._f.close()
        super().close()
