"""The live jog (issue 15, from step 5): the arrow keys move a target the wrist follows live,
through the runtime's following; esc ends it (the run completes), SPACE stops it."""

from __future__ import annotations

import asyncio
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from textual.pilot import Pilot
from textual.widgets import DataTable

from spm_console.motion.logs.runlog import load_run
from spm_console.tui.app import SpmConsoleApp
from spm_console.tui.screens.execute import ExecuteScreen
from spm_console.tui.screens.help import HelpScreen
from spm_console.tui.screens.jog import JOG_SOURCE, JogScreen
from spm_console.tui.screens.jog_target import JOG_STEPS_DEG, JogTarget, TargetSender
from spm_console.viewer.view import NullView
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (130, 42)
#: The emulated wrist settles on its target within this, deg (the follower's own settle
#: tolerance is 0.2°, plus the emulated encoder's resolution).
SETTLED_DEG = 0.5


async def until(pilot: Pilot[Any], cond: Callable[[], bool], what: str,
                timeout_s: float = 30.0) -> None:
    """Pump the app until ``cond()`` holds (a running following never lets the workers
    settle)."""
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout_s
    while not cond():
        if loop.time() > t_end:
            raise TimeoutError(f"waited in vain for {what}")
        await pilot.pause(0.02)


async def _homed_on_step5(app: SpmConsoleApp, pilot: Pilot[Any]) -> None:
    import time; t=time.perf_counter()
    await settle(pilot)
    print("settle", time.perf_counter()-t); t=time.perf_counter()
    await asyncio.to_thread(app.session.home)
    print("home", time.perf_counter()-t); t=time.perf_counter()
    assert app.session.homed
    await pilot.press("5")
    await settle(pilot)
    print("step5", time.perf_counter()-t); t=time.perf_counter()


async def _start_jog(app: SpmConsoleApp, pilot: Pilot[Any]) -> JogScreen:
    import time; t=time.perf_counter()
    await pilot.press("j")
    await until(pilot, lambda: isinstance(app.screen, JogScreen), "the jog screen")
    print("jogscreen", time.perf_counter()-t); t=time.perf_counter()
    jog = app.screen
    assert isinstance(jog, JogScreen)
    await until(pilot, lambda: jog.phase == "live", "the first cycle of the following")
    print("live", time.perf_counter()-t); t=time.perf_counter()
    assert app.moving
    return jog


async def _ended(app: SpmConsoleApp, pilot: Pilot[Any]) -> None:
    await until(pilot, lambda: isinstance(app.screen, ExecuteScreen) and not app.moving,
                "the end of the jog")
    await settle(pilot)


class ViewSpy(NullView):
    """A 3D view that remembers what it was asked to show."""

    def __init__(self) -> None:
        self.measured: list[Any] = []
        self.ghosts: list[Any] = []

    def show_theta(self, theta_deg: Any) -> None:
        self.measured.append(None if theta_deg is None else np.asarray(theta_deg, float))

    def show_target(self, theta_deg: Any) -> None:
        self.ghosts.append(None if theta_deg is None else np.asarray(theta_deg, float))


def _spy_targets(app: SpmConsoleApp) -> list[np.ndarray]:
    """Record every target the console hands to the runtime."""
    sent: list[np.ndarray] = []
    real = app.session.set_target

    def spy(theta_deg: Any) -> bool:
        sent.append(np.asarray(theta_deg, float).copy())
        return real(theta_deg)

    app.session.set_target = spy  # type: ignore[method-assign]
    return sent


async def test_probe(console) -> None:
    import time; T0=time.perf_counter()
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        print('T', round(time.perf_counter()-T0,2), 'await _homed_on_step5(app, pilot)', flush=True)
        sent = _spy_targets(app)
        view = app.view = ViewSpy()
        home = np.asarray(app.session.profile.home.theta_deg, float)
        jog = await _start_jog(app, pilot)
        assert jog.target is not None and jog.target.mode == "rpy"
        await pilot.press("m")  # per joint
        assert jog.target.mode == "joint" and "per joint" in text_of(app, "#jog-mode")
        step = jog.target.step_deg
        await pilot.press("right", "right", "up", "pagedown")
        print('T', round(time.perf_counter()-T0,2), 'await pilot.press("right", "right", "up"', flush=True)
        want = home + np.array([2 * step, step, -step])
        np.testing.assert_allclose(jog.target.theta_deg, want)
        await until(pilot, lambda: len(sent) == 4, "four targets sent")
        print('T', round(time.perf_counter()-T0,2), 'await until(pilot, lambda: len(sent) == ', flush=True)
        np.testing.assert_allclose(sent[0], home + np.array([step, 0, 0]))  # one per key, at once
        np.testing.assert_allclose(sent[-1], want)
        np.testing.assert_allclose(view.ghosts[-1], want)  # the target: the ghost
        assert len(view.measured) > 0  # the measured pose: solid, from the telemetry
        assert "inside P: not clamped" in text_of(app, "#jog-target")
        await until(pilot, lambda: jog.last_sample is not None
                    and jog.last_sample.target_deg is not None
                    and np.allclose(jog.last_sample.target_deg, want), "the loop's target")
        await pilot.press("escape")  # end: the wrist settles on the last target
        await _ended(app, pilot)
        print('T', round(time.perf_counter()-T0,2), 'await _ended(app, pilot)', flush=True)
        res = app.session.last_run
        assert res is not None and res.ok and int(res.exit_code) == 0, res.message
        np.testing.assert_allclose(res.final_deg, want, atol=SETTLED_DEG)
        assert view.ghosts[-1] is None  # no ghost once the jog ended
        out = text_of(app, "#exec-outcome")
        assert out.startswith("COMPLETED (exit code 0)") and "live jog: " in out
        assert "live jog completed" in status_of(app)
        # the clock and loop-timing lines are the jog's, not an earlier plan's
        assert text_of(app, "#exec-clock").startswith("live jog: ")
        assert f"{res.stats.samples} cycles" in text_of(app, "#exec-timing")
        run = load_run(res.log_dir)
        print(open(str(res.log_dir)+"/events.jsonl").read()[:3000])
        np.testing.assert_allclose(run.vec("target")[-1], want)  # the log's target column
        np.testing.assert_allclose(run.vec("target")[0], home)
        assert run.info.kind == "follow" and run.meta["plans"][0]["source"] == JOG_SOURCE
        await pilot.press("6")  # the run is listed in the logs
        await settle(pilot)
        print('T', round(time.perf_counter()-T0,2), 'await settle(pilot)', flush=True)
        rows = app.screen.query_one("#runs", DataTable)
        kinds = [str(rows.get_row_at(i)[1]) for i in range(rows.row_count)]
        assert "follow" in kinds

