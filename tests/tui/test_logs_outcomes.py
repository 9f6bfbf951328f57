"""Step 6 explains each run: outcome, exit code, stop reason (E-stop vs communication lost),
duration, plan and its ends; a filter by outcome; the log root actually in use."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from textual.widgets import DataTable

from spm_console.config.schema import Profile
from spm_console.motion.logs.runlog import LOGS_ENV
from spm_console.tui.app import make_app
from tests.support.console_helpers import settle, status_of, text_of
from tests.support.runlog_helpers import write_run

SIZE = (160, 40)


def _runs(root: Path) -> dict[str, str]:
    """Four runs, oldest first: completed, E-stop, communication lost, killed; name by role."""
    return {
        "completed": write_run(root, "completed", 0, "executed 20 cycles (0.40 s)").path.name,
        "estop": write_run(root, "stopped", 20, "E-stop: operator E-stop (SPACE)",
                           "estop").path.name,
        "comm": write_run(root, "stopped", 22, "communication lost: 3 consecutive bus cycles "
                          "without a valid reply", "comm").path.name,
        "killed": write_run(root, "killed").path.name,
    }


def _rows(app) -> dict[str, list[str]]:  # type: ignore[no-untyped-def]
    table = app.screen.query_one("#runs", DataTable)
    labels = [str(c.label) for c in table.columns.values()]
    rows = [[str(c) for c in table.get_row_at(i)] for i in range(table.row_count)]
    return {r[0]: dict(zip(labels, r, strict=True)) for r in rows}  # type: ignore[misc]


async def test_stopped_runs_say_e_stop_or_communication_lost_with_exit_codes(
        console, tmp_path) -> None:
    names = _runs(tmp_path / "logs")
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        table = app.screen.query_one("#runs", DataTable)
        assert [str(table.get_row_at(i)[0]) for i in range(4)] == [
            names["killed"], names["comm"], names["estop"], names["completed"]]  # newest first
        rows = _rows(app)
        estop, comm = rows[names["estop"]], rows[names["comm"]]
        assert (estop["outcome"], estop["exit"], estop["reason"]) == ("stopped", "20", "E-stop")
        assert (comm["outcome"], comm["exit"], comm["reason"]) == (
            "stopped", "22", "communication lost")
        done, killed = rows[names["completed"]], rows[names["killed"]]
        assert (done["outcome"], done["exit"], done["reason"]) == ("completed", "0", "")
        assert (killed["outcome"], killed["exit"], killed["loop"]) == ("killed", "", "–")
        assert done["plan"] == "mvn" and done["loop"].endswith(" s")

        await pilot.press("down", "enter")  # the communication loss
        await settle(pilot)
        out = text_of(app, "#run-text")
        assert "outcome stopped (exit code 22): communication lost: 3 consecutive" in out
        assert "stop reason: communication lost" in out and "E-stop" not in out
        assert "plan: MVN [135.00, 135.00, 135.00]° → [95.00, 110.00, 105.00]°, 1.00 s" in out
        assert "(after an approach move)" in out
        assert "servo loop 0.40 s (20 cycles)" in out and "wall time " in out

        await pilot.press("down", "enter")  # the E-stop
        await settle(pilot)
        out = text_of(app, "#run-text")
        assert "outcome stopped (exit code 20): E-stop: operator E-stop (SPACE)" in out
        assert "stop reason: E-stop" in out and "communication" not in out


async def test_the_filter_lists_one_outcome_at_a_time(console, tmp_path) -> None:
    names = _runs(tmp_path / "logs")
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        assert len(_rows(app)) == 4 and "all outcomes: 4 of 4 runs" in text_of(app, "#logs-head")
        seen = {}
        for _ in range(5):  # completed, stopped, refused, killed, error
            await pilot.press("f")
            await settle(pilot)
            which = app.screen.outcome_filter
            seen[which] = set(_rows(app))
            assert f"outcome {which}: {len(seen[which])} of 4 runs" in text_of(app, "#logs-head")
            assert {r["outcome"] for r in _rows(app).values()} <= {which}
        assert seen == {"completed": {names["completed"]},
                        "stopped": {names["estop"], names["comm"]},
                        "refused": set(), "killed": {names["killed"]}, "error": set()}
        assert "no error run among 4" in status_of(app)
        await pilot.press("f")  # back to all
        await settle(pilot)
        assert app.screen.outcome_filter == "all" and len(_rows(app)) == 4
        await pilot.press("f", "f")  # stopped: Enter opens the listed run, not a hidden one
        await settle(pilot)
        await pilot.press("enter")
        await settle(pilot)
        assert app.screen.run is not None and app.screen.run.path.name == names["comm"]
        await pilot.press("f")  # refused: none listed, and the opened run is not shown either
        await settle(pilot)
        assert app.screen.run is None and names["comm"] in text_of(app, "#run-text")
        assert "is not listed now" in text_of(app, "#run-text")


async def test_the_configured_log_root_is_shown(console, tmp_path) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        root = str((tmp_path / "logs").absolute())
        assert f"logs in {root} " in text_of(app, "#logs-head")
        assert root in status_of(app)


async def test_the_environment_log_root_is_shown(agile: Profile, ws_cache: Path, tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """No --logs: $SPM_CONSOLE_LOGS is where the runs are, and what the screen names."""
    elsewhere = tmp_path / "elsewhere"
    monkeypatch.setenv(LOGS_ENV, str(elsewhere))
    write_run(elsewhere, "completed", 0, "done")
    app = make_app(agile, sim=True, viewer=False, cache_dir=ws_cache)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        head = text_of(app, "#logs-head")
        assert f"logs in {elsewhere.absolute()} " in head and "1 of 1 runs" in head
        assert len(_rows(app)) == 1


async def test_a_refused_run_shows_its_reason(console, tmp_path) -> None:
    """A refusal logged by the runtime (homing from a pose home cannot be reached from):
    its reason in the table's reason column (cut to the column, at a word) and in full
    when the run is opened."""
    from spm_console.motion.logs.runlog import list_runs
    from spm_console.tui.screens.logs import REASON_CHARS

    app = console(initial_deg=(62.0, 158.0, 62.0))
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("h", "y")
        await settle(pilot)
        [run] = list_runs(tmp_path / "logs")
        assert run.meta["outcome"] == "refused"
        message = run.meta["message"]
        assert len(message) > REASON_CHARS  # long enough to be cut in the table
        await pilot.press("6")
        await settle(pilot)
        row = _rows(app)[run.path.name]
        assert row["outcome"] == "refused" and row["exit"] == str(run.meta["exit_code"])
        reason = row["reason"]
        assert reason.endswith("…") and len(reason) <= REASON_CHARS
        assert message.startswith(reason[:-1]) and len(reason) > REASON_CHARS // 2
        # the line above the table names the whole reason, wrapped, whatever the width
        assert message in " ".join(text_of(app, "#run-line").split())
        await pilot.press("enter")
        await settle(pilot)
        assert message in " ".join(text_of(app, "#run-text").split())


async def test_at_80_columns_the_highlighted_run_shows_outcome_exit_reason_duration_plan(
        console, tmp_path) -> None:
    """80×24: the table shows only its first columns; the line above it names the highlighted
    run's outcome, exit code, stop reason, duration and plan kind, and follows the cursor."""
    names = _runs(tmp_path / "logs")
    app = console()
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        line = app.screen.query_one("#run-line")
        assert line.region.right <= 80 and line.region.bottom <= 24  # on screen, no scrolling
        assert text_of(app, "#run-line").startswith("▸ killed · exit –")  # newest first
        await pilot.press("down")  # the communication loss
        rows = _rows(app)
        comm = rows[names["comm"]]
        want = f"▸ stopped · exit 22 · communication lost · servo loop {comm['loop']} · plan mvn"
        assert text_of(app, "#run-line") == want
        assert app.screen.query_one("#runs").region.width >= 72  # the table: all the width


