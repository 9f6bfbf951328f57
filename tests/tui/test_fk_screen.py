"""Step 2: FK check against the paper's printed vectors, IK, modes, bad input."""

from __future__ import annotations

import numpy as np

from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (120, 40)

# eq. (34): θ = [95, 110, 105]° (paper prints ±3e-4)
V_PAPER = [[-0.0817, 0.8229, 0.5623], [0.9038, -0.1766, 0.3899], [-0.4202, -0.5400, 0.7293]]
N_PAPER = [0.2320, 0.0613, 0.9708]


def _rows(text: str, prefix: str) -> np.ndarray:
    line = next(ln for ln in text.splitlines() if ln.startswith(prefix))
    return np.array([float(x) for x in line.split("[")[1].split("]")[0].split(",")])


async def test_fk_of_the_paper_example_shows_the_printed_orientation(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        app.screen.query_one("#theta", AnglesInput).set_values([95, 110, 105])
        await pilot.press("f")
        await settle(pilot)
        out = text_of(app, "#fk-result")
        for i in range(3):
            np.testing.assert_allclose(_rows(out, f"v{i + 1} "), V_PAPER[i], atol=5e-4)
        np.testing.assert_allclose(_rows(out, "n "), N_PAPER, atol=5e-4)
        assert "FEASIBLE" in out and "closest links" in out
        assert app.fk_done and "✔ FK check" in text_of(app, "#steps-line")


async def test_typing_theta_and_enter_solves(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2", "tab")  # into θ1
        field = app.focused
        assert field is not None and field.id == "theta-0"
        field.value = ""  # type: ignore[attr-defined]
        await pilot.press(*"108", "tab")
        app.focused.value = ""  # type: ignore[union-attr]
        await pilot.press(*"60", "tab")
        app.focused.value = ""  # type: ignore[union-attr]
        await pilot.press(*"105", "enter")
        await settle(pilot)
        out = text_of(app, "#fk-result")
        # Table I: θ = [108, 60, 105] -> v1 = [-0.27658, 0.12708, 0.95255] (±5e-4)
        np.testing.assert_allclose(_rows(out, "v1 "), [-0.27658, 0.12708, 0.95255], atol=5e-4)


async def test_ik_from_roll_pitch_yaw_round_trips(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        app.screen.query_one("#rpy", AnglesInput).set_values([10, -5, 20])
        await pilot.press("i")
        await settle(pilot)
        theta = app.screen.query_one("#theta", AnglesInput).values()
        expect = app.session.wrist.ik([10, -5, 20])
        np.testing.assert_allclose(theta, expect, atol=1e-3)
        assert "FK solved" in status_of(app)


async def test_fk_fills_the_orientation_fields_with_the_poses_own(console) -> None:
    """After FK of θ the orientation fields show that pose's roll/pitch/yaw (not an older
    orientation, nor its refusal), and IK of them gives θ back."""
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        rpy = app.screen.query_one("#rpy", AnglesInput)
        rpy.set_values([0, 0, 170])  # an orientation IK cannot reach within the servo limits
        await pilot.pause()
        app.screen.query_one("#theta", AnglesInput).set_values([95, 110, 105])
        await pilot.press("f")
        await settle(pilot)
        assert "FK solved" in status_of(app)
        shown = rpy.values()  # valid now: no refusal left beside the new result
        assert not np.allclose(shown, [0, 0, 170])
        np.testing.assert_allclose(app.session.wrist.ik(shown), [95, 110, 105], atol=0.05)


async def test_all_modes_flags_the_home_connected_one(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        app.screen.query_one("#theta", AnglesInput).set_values([95, 110, 105])
        await pilot.press("m")
        await settle(pilot)
        out = text_of(app, "#fk-result")
        assert "assembly modes at this θ" in out
        assert out.count("home-connected") == 1


async def test_bad_input_is_a_message_not_a_crash(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        fields = app.screen.query_one("#theta", AnglesInput).fields
        fields[1].value = ""
        await pilot.press("f")
        await settle(pilot)
        assert "FK refused: θ2: empty, type a number of degrees" in status_of(app)
        # an unreachable θ: the reason (with its [..] list) is shown literally, not as markup
        app.screen.query_one("#theta", AnglesInput).set_values([65, 155, 65])
        await pilot.press("f")
        await settle(pilot)
        msg = status_of(app)
        assert msg.startswith("FK failed: θ = [65.00, 155.00, 65.00]°"), msg
        assert app.is_running


async def test_the_orientation_fields_are_named_roll_pitch_yaw_in_degrees(console) -> None:
    app = console()
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("2")
        await pilot.pause()
        rpy = app.screen.query_one("#rpy")
        assert [str(n.render()) for n in rpy.query(".angle-name")] == [
            "roll (°)", "pitch (°)", "yaw (°)"]
