"""Design sweeps on Dask: designs per minute on a local cluster of two workers against one
worker (the baseline, same run, same designs), the cost of one design, and each worker's
peak memory.

The designs: a Latin hypercube of α1, α2 and δ around the Agile Wrist, each built on the
paper's 2° grid (97,336 nodes) with its region P and figures of merit. Rates count from the
first task sent (the cluster up, its workers' imports done, as a sweep does before it sends
anything) to the last row written.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from benchmarks.common import Row
from spm_console.design.spec import load_spec
from spm_console.design.sweep import SweepOutcome, SweepProgress, allowed_cores, run_sweep

ROOT = Path(__file__).resolve().parent.parent
PROFILE = ROOT / "profiles" / "agile_wrist.toml"
DESIGNS = 24

SPEC = f"""
[sweep]
base_profile = "{PROFILE}"
sampling = "lhs"
samples = {DESIGNS}
seed = 7

[parameters.alpha1_deg]
min = 75.0
max = 100.0

[parameters.alpha2_deg]
min = 80.0
max = 100.0

[parameters.delta_mm]
min = 10.0
max = 16.0
"""


def _sweep(spec_path: Path, folder: Path, workers: int) -> tuple[SweepOutcome, float]:
    """The sweep's outcome and its designs per minute."""
    last: list[SweepProgress] = []
    out = run_sweep(load_spec(spec_path), folder, workers=workers, progress=last.append)
    p = last[-1]
    return out, 60.0 * p.computed / p.elapsed_s


def run() -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "spec.toml"
        spec.write_text(SPEC)
        _, rate1 = _sweep(spec, Path(tmp) / "one", 1)
        two, rate2 = _sweep(spec, Path(tmp) / "two", 2)
    cores = allowed_cores()
    per_design = 60.0 / rate1
    peak = max(two.worker_peak_rss_mb.values())
    return [
        Row(f"design: {DESIGNS} designs (2° grid), 2 workers", 60.0 / rate2, "s/design",
            target="≥ 1.7× one worker's rate", baseline=60.0 / rate1, passed=rate2 >= 1.7 * rate1,
            note=f"{rate2:.1f} designs/min on 2 workers, {rate1:.1f} on 1 (the baseline: same "
                 f"designs, same run); the ratio is the speed-up, on {cores} allowed cores; "
                 f"{two.failed} designs could not be built"),
        Row("design: one design (2° grid), 1 worker", per_design, "s", target="≤ 1 s",
            passed=per_design <= 1.0,
            note="grid (Algorithm 2), P (eq. 30) and the figures of merit; the cost a "
                 "sweep of N designs multiplies"),
        Row("design: peak memory per worker", peak, "MB", target="≤ 1024 MB",
            passed=peak <= 1024.0,
            note="largest resident set of the two workers (ru_maxrss) after the sweep"),
    ]