async def test_at_80x24_an_opened_run_scrolls_to_its_plot_by_keyboard(console) -> None:
    """80×24: the opened run's text and plot do not fit under the table; tab moves to them
    and End scrolls to the plot's bottom, tab again goes back to the runs. The logs folder has
    a path of fixed length: its path is shown, and a long one (pytest's temporary folders
    differ in length between machines, users and parallel workers) wraps to one more line."""
    logs = Path(tempfile.mkdtemp(prefix="spm-logs-", dir="/tmp"))
    try:
        await _scrolls_to_its_plot(console, logs)
    finally:
        shutil.rmtree(logs, ignore_errors=True)


async def _scrolls_to_its_plot(console, logs: Path) -> None:  # type: ignore[no-untyped-def]
    _runs(logs)
    app = console(logs_root=logs)
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        await pilot.press("enter")
        await settle(pilot)
        detail = app.screen.query_one("#run-detail")
        plot = app.screen.query_one("#run-plot")
        assert detail.max_scroll_y > 0  # the case: more than fits
        await pilot.press("tab")
        assert app.focused is detail
        await pilot.press("end")
        await pilot.pause(0.2)
        assert detail.scroll_y == detail.max_scroll_y
        visible = plot.region.intersection(detail.region)
        assert visible.height >= 8 and plot.region.bottom <= 24, (plot.region, detail.region)
        await pilot.press("tab")
        assert app.focused is app.screen.query_one("#runs")
