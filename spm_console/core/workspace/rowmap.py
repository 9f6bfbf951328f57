"""How a build runs a row-wise computation: in this process, or split between processes.

A *row-wise* function maps arrays of equal length (rows) to an array, or a tuple of arrays,
of the same length, each output row depending only on the same input rows (the exact checks
of points, the link distances of grid nodes). A :class:`RowMap` may therefore run it on parts
of the rows anywhere and join the parts: the result is the one ``fn(*rows)`` gives. The core
only calls a row map it is given (:func:`serial` by default); a front end may hand it one that
uses another process (``spm_console.system.forked``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, TypeVar

from numpy.typing import NDArray

R = TypeVar("R")


class RowMap(Protocol):
    """Runs a row-wise ``fn`` over ``rows`` and returns what ``fn(*rows)`` returns."""

    def __call__(self, fn: Callable[..., R], *rows: NDArray[Any]) -> R: ...


def serial(fn: Callable[..., R], *rows: NDArray[Any]) -> R:
    """The row map of one process: ``fn(*rows)``."""
    return fn(*rows)
