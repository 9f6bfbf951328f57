"""Step 5 while the wrist moves: the servo loop's timing so far, a missing reply shown as
such, the tracking columns named for what they subtract."""

from __future__ import annotations

import asyncio
import math
import re

import numpy as np
import pytest
from textual.widgets import DataTable

from spm_console.motion.stats import run_stats
from spm_console.tui.messages import Telemetry
from spm_console.tui.screens.execute import NO_REPLY
from spm_console.tui.widgets.loop_timing import LiveTiming, LoopTiming
from tests.support.console_helpers import confirm_execute, settle, status_of, text_of
from tests.support.runlog_helpers import TS, sample

pytestmark = pytest.mark.usefixtures("paced_clock")  # acts while the wrist moves

SIZE = (130, 42)


def _labels(table: DataTable[str]) -> list[str]:
    return [" ".join(str(c.label).split()) for c in table.columns.values()]


def test_live_timing_counts_as_the_run_statistics_do() -> None:
    samples = [sample(0), sample(1, jitter_s=0.003), sample(2, retries=2),
               sample(3, ok=False, retries=2, stale=1), sample(4, late_s=1.5 * TS, stale=3),
               sample(5)]
    live = LiveTiming(TS)
    live.add(samples[:2])
    live.add(samples[2:])  # in pieces, as telemetry arrives
    got = live.timing()
    want = LoopTiming.of_run(run_stats(samples, TS))
    assert got.jitter_p99_ms == pytest.approx(want.jitter_p99_ms)
    assert (got.cycles, got.late_cycles, got.read_retries, got.no_reply) == (
        want.cycles, want.late_cycles, want.read_retries, want.no_reply) == (6, 1, 4, 1)
    assert got.stale_replies == 3  # the bus's running count, as of the last sample
    text = got.text()
    assert text.startswith("servo loop, 6 cycles: jitter p99 ")
    assert ("late cycles 1 · read retries 4 · no-reply cycles 1 · stale replies 3") in text
    assert "jitter p99 –" in LiveTiming(TS).timing().text()  # no pair of cycles yet


def test_a_cycle_left_out_of_the_telemetry_breaks_the_jitter_pair() -> None:
    live = LiveTiming(TS)
    live.add([sample(0), sample(1), sample(7)])  # 2..6 never reached the console
    assert live.timing().jitter_p99_ms == pytest.approx(0.0, abs=1e-9)


async def test_the_timing_line_follows_the_telemetry_and_no_reply_shows(console) -> None:
    """Telemetry as the executor's callback delivers it: the kept samples and a message."""
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("5")
        await settle(pilot)
        screen = app.screen
        table = screen.query_one("#joints", DataTable)
        assert _labels(table)[-2:] == ["measured − model", "reference − measured"]
        assert "shown while a plan executes" in text_of(app, "#exec-timing")

        app.live_samples[:] = [sample(k) for k in range(3)]
        screen.post_message(Telemetry(app.live_samples[-1]))
        await pilot.pause()
        first = text_of(app, "#exec-timing")
        assert first.startswith("servo loop, 3 cycles:") and "no-reply cycles 0" in first
        row = [str(c).strip() for c in table.get_row_at(2)]
        assert row[1:3] == ["102.00°", "101.90°"]
        assert row[4:] == ["-0.10°", "+0.10°"]  # measured − model, reference − measured

        app.live_samples.extend([sample(3, retries=2), sample(4, ok=False, retries=2, stale=1)])
        screen.post_message(Telemetry(app.live_samples[-1]))
        await pilot.pause()
        second = text_of(app, "#exec-timing")
        assert second != first and second.startswith("servo loop, 5 cycles:")
        assert "read retries 4 · no-reply cycles 1 · stale replies 1" in second
        for i in range(3):
            row = [str(c).strip() for c in table.get_row_at(i)]
            assert row[2] == NO_REPLY == "no reply"  # never "nan°"
            assert row[4] == row[5] == "–"  # nothing to subtract
            assert row[1].endswith("°") and "nan" not in " ".join(row)


async def test_during_a_real_execution_the_timing_line_updates(console) -> None:
    from spm_console.services.wrist_service import PoseSpec

    app = console()
    seen: list[str] = []

    def hook(message: object) -> None:  # runs on the app's loop, before the screen handles it
        if isinstance(message, Telemetry) and type(app.screen).__name__ == "ExecuteScreen":
            seen.append(text_of(app, "#exec-timing"))

    async with app.run_test(size=SIZE, message_hook=hook) as pilot:
        s = app.session
        await settle(pilot)
        await asyncio.to_thread(s.home)
        await asyncio.to_thread(s.wrist.load_workspace)
        await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("current"),
                                PoseSpec("theta", (95.0, 110.0, 105.0)), s.theta_deg, 100)
        await pilot.press("5")
        await settle(pilot)
        await confirm_execute(pilot)
        await settle(pilot)
        res = s.last_run
        assert res is not None and res.ok, status_of(app)
        counts = [int(m.group(1)) for t in seen if (m := re.match(r"servo loop, (\d+) cycles", t))]
        assert len(set(counts)) >= 2 and counts == sorted(counts), seen  # it moved on, onward
        final = text_of(app, "#exec-timing")
        assert final == LoopTiming.of_run(res.stats).text()  # every cycle, from the loop
        assert final.startswith(f"servo loop, {res.stats.samples} cycles")
        jitter = res.stats.jitter_ms
        assert jitter is not None and math.isfinite(jitter.p99)
        assert text_of(app, "#exec-outcome").startswith("COMPLETED (exit code 0)")
        assert "servo loop: " in text_of(app, "#exec-outcome")  # its scheduling, kept
        measured = [float(str(c).strip().rstrip("°"))
                    for c in app.screen.query_one("#joints", DataTable).get_row_at(0)[2:3]]
        np.testing.assert_allclose(measured, [95.0], atol=1.0)


def test_after_a_run_the_table_shows_the_last_position_read() -> None:
    """A run whose last cycle lost its reply: the table shows where the wrist ended (the last
    sample read), not "no reply" beside the final θ."""
    from spm_console.tui.screens.execute import _last_read

    samples = [sample(0), sample(1), sample(2, ok=False), sample(3, ok=False)]
    assert _last_read(samples) is samples[1]
    assert _last_read(samples[2:]) is samples[3]  # nothing read: the last one
