"""A text field that applies every key in the order it was typed.

Textual hands a key to the focused widget's queue, but runs the widget's own key bindings
(backspace, delete, ctrl+u, the arrows, home/end, enter) only when the key has bubbled up
to the app, after the widget has already inserted the characters typed behind it. Typed
one key at a time nobody notices; in a burst (type-ahead, an unbracketed paste, tmux
``send-keys``) "127.6⌫5" became "127.65" and the backspace hit whichever field had the
focus by then. :class:`TextField` runs its own bindings as the key comes out of its queue,
in line with the characters around it.

A pasted text stays whole too: Textual's field keeps only the first line of a multi-line
paste; here the lines are joined by spaces, so everything pasted shows (and a number field
refuses it with the reason).

A field that is left shows its text from the start: a text longer than the field (refused,
with the reason under it) then reads as typed from its first character, not as its tail,
which could pass for a plausible number.
"""

from __future__ import annotations

from textual import events
from textual.widgets import Input


class TextField(Input):
    """An :class:`~textual.widgets.Input` whose own bindings run in typing order."""

    def on_paste(self, event: events.Paste) -> None:
        # Runs before Input's handler, which would drop every line after the first.
        lines = event.text.splitlines()
        if len(lines) <= 1:
            return
        event.stop()
        event.prevent_default()
        text = " ".join(lines)
        if self.selection.is_empty:
            self.insert_text_at_cursor(text)
        else:
            self.replace(text, *self.selection)

    def on_blur(self, event: events.Blur) -> None:
        if self.app.screen_stack:  # (not while the app closes: moving the cursor needs one)
            self.cursor_position = 0  # the view follows the cursor: the text's start shows

    async def on_key(self, event: events.Key) -> None:
        # Runs before Input's handler (subclass first); printable keys go on to it.
        if event.is_printable:
            return
        for binding in self._bindings.key_to_bindings.get(event.key, ()):
            if binding.priority:
                continue  # priority bindings already ran before the key got here
            if await self.app.run_action(binding.action, self):
                event.stop()
                event.prevent_default()
                return
