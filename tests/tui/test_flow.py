"""The whole flow on the emulated bus, keyboard only, as a new operator walks it:
connect & home -> FK check -> workspace -> MVN plan -> execute -> logs."""

from __future__ import annotations

import numpy as np
from textual.widgets import DataTable, Input

from spm_console.motion.logs.runlog import list_runs
from tests.support.console_helpers import confirm_execute, settle, status_of, text_of

SIZE = (130, 42)


async def test_whole_flow_by_keys(console, tmp_path) -> None:
    app = console(initial_deg=(128.0, 140.0, 133.0))
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        hint = text_of(app, "#hint-line")
        assert "press h to home" in hint

        await pilot.press("h", "y")  # 1: home
        await settle(pilot)
        assert app.session.homed
        assert "press 2" in text_of(app, "#hint-line")

        await pilot.press("2", "f")  # 2: FK of the current pose
        await settle(pilot)
        assert "FEASIBLE" in text_of(app, "#fk-result")
        assert "press 3" in text_of(app, "#hint-line")

        await pilot.press("3")  # 3: workspace (cached)
        await settle(pilot)
        assert "press 4" in text_of(app, "#hint-line")

        await pilot.press("4")  # 4: MVN plan, typed
        await pilot.pause()
        await pilot.press("tab")  # the fields come in order: start kind first
        steps = app.screen.query_one("#steps", Input)
        steps.focus()
        steps.value = ""
        await pilot.press(*"60", "enter")  # Enter in a field solves
        await settle(pilot)
        plan = app.session.plans.plan
        assert plan is not None and plan.N == 60, status_of(app)
        await pilot.press("escape")
        assert app.focused is None
        assert "press 5" in text_of(app, "#hint-line")

        await pilot.press("5")  # 5: execute (x previews the run, then asks)
        await confirm_execute(pilot)
        await settle(pilot)
        res = app.session.last_run
        assert res is not None and res.ok, status_of(app)
        np.testing.assert_allclose(res.final_deg, plan.reference_deg[-1], atol=0.3)
        assert "press 6" in text_of(app, "#hint-line")

        await pilot.press("6")  # 6: the log
        await settle(pilot)
        table = app.screen.query_one("#runs", DataTable)
        # homing, the preview and the execution, newest first
        assert [table.get_row_at(i)[1] for i in range(table.row_count)] == [
            "execute", "execute (preview)", "home"]
        await pilot.press("enter")
        await settle(pilot)
        assert str(res.log_dir) in text_of(app, "#run-text")
        assert app.screen.run is not None and app.screen.run.rows >= 61
        await pilot.press("p", "j")  # other plot, other joint: no error
        await settle(pilot)
        assert "joint 2: velocities" in str(app.screen.query_one("#run-plot").render())

        await pilot.press("q", "q")  # quitting asks first
    assert app.return_code == 0
    assert [r.info.preview for r in list_runs(tmp_path / "logs")] == [False, True, False]
    assert app.session.bus is None and app.session.emulator is None  # closed on quit


def test_the_hint_on_the_step_it_names_says_what_to_do_there() -> None:
    """"press 2 (F2) for an FK check" on step 2 itself read oddly: there it names the key of
    the step's own action; elsewhere the step's key."""
    import threading
    from types import SimpleNamespace

    from spm_console.tui.widgets.steps import next_hint

    homed = SimpleNamespace(moving=threading.Event(), bus=object(), homed=True,
                            wrist=SimpleNamespace(workspace=None), last_run=None,
                            plans=SimpleNamespace(plan=None, info=None))
    elsewhere = next_hint(homed, current="connect")  # type: ignore[arg-type]
    assert elsewhere == "Next: press 2 (F2) for an FK check, or 3 (F3) for the workspace."
    here = next_hint(homed, current="fk")  # type: ignore[arg-type]
    assert here == "Next: type θ and press f for an FK check, or 3 (F3) for the workspace."
    there = next_hint(homed, current="workspace")  # type: ignore[arg-type]
    assert there.endswith("or press l to load the workspace.")
