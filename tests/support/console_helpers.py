"""Helpers of the console tests: wait for workers, read widget text."""

from __future__ import annotations

import asyncio
import html
import re
from collections import defaultdict
from typing import Any

from textual.pilot import Pilot
from textual.widgets import Static

from spm_console.tui.app import SpmConsoleApp


async def settle(pilot: Pilot[Any], timeout_s: float = 30.0) -> None:
    """Wait until no worker runs and no screen operation is pending (their results posted
    and handled), polling the workers rather than sleeping a fixed time."""
    app = pilot.app
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout_s
    quiet = 0
    while quiet < 3:  # three consecutive idle checks: nothing queued behind the last one
        await pilot.pause()
        busy = any(w.is_running for w in app.workers) or bool(getattr(app.screen, "busy_op", ""))
        quiet = 0 if busy else quiet + 1
        if busy:
            await asyncio.wait_for(app.workers.wait_for_complete(), max(0.1, t_end - loop.time()))
        if loop.time() > t_end:
            raise TimeoutError("the console did not settle")


async def confirm_execute(pilot: Pilot[Any]) -> None:
    """x on the Execute step: the run's preview on the twin first (a worker), then "Execute
    the plan?", answered y."""
    await pilot.press("x")
    await settle(pilot)
    assert type(pilot.app.screen).__name__ == "LongConfirm", status_of(pilot.app)
    await pilot.press("y")


def text_of(app: SpmConsoleApp, selector: str) -> str:
    """Plain text of a Static on the current screen."""
    return str(app.screen.query_one(selector, Static).render())


def status_of(app: SpmConsoleApp) -> str:
    return text_of(app, "#status")


_TEXT = re.compile(r'<text class="[^"]*" x="([\d.]+)" y="([\d.]+)"[^>]*>([^<]*)</text>')


def screen_text(app: Any) -> str:
    """What the terminal shows, one line per row (from the SVG screenshot)."""
    rows: dict[float, list[tuple[float, str]]] = defaultdict(list)
    for x, y, text in _TEXT.findall(app.export_screenshot()):
        rows[float(y)].append((float(x), html.unescape(text).replace("\xa0", " ")))
    return "\n".join("".join(t for _x, t in sorted(rows[y])) for y in sorted(rows))


class MotionSpy:
    """Records, without racing the motion, what the operator saw while the wrist moved:
    the ``moving`` flag's values and whether the E-stop banner was up at each telemetry."""

    def __init__(self, press_while_moving: str = "") -> None:
        self.moving: list[bool] = []
        self.banner_at_telemetry: list[bool] = []
        self.screens_at_telemetry: list[str] = []
        self.press_while_moving = press_while_moving
        """A key sent (once) at the first telemetry of a motion, e.g. a step key."""
        self.app: SpmConsoleApp | None = None

    def attach(self, app: SpmConsoleApp) -> None:
        self.app = app
        def changed(moving: bool) -> None:
            self.moving.append(moving)

        app.watch(app, "moving", changed, init=False)

    def hook(self, message: Any) -> None:
        """``run_test(message_hook=spy.hook)``."""
        from spm_console.tui.messages import Telemetry

        if isinstance(message, Telemetry) and self.app is not None:
            from textual import events

            banners = self.app.screen.query(".estop-banner")
            self.banner_at_telemetry.append(bool(banners) and bool(banners.first().display))
            self.screens_at_telemetry.append(type(self.app.screen).__name__)
            if self.press_while_moving:
                key, self.press_while_moving = self.press_while_moving, ""
                self.app.post_message(events.Key(key, key))


#: Keys by name, as the terminal sends them (their character, if any).
_NAMED_KEYS = {"tab": "\t", "shift+tab": None, "enter": "\r", "escape": "\x1b",
               "backspace": "\x7f", "ctrl+u": "\x15", "end": None, "space": " "}


def burst(app: SpmConsoleApp, *parts: str) -> None:
    """Queue keys as a terminal delivers type-ahead or an unbracketed paste: all at once,
    none waiting for the one before to be handled (``pilot.press`` waits after each key).
    A part is a named key (``"tab"``, ``"enter"`` …) or text sent character by character."""
    from textual import events
    from textual.keys import _character_to_key

    for part in parts:
        if part in _NAMED_KEYS:
            keys = [events.Key(part, _NAMED_KEYS[part])]
        else:
            keys = [events.Key(_character_to_key(c), c) for c in part]
        for key in keys:
            key.set_sender(app)
            app.post_message(key)
