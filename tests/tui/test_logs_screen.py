"""Step 6: browse run logs written by the run-log writer, including a killed run."""

from __future__ import annotations

import numpy as np
from textual.widgets import DataTable

from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (130, 40)


def _sample(k: int) -> Sample:
    th = np.full(3, 100.0 + k)
    return Sample(t=k * 0.02, k=k, phase="plan", reference_deg=th, measured_deg=th - 0.1,
                  predicted_deg=th, predicted_velocity_degps=np.full(3, 50.0),
                  filtered_deg=th, velocity_degps=np.full(3, 49.0),
                  fd_velocity_degps=np.full(3, 48.0), tracking_error_deg=0.1, bus_s=1e-3,
                  late_s=1e-4)


async def test_no_runs_says_what_to_do(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        assert "no runs logged yet" in status_of(app)


async def test_lists_runs_newest_first_and_plots_one(console, tmp_path) -> None:
    done = RunLog.create("execute", "agile_wrist", "h", [{"kind": "mvn"}], root=tmp_path / "logs")
    for k in range(20):
        done.sample(_sample(k))
    done.event("stop", 0.38, kind="estop", message="operator [SPACE] E-stop")
    done.finish("stopped", 20, "E-stop [operator]", {})
    killed = RunLog.create("execute", "agile_wrist", "h", [], root=tmp_path / "logs")
    for k in range(5):
        killed.sample(_sample(k))
    killed.flush()  # the writer dies here: outcome stays "running"
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        table = app.screen.query_one("#runs", DataTable)
        assert table.row_count == 2
        assert table.get_row_at(0)[0] == killed.path.name  # newest first
        assert table.get_row_at(1)[2] == "stopped"
        await pilot.press("down", "enter")
        await settle(pilot)
        out = text_of(app, "#run-text")
        assert "outcome stopped (exit code 20): E-stop [operator]" in out  # brackets literal
        assert "estop" in out or "operator [SPACE] E-stop" in out
        assert "20 samples" in out
        plot = str(app.screen.query_one("#run-plot").render())
        assert "joint 1: positions" in plot
        await pilot.press("p", "p")
        assert "tracking error" in str(app.screen.query_one("#run-plot").render())
