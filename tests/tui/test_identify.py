"""The console offers the identification experiment (step 1, key i): refused before homing,
asked first, then run like any motion (E-stop banner, logged), the model fitted and the
identified profile written beside the profile in use (the plot into the run's folder). The
whole result is shown, its path whole at 80×24, and "Use the identified servo model now?":
yes restarts the console on the identified profile with the workspace kept (not loaded or
built again) and no plan; there the operator plans and executes at 80×24 without leaving it."""

from __future__ import annotations

import argparse
import asyncio
import re
from pathlib import Path

import pytest
from textual.widgets import Input

from spm_console.cli.tui import console_factory
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.motion.logs.runlog import list_runs
from spm_console.store.identified_profiles import family
from spm_console.store.workspace_cache import cache_path
from spm_console.tui.identify_run import PLOT_NAME
from spm_console.tui.switch import SwitchRequest
from spm_console.tui.widgets.confirm import LongConfirm
from tests.conftest import ROOT
from tests.support.console_helpers import MotionSpy, confirm_execute, screen_text, settle, status_of, text_of

SMALL = (80, 24)
#: The dialog's border (left and right), and its scrollbar's thumb beside the text.
BORDER, THUMB = "█", " ▁▂▃▄▅▆▇"


def _dialog_text(screen: str) -> str:
    """The text inside the dialog's border, its lines joined: a path wrapped over lines reads
    whole."""
    return "".join(line[line.index(BORDER) + 1:line.rindex(BORDER)].rstrip(THUMB)
                   for line in screen.splitlines() if line.count(BORDER) >= 2)


@pytest.mark.slow  # the 18 s experiment and its fit (CI runs the slow set, alone)
async def test_identify_then_use_the_identified_model_with_the_workspace_kept(
        console, tmp_path: Path, ws_cache: Path, agile: Profile) -> None:  # type: ignore[no-untyped-def]
    folder = tmp_path / "profiles"
    folder.mkdir()
    in_use = folder / "agile_wrist.toml"
    in_use.write_bytes((ROOT / "profiles" / "agile_wrist.toml").read_bytes())
    cached = cache_path(agile, ws_cache)
    cached_at = cached.stat().st_mtime_ns
    app = console(profile_path=in_use)
    spy = MotionSpy()
    async with app.run_test(size=SMALL, message_hook=spy.hook) as pilot:
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
        runs = list_runs(tmp_path / "logs")
        assert [r.meta["outcome"] for r in runs] == ["completed", "completed"]  # home, experiment
        assert (runs[-1].path / PLOT_NAME).stat().st_size > 0
        # written beside the profile in use, named after it and the fit's time
        written = family(in_use)[1:]
        assert len(written) == 1 and written[0].parent == folder, written
        identified = written[0]
        assert re.match(r"^agile_wrist\.identified-[0-9T-]+Z\.toml$", identified.name)
        new = load_profile(identified)
        assert new.servo.identified is not None and new.servo.identified.source == str(
            runs[-1].path)
        # the ideal emulated servo is eq. (27) itself: the fit finds its p and ζ = 1
        assert abs(new.servo.p / before.servo.p - 1) < 0.05 and abs(new.servo.zeta - 1) < 0.05
        assert app.session.profile is before  # nothing changes before the answer
        # the question shows the whole result; at 80×24 the whole path
        assert isinstance(app.screen, LongConfirm), type(app.screen).__name__
        assert "Use the identified servo model now?" in screen_text(app)
        assert str(identified) in _dialog_text(screen_text(app)), screen_text(app)
        body = text_of(app, "#confirm-body")
        assert all(w in body for w in ("ωn", "ζ", "delay", "held-out part RMS", "load",
                                       "linear range", "joint 3 alone")), body
        ws = app.session.wrist.workspace
        assert ws is not None
        await pilot.press("y")
        await settle(pilot)
    request = app.return_value
    assert isinstance(request, SwitchRequest) and request.profile_path == identified
    assert app.session.bus is None  # closed before the next console
    # the next console, as `spm-console tui` builds it for the request
    args = argparse.Namespace(plant="ideal", port=None, sim=True, no_viewer=True,
                              logs=tmp_path / "logs", cache_dir=ws_cache)
    second = console_factory(args)(request.profile_path, request.grid_step_deg,
                                   request.note(), request.kept)
    async with second.run_test(size=SMALL) as pilot:
        await settle(pilot)
        s = second.session
        assert s.profile.servo == new.servo and s.plans.plan is None
        assert s.wrist.workspace is ws  # kept, not loaded or built again
        result = await asyncio.to_thread(s.home)  # the motion process verifies with the cache
        assert result.ok, result.message
        await pilot.press("3")
        await settle(pilot)
        assert "workspace ready" in status_of(second), status_of(second)
        await pilot.press("4")  # plan on the identified model, by keys, at 80×24
        await pilot.pause()
        await pilot.press("tab")
        steps = second.screen.query_one("#steps", Input)
        steps.focus()
        steps.value = ""
        await pilot.press(*"60", "enter")
        await settle(pilot)
        plan = s.plans.plan
        assert plan is not None and plan.N == 60, status_of(second)
        await pilot.press("escape", "5")  # and execute it
        await confirm_execute(pilot)
        await settle(pilot)
        res = s.last_run
        assert res is not None and res.ok, status_of(second)
    assert cached.stat().st_mtime_ns == cached_at  # the cached workspace was not rebuilt
