"""Report section: workspace (Algorithm 2), region P (Fig. 5) and its exact verification."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.workspace.verify import verify_region
from spm_console.report import paper_values as pv
from spm_console.report.plot_workspace import plot_workspace
from spm_console.report.repro_types import Check, ReproSettings, Section
from spm_console.store.workspace_cache import load_or_build


def workspace_sections(profile: Profile, out: Path, settings: ReproSettings) -> list[Section]:
    t0 = time.perf_counter()
    sec = Section("Workspace and convex region P (Sec. IV, VI-D, Fig. 5)", "workspace")
    # a throw-away cache: the build is timed from scratch, honestly
    with tempfile.TemporaryDirectory(prefix="spm-repro-") as tmp:
        ws, info = load_or_build(profile, cache_dir=tmp, force=True)
    counts = ws.counts()
    n = settings.verify_samples if not settings.quick else min(settings.verify_samples, 5_000)
    rep = verify_region(ws, model_of(profile), link_model_of(profile), n=n)
    sec.checks += [
        Check("grid nodes (65–155°, Δ = 2°)", "46³ = 97,336", f"{counts['nodes']:,}", None, None),
        Check("feasible / singular / colliding nodes", "not printed",
              f"{counts['feasible']:,} / {counts['singular']:,} / {counts['colliding']:,}", None, None),
        Check("half-spaces of P", str(pv.REGION_HALFSPACES), str(ws.region.halfspaces), None, None,
              explained="link dimensions OA…OF are not printed; ours are documented assumptions, "
              "and our P is built by IRIS with redundant planes removed"),
        Check("feasible nodes inside P", "not printed", f"{100 * ws.coverage():.1f} %", None, None),
        Check(f"verifier: {rep.samples:,} uniform samples of P checked exactly", "no collision in trials",
              f"{rep.infeasible} infeasible (min ζ {rep.min_zeta:.3f}, min link distance "
              f"{rep.min_link_mm:.1f} mm)", float(rep.infeasible), 0.0),
        Check("grid + region build time", "not printed",
              f"{info.build_seconds:.2f} s ({ws.region_seconds:.2f} s region)", None, None),
    ]
    fig = "fig5_workspace.png"
    plot_workspace(ws, out / fig, title=f"{profile.name}: feasible nodes and P ({ws.region.halfspaces} half-spaces)")
    sec.figures.append((fig, "Feasible configurations and the convex region P (cf. the paper's Fig. 5)"))
    sec.text = (
        "Every node's FK is tracked from home by flood fill (never a seeded solve per node); a node is "
        f"feasible when ζ ≥ {profile.workspace.zeta_min}, no two links of different legs are closer than "
        f"2δ = {2 * profile.links.delta_mm:.0f} mm, and it is connected to home through feasible nodes. "
        "P contains no infeasible cell (the cube of half-width Δ around each infeasible node), which is "
        "the paper's Minkowski/Pontryagin construction P ⊆ P′. The paper's link dimensions are not "
        "printed, so counts and n_p cannot be compared number for number."
    )
    sec.seconds = time.perf_counter() - t0
    return [sec]
