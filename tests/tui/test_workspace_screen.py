"""Step 3: the workspace from the cache, its counts, and the θ check."""

from __future__ import annotations

from spm_console.store.workspace_cache import load_or_build
from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (120, 40)


async def test_loads_the_cached_workspace_and_shows_its_counts(console, agile, ws_cache) -> None:
    ws, _ = load_or_build(agile, cache_dir=ws_cache)  # the independent reading of the cache
    c = ws.counts()
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        info = text_of(app, "#ws-info")
        assert info.startswith("loaded from the cache")
        assert f"{c['nodes']} nodes" in info
        assert f"feasible     {c['feasible']} " in info
        assert f"singular     {c['singular']} " in info
        assert f"colliding {c['colliding']} " in info
        assert f"{ws.region.halfspaces} half-spaces" in info
        assert "press 4" in status_of(app)


async def test_check_gives_the_one_verdict_and_says_why(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        await pilot.press("k")  # default θ = eq. (32): usable
        await settle(pilot)
        assert "feasible, inside P: plannable in P" in text_of(app, "#ws-check")
        # within the servo limits (60…160°), outside the grid (65…155°)
        app.screen.query_one("#check-theta", AnglesInput).set_values([62, 135, 135])
        await pilot.press("k")
        await settle(pilot)
        out = text_of(app, "#ws-check")
        assert "NOT feasible: outside the workspace grid" in out


async def test_rebuild_asks_first(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        await pilot.press("b")
        assert type(app.screen).__name__ == "ConfirmScreen"
        await pilot.press("n")
        await settle(pilot)
        assert text_of(app, "#ws-info").startswith("loaded from the cache")


async def test_building_shows_progress_then_the_counts(agile, tmp_path) -> None:
    """No cache yet: the workspace is built in a worker with a progress bar (a coarse 5° grid
    keeps this quick), then cached."""
    from spm_console.tui.app import make_app
    from spm_console.tui.messages import Progress

    coarse = agile.model_copy(update={"workspace": agile.workspace.model_copy(
        update={"step_deg": 5.0})})
    seen: list[tuple[str, float]] = []

    def hook(message: object) -> None:
        if isinstance(message, Progress):
            seen.append((message.stage, message.fraction))

    app = make_app(coarse, viewer=False, logs_root=tmp_path / "logs", cache_dir=tmp_path / "c")
    async with app.run_test(size=SIZE, message_hook=hook) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot, timeout_s=120)
        info = text_of(app, "#ws-info")
        assert info.startswith("built in") and "no cache file" in info
        assert "6859 nodes" in info  # 19³ nodes at 5°
        assert {"fk", "links", "region"} <= {s for s, _ in seen}
        assert not app.screen.query_one("#ws-progress").display  # hidden when done
        assert any((tmp_path / "c").iterdir())  # cached for next time
