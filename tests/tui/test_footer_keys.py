"""The footer is rebuilt when the keys it shows change, not on every focus change."""

from __future__ import annotations

from typing import ClassVar

from textual.app import App, ComposeResult
from textual.binding import Binding, BindingType
from textual.widgets import Input
from textual.widgets._footer import FooterKey

from spm_console.tui.widgets.footer import ConsoleFooter


class _CountingFooter(ConsoleFooter):
    composed = 0

    def compose(self) -> ComposeResult:
        type(self).composed += 1
        yield from super().compose()


class _Keys(App[None]):
    BINDINGS: ClassVar[list[BindingType]] = [Binding("f2", "ask", "Ask"), Binding("f3", "other", "Other")]
    allowed = True

    def compose(self) -> ComposeResult:
        yield Input(id="one")
        yield Input(id="two")
        yield _CountingFooter()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        # None: shown, disabled (False would hide it)
        return None if action == "other" and not self.allowed else True

    def action_ask(self) -> None:
        pass

    def action_other(self) -> None:
        pass


def _keys(app: _Keys) -> dict[str, bool]:
    """Shown key → enabled (the command palette's key left out)."""
    return {k.key: not k.has_class("-disabled") for k in app.query(FooterKey) if k.key != "ctrl+p"}


def _palette_shown(app: _Keys) -> bool:
    return any(k.key == "ctrl+p" for k in app.query(FooterKey))


async def test_a_focus_change_keeps_the_footer_and_a_key_state_change_rebuilds_it() -> None:
    app = _Keys()
    async with app.run_test(size=(120, 10)) as pilot:
        await pilot.pause()
        assert _keys(app) == {"f2": True, "f3": True}
        before = _CountingFooter.composed
        for target in ("#two", "#one", "#two"):
            app.query_one(target, Input).focus()
            await pilot.pause()
        assert _CountingFooter.composed == before
        assert _keys(app) == {"f2": True, "f3": True}

        app.allowed = False
        app.refresh_bindings()
        await pilot.pause()
        assert _CountingFooter.composed == before + 1
        assert _keys(app) == {"f2": True, "f3": False}

        app.allowed = True
        app.refresh_bindings()
        await pilot.pause()
        assert _keys(app) == {"f2": True, "f3": True}


async def test_narrowing_drops_the_palette_key_and_widening_brings_it_back() -> None:
    app = _Keys()
    async with app.run_test(size=(120, 10)) as pilot:
        await pilot.pause()
        assert _palette_shown(app)
        await pilot.resize_terminal(80, 10)
        await pilot.pause()
        assert not _palette_shown(app) and _keys(app) == {"f2": True, "f3": True}
        await pilot.resize_terminal(120, 10)
        await pilot.pause()
        assert _palette_shown(app) and _keys(app) == {"f2": True, "f3": True}
