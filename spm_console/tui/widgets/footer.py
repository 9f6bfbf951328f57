"""The key footer, narrowed on narrow terminals so that no step's keys are cut off."""

from __future__ import annotations

from textual import events
from textual.widgets import Footer

#: Below this many columns the footer drops its padding and the command palette's key (ctrl+p
#: stays bound and the help screen names it): the connect step's nine keys then fit 80 columns.
NARROW_COLUMNS = 100


class ConsoleFooter(Footer):
    """Textual's footer; compact, without the palette's entry, below :data:`NARROW_COLUMNS`."""

    def on_resize(self, event: events.Resize) -> None:
        narrow = event.size.width < NARROW_COLUMNS
        self.compact = narrow
        if self.show_command_palette == narrow:  # (compose reads it: recompose)
            self.show_command_palette = not narrow
            self.refresh(recompose=True)
