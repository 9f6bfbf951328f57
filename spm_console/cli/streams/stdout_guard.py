"""With ``--json``, standard output carries the command's JSON object and nothing else.

Libraries print: a solver's banner from C (HiGHS, OSQP), a Python ``print`` in a dependency,
a child process that inherited file descriptor 1. For the command's duration
:func:`json_stdout` points descriptor 1 at standard error, so all of that lands there, and
gives the command a stream of its own on the real standard output (:func:`out`), which only
the JSON is written to. On the way out, C's buffered output is flushed (still to standard
error) before descriptor 1 is put back.

When ``sys.stdout`` is not descriptor 1 (a caller captured it, as tests do), only Python's
``sys.stdout`` is redirected, and the JSON goes to the stream the caller gave.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator
from typing import TextIO

_out: TextIO | None = None
"""The command's own stream while :func:`json_stdout` is active."""


def out() -> TextIO:
    """Where the command's output goes: the guarded stream with ``--json``, else stdout."""
    return _out if _out is not None else sys.stdout


def _flush_c_stdio() -> None:
    """Flush C's stdio buffers (what a C library printed with printf and not yet written)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)


def _fd_of(stream: TextIO) -> int | None:
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):
        return None


@contextlib.contextmanager
def json_stdout(active: bool) -> Iterator[None]:
    """While active: descriptor 1 (and ``sys.stdout``) lead to standard error; :func:`out` is
    the real standard output."""
    global _out
    if not active or _out is not None:
        yield
        return
    given = sys.stdout
    if _fd_of(given) != 1:  # captured by the caller: Python-level redirection only
        _out = given
        sys.stdout = sys.stderr
        try:
            yield
        finally:
            sys.stdout = given
            _out = None
        return
    given.flush()
    _flush_c_stdio()
    saved = os.dup(1)
    os.dup2(2, 1)  # from here, whatever writes to descriptor 1 writes to standard error
    stream = os.fdopen(os.dup(saved), "w", encoding="utf-8", errors="backslashreplace",
                       closefd=True)
    _out = stream
    try:
        yield
    finally:
        _out = None
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
        with contextlib.suppress(OSError, ValueError):
            stream.close()
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
        _flush_c_stdio()
        os.dup2(saved, 1)
        os.close(saved)


def silence() -> None:
    """The guarded stream leads to /dev/null from now on (its reader is gone)."""
    if _out is None:
        return
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, _out.fileno())
        os.close(devnull)
