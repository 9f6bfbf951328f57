"""Run every benchmark module and print one table (target, ours, baseline, ratio).

Each ``benchmarks/bench_*.py`` defines ``run() -> list[Row]``; baselines are
measured in the same run on the same machine. Select modules with arguments:
``python -m benchmarks kinematics workspace``.

A module that raises becomes one failed row carrying its error (the full traceback goes
to stderr), and the run goes on. Exit status: 0 when every row ran and met its target,
1 otherwise.
"""

from __future__ import annotations

import importlib
import platform
import sys
import time
import traceback
from pathlib import Path

from benchmarks.common import Row, print_table


def _run_module(name: str) -> list[Row]:
    """The module's rows, or one failed row naming the error: a failing row never ends the run."""
    try:
        mod = importlib.import_module(f"benchmarks.{name}")
        rows: list[Row] = mod.run()
        return rows
    except Exception as exc:  # a benchmark's failure is its result, reported in the table
        traceback.print_exc(file=sys.stderr)
        return [Row(f"{name}: did not complete", float("nan"), "", "runs to the end", passed=False,
                    note=f"{type(exc).__name__}: {exc}")]


def main(argv: list[str]) -> int:
    here = Path(__file__).parent
    names = sorted(p.stem for p in here.glob("bench_*.py"))
    if argv:
        names = [n for n in names if any(a in n for a in argv)]
    print(f"machine: {platform.machine()} {platform.processor() or ''}, python {platform.python_version()}")
    rows: list[Row] = []
    for name in names:
        t0 = time.perf_counter()
        rows.extend(_run_module(name))
        print(f"[{name}] {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    print_table(rows)
    failed = any(r.passed is False for r in rows)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
