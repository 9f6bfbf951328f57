"""Benchmark rows and the table printer."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class Row:
    """One measured quantity with its target and the same-run baseline."""

    name: str
    value: float
    unit: str
    target: str = ""
    baseline: float | None = None
    passed: bool | None = None
    note: str = ""

    @property
    def ratio(self) -> float | None:
        if self.baseline is None or self.value == 0:
            return None
        return self.baseline / self.value


def timeit(fn: Callable[[], object], repeat: int = 3) -> float:
    """Best wall time of ``repeat`` calls, seconds."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def print_table(rows: list[Row]) -> None:
    head = f"{'benchmark':44} {'ours':>12} {'baseline':>12} {'ratio':>8}  {'target':24} ok"
    print(head)
    print("-" * len(head))
    for r in rows:
        base = f"{r.baseline:.4g}" if r.baseline is not None else "-"
        ratio = f"{r.ratio:.1f}x" if r.ratio is not None else "-"
        ok = {True: "yes", False: "NO", None: ""}[r.passed]
        print(f"{r.name:44} {r.value:>10.4g} {r.unit:<1} {base:>12} {ratio:>8}  {r.target:24} {ok}")
        if r.note:
            print(f"    {r.note}")
