"""The console offers the identification experiment (step 1, key i): refused before homing,
asked first, then run like any motion (E-stop banner, logged), the model fitted and a profile
with it written into the run's folder beside the plot; the profile in use does not change."""

from __future__ import annotations

import asyncio

import pytest

from spm_console.config.load import load_profile
from spm_console.motion.logs.runlog import list_runs
from spm_console.tui.identify_run import PLOT_NAME, PROFILE_NAME
from tests.support.console_helpers import MotionSpy, settle, status_of

SIZE = (130, 42)


@pytest.mark.slow  # the 18 s experiment and its fit (CI runs the slow set, alone)
async def test_identify_is_refused_until_homed_then_writes_a_profile(console, tmp_path) -> None:  # type: ignore[no-untyped-def]
    app = console()
    spy = MotionSpy()
    async with app.run_test(size=SIZE, message_hook=spy.hook) as pilot:
        spy.attach(app)
        await settle(pilot)
        await pilot.press("i")
        await settle(pilot)
        assert "identify refused" in status_of(app) and "home" in status_of(app)
        assert list_runs(tmp_path / "logs") == []
        await asyncio.to_thread(app.session.home)
        before = app.session.profile
        await pilot.press("i")
        assert type(app.screen).__name__ == "ConfirmScreen"
        await pilot.press("y")
        await settle(pilot, timeout_s=120)
        assert spy.moving[-2:] == [True, False]
        assert "identified: ωn" in status_of(app), status_of(app)
        runs = list_runs(tmp_path / "logs")
        assert [r.meta["outcome"] for r in runs] == ["completed", "completed"]  # home, experiment
        folder = runs[-1].path
        new = load_profile(folder / PROFILE_NAME)
        assert new.servo.identified is not None and new.servo.residual_bound_deg is not None
        # the ideal emulated servo is eq. (27) itself: the fit finds its p and ζ = 1
        assert abs(new.servo.p / before.servo.p - 1) < 0.05 and abs(new.servo.zeta - 1) < 0.05
        assert (folder / PLOT_NAME).stat().st_size > 0
        assert app.session.profile is before  # the profile in use is unchanged
