"""The key footer: narrowed on narrow terminals so that no step's keys are cut off, and rebuilt
only when the keys it shows change."""

from __future__ import annotations

from collections.abc import Hashable

from textual import events
from textual.screen import Screen
from textual.widgets import Footer

#: Below this many columns the footer drops its padding and the command palette's key (ctrl+p
#: stays bound and the help screen names it): the connect step's nine keys then fit 80 columns.
NARROW_COLUMNS = 100


class ConsoleFooter(Footer):
    """Textual's footer; compact, without the palette's entry, below :data:`NARROW_COLUMNS`.

    Textual's footer recomposes (removes and mounts one widget per key, then styles them) on
    every update of the screen's bindings, which it announces on each focus change. This one
    recomposes only when what it shows changed: each shown key with its label, action, state,
    tooltip and group, and the palette's entry."""

    _shown: Hashable | None = None

    def _signature(self, screen: Screen[object]) -> Hashable:
        keys = tuple(
            (b.key, b.description, b.action, enabled, tooltip, b.tooltip,
             None if b.group is None else (b.group.description, b.group.compact))
            for (_node, b, enabled, tooltip) in screen.active_bindings.values() if b.show)
        return (keys, self.show_command_palette, self.app.ENABLE_COMMAND_PALETTE)

    def bindings_changed(self, screen: Screen[object]) -> None:
        self._bindings_ready = True
        if not screen.app.app_focus:
            return
        if self.is_attached and screen is self.screen:
            self.call_after_refresh(self._recompose_if_changed)

    async def _recompose_if_changed(self) -> None:
        if not self.is_attached:
            return
        shown = self._signature(self.screen)
        if shown != self._shown:
            self._shown = shown
            await self.recompose()

    def on_resize(self, event: events.Resize) -> None:
        narrow = event.size.width < NARROW_COLUMNS
        self.compact = narrow
        if self.show_command_palette == narrow:  # (compose reads it: recompose)
            self.show_command_palette = not narrow
            self._shown = None
            self.refresh(recompose=True)
