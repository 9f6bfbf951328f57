"""A checkbox that reads as off when it is off.

Textual's :class:`~textual.widgets.Checkbox` draws its "X" in both states and tells them apart
by colour alone, so an unticked box looked ticked to an operator (and on a monochrome
terminal the two are the same). Here the mark is drawn only while the box is on.
"""

from __future__ import annotations

from textual.content import Content
from textual.widgets import Checkbox

#: What the box holds when on, and when off.
MARK_ON = "X"
MARK_OFF = " "


class TickBox(Checkbox):
    """A :class:`~textual.widgets.Checkbox` showing its mark only while on."""

    def render(self) -> Content:
        self.BUTTON_INNER = MARK_ON if self.value else MARK_OFF
        return super().render()
