"""Run every benchmark module and print one table (target, ours, baseline, ratio).

Each ``benchmarks/bench_*.py`` defines ``run() -> list[Row]``; baselines are
measured in the same run on the same machine. Select modules with arguments:
``python -m benchmarks kinematics workspace``.
"""

from __future__ import annotations

import importlib
import platform
import sys
import time
from pathlib import Path

from benchmarks.common import Row, print_table


def main(argv: list[str]) -> int:
    here = Path(__file__).parent
    names = sorted(p.stem for p in here.glob("bench_*.py"))
    if argv:
        names = [n for n in names if any(a in n for a in argv)]
    print(f"machine: {platform.machine()} {platform.processor() or ''}, python {platform.python_version()}")
    rows: list[Row] = []
    failed = False
    for name in names:
        t0 = time.perf_counter()
        mod = importlib.import_module(f"benchmarks.{name}")
        got = mod.run()
        rows.extend(got)
        print(f"[{name}] {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    print_table(rows)
    failed = any(r.passed is False for r in rows)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
