"""Regenerate ``fk_hard_cases.csv``: grid nodes where the paper's fixed-seed solve
(Algorithm 1, ``core.modes.seeded_solve`` from the profile's sign seed) fails or lands
in another assembly mode, while continuation (the workspace flood fill) gives the
home-connected solution. Run from the project root:

    .venv/bin/python tests/data/make_fk_hard_cases.py
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from spm_console.config.load import load_profile  # noqa: E402
from spm_console.config.models import grid_spec, model_of  # noqa: E402
from spm_console.core.kinematics.model import platform_axes  # noqa: E402
from spm_console.core.kinematics.modes import seeded_solve  # noqa: E402
from spm_console.core.workspace.build import build_grid  # noqa: E402

MAX_ROWS = 200


def main() -> None:
    prof = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    model = model_of(prof)
    ws = build_grid(grid_spec(prof))
    x0 = np.asarray(prof.home.sign_seed, float)
    th = ws.theta_deg()
    V = platform_axes(ws.R, model.v_home)
    rows = []
    for i in map(tuple, np.argwhere(ws.reached)):
        vs, ok = seeded_solve(model.geom, np.radians(th[i]), x0)
        diff = float(np.abs(vs - V[i]).max())
        if not ok or diff > 1e-6:
            rows.append((i, ok, diff, vs))
    if len(rows) > MAX_ROWS:  # keep a spread
        keep = np.linspace(0, len(rows) - 1, MAX_ROWS).round().astype(int)
        rows = [rows[k] for k in keep]
    out = Path(__file__).with_name("fk_hard_cases.csv")
    with out.open("w", newline="") as f:
        f.write(f"# {len(rows)} Agile Wrist grid nodes (2 deg grid) where seeded_solve from the\n")
        f.write("# sign seed disagrees with the continuation (home-connected) solution.\n")
        f.write("# v_* = continuation v (rows v1..v3); seeded_* = what the seeded solve returned.\n")
        w = csv.writer(f)
        w.writerow(["theta1_deg", "theta2_deg", "theta3_deg", "zeta", "node_class",
                    *[f"v{r}{c}" for r in range(1, 4) for c in "xyz"], "seeded_converged",
                    "seeded_outcome", "seeded_max_diff",
                    *[f"seeded_v{r}{c}" for r in range(1, 4) for c in "xyz"]])
        for i, ok, diff, vs in rows:
            outcome = "other_mode" if ok else "failed"
            w.writerow([*(f"{x:g}" for x in th[i]), f"{float(ws.zeta[i]):.6f}",
                        int(ws.klass[i]), *(f"{x:.17g}" for x in V[i].ravel()), int(ok),
                        outcome, f"{diff:.3e}", *(f"{x:.17g}" for x in vs.ravel())])
    print(f"wrote {out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
