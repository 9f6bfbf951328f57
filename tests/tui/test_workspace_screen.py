"""Step 3: the workspace from the cache, its counts, and the θ check."""

from __future__ import annotations

from spm_console.tui.widgets.angles import AnglesInput
from spm_console.workspace_cache import load_or_build
from tests.tui.helpers import settle, status_of, text_of

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


async def test_check_says_why_a_theta_is_not_usable(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        await pilot.press("k")  # default θ = eq. (32): usable
        await settle(pilot)
        assert "USABLE for planning" in text_of(app, "#ws-check")
        app.screen.query_one("#check-theta", AnglesInput).set_values([40, 135, 135])
        await pilot.press("k")
        await settle(pilot)
        out = text_of(app, "#ws-check")
        assert "NOT usable" in out and "outside the workspace grid" in out


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
