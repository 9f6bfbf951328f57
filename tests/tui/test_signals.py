"""The console on a terminating signal: E-stop any motion, close the log, leave with 20
(a motion was stopped) or 130 (nothing moved). The signals are sent to this process,
so each test first checks that the console's handler is the one in place."""

from __future__ import annotations

import asyncio
import os
import signal

import pytest

from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import list_runs
from spm_console.system.signals import STOP_SIGNALS
from tests.support.console_helpers import confirm_execute, settle, status_of

SIZE = (130, 42)
# paced: the signals land while the wrist moves
pytestmark = pytest.mark.usefixtures("sighup_default", "paced_clock")


def _send(app, sig: signal.Signals) -> None:  # type: ignore[no-untyped-def]
    handler = signal.getsignal(sig)
    assert callable(handler) and getattr(handler, "__qualname__", "").startswith(
        "install_stop_handler"), handler  # never deliver a signal that would end pytest
    os.kill(os.getpid(), sig)


async def _wait_exit(app, timeout_s: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout_s
    while app.return_value is None and loop.time() < t_end:
        await asyncio.sleep(0.05)


@pytest.mark.parametrize("sig", STOP_SIGNALS, ids=lambda s: s.name)
async def test_a_signal_mid_motion_stops_the_wrist_and_the_console(console, tmp_path, sig) -> None:
    from spm_console.services.wrist_service import PoseSpec

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        s = app.session
        assert s.bus is not None, status_of(app)
        await asyncio.to_thread(s.home)
        await asyncio.to_thread(s.wrist.load_workspace)
        await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("current"),
                                PoseSpec("theta", (95.0, 110.0, 105.0)), s.theta_deg, 150)  # 3 s
        await pilot.press("5")
        await confirm_execute(pilot)
        t_end = asyncio.get_running_loop().time() + 30.0
        while not s.moving.is_set():  # bounded: a motion that never starts fails, never hangs
            assert asyncio.get_running_loop().time() < t_end, status_of(app)
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.3)
        _send(app, sig)
        await _wait_exit(app)
    assert app.return_value == app.return_code == int(ExitCode.STOP_ESTOP)  # what `tui` exits with
    assert signal.getsignal(sig) is not app._on_stop_signal  # handlers given back on exit
    runs = [r for r in list_runs(tmp_path / "logs") if not r.info.preview]
    assert [r.meta["outcome"] for r in runs] == ["completed", "stopped"]
    assert runs[-1].meta["exit_code"] == 20
    assert runs[-1].meta["message"] == f"E-stop: signal {sig.name}"
    assert s.bus is None  # the console closed the bus on its way out


async def test_a_signal_while_nothing_moves_quits_with_130(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        _send(app, signal.SIGHUP)
        await _wait_exit(app)
    assert app.return_value == app.return_code == int(ExitCode.INTERRUPTED)
