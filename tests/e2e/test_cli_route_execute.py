"""A plan across regions of the cover, planned by the CLI and executed on the emulated bus."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.mark.slow
def test_a_plan_across_regions_is_planned_by_the_cli_and_executes_on_the_emulated_bus(
        tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """CLI ``plan mvn`` across regions, then ``execute --sim`` (homes, approaches, runs):
    the runtime verifies it against the workspace itself and the wrist reaches the goal."""
    import json

    from spm_console.cli.main import main
    from spm_console.motion.logs.runlog import load_run

    start, goal = ["121", "65", "87"], ["139", "67", "107"]
    out = tmp_path / "route.json"
    assert main(["plan", "mvn", "--start", *start, "--goal", *goal, "--steps", "250",
                 "--out", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["region_kind"] == "route" and len(d["route"]["switch_samples"]) >= 1
    code = main(["execute", "--plan", str(out), "--sim", "--json", "--logs", str(tmp_path / "logs"),
                 "--skip-homing", "route test", "--sim-start", *start])
    r = json.loads(capsys.readouterr().out)
    assert code == 0 and r["outcome"] == "completed"
    np.testing.assert_allclose(r["final_deg"], [float(x) for x in goal], atol=0.15)
    run = load_run(r["log_dir"])
    assert any(e["event"] == "plan_verified" for e in run.events)
