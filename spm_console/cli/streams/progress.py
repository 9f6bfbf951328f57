"""What a moving command is doing, on standard error while it runs (an operator's terminal).

``execute``, ``home``, ``follow`` and ``identify --experiment`` take seconds before and while
the wrist moves; on a terminal they show the phase (starting, verifying, homing, approach,
plan, following), a bar over the motion's planned duration, the time elapsed since the command started, the time left
of the motion under way, and the live tracking error (measured θ against the servo model, the
safety check's quantity). Drawn with rich's live progress on standard error only, and only
when it is a terminal: standard output, a ``--json`` answer, a redirected standard error and
``--quiet`` see nothing of it. The display is removed when the run ends, before the command's
summary. Degrees, seconds.
"""

from __future__ import annotations

import contextlib
import math
import sys
import threading
from collections.abc import Callable
from types import TracebackType
from typing import TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)

from spm_console.motion.sample import Sample

#: What a sample's phase is shown as.
PHASE_WORDS = {"homing": "homing", "approach": "approach", "plan": "plan",
               "follow": "following"}


class _VanishingTerminal:
    """The terminal's stream as the display writes it: the terminal may close under a running
    command (SIGHUP; writes then fail with EIO), and a display must never turn the run's
    outcome into an error. From the first failed write on, nothing more is written."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream
        self.gone = False

    def write(self, text: str) -> int:
        if not self.gone:
            try:
                self._stream.write(text)
            except (OSError, ValueError):
                self.gone = True
        return len(text)

    def flush(self) -> None:
        if not self.gone:
            try:
                self._stream.flush()
            except (OSError, ValueError):
                self.gone = True

    def isatty(self) -> bool:
        try:
            return not self.gone and self._stream.isatty()
        except (OSError, ValueError):
            return False

    def __getattr__(self, name: str) -> object:  # fileno, encoding, …: the stream's own
        return getattr(self._stream, name)


def wanted(stream: TextIO, quiet: bool, as_json: bool) -> bool:
    """Whether to show progress: a terminal, no ``--quiet`` and no ``--json``."""
    if quiet or as_json:
        return False
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


class RunProgress:
    """The live display of one command (a context manager; inert when not ``enabled``).

    ``total_s()`` gives the planned duration of the motion under way (read at each sample:
    the homing run and the execution each set theirs before they start). Samples arrive on
    the motion client's telemetry thread; rich's display is thread-safe and redraws from a
    thread of its own (ten times a second), so a sample costs a dictionary update."""

    def __init__(self, enabled: bool, total_s: Callable[[], float] | None = None,
                 stream: TextIO | None = None) -> None:
        self.enabled = enabled
        self.total_s = total_s
        self._lock = threading.Lock()
        self._progress: Progress | None = None
        self._task: TaskID | None = None
        if enabled:
            self._out = _VanishingTerminal(stream or sys.stderr)
            console = Console(file=self._out)  # type: ignore[arg-type]  # a text stream
            self._progress = Progress(
                TextColumn("{task.description:<10}"), BarColumn(bar_width=24),
                TextColumn("{task.percentage:>3.0f}%"), TimeElapsedColumn(),
                TextColumn("{task.fields[left]}"), TextColumn("{task.fields[err]}"),
                console=console, transient=True, refresh_per_second=10,
                redirect_stdout=False)  # a message on stderr prints above the display

    def __enter__(self) -> RunProgress:
        if self._progress is not None:
            self._progress.start()
            self._task = self._progress.add_task("starting", total=None, left="", err="")
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._progress is not None:
            with contextlib.suppress(OSError, ValueError):  # the terminal is gone: nothing to clear
                self._progress.stop()

    def phase(self, words: str) -> None:
        """A phase without a known duration (starting, verifying the plan)."""
        if self._progress is None or self._task is None:
            return
        with self._lock:
            self._progress.update(self._task, description=words, total=None, completed=0,
                                  left="", err="")

    def on_sample(self, sample: Sample) -> None:
        """One servo cycle: the phase, the share of the motion done, the tracking error."""
        if self._progress is None or self._task is None:
            return
        total = self.total_s() if self.total_s is not None else 0.0
        total = total if math.isfinite(total) and total > 0 else 0.0  # live targets: no end
        words = PHASE_WORDS.get(sample.phase, sample.phase)
        err = sample.tracking_error_deg
        shown = (f"tracking error {err:5.2f}°" if math.isfinite(err) else "no reply this cycle")
        done = min(max(sample.t, 0.0), total)
        left = f"{total - done:4.1f} s left" if total else ""
        with self._lock:
            self._progress.update(self._task, description=words, completed=done,
                                  total=total or None, left=left, err=shown)
