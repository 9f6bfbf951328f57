"""The terminating signals, and the one place that routes them to a stop.

Every front end that moves the wrist (``execute`` / ``home``, ``script``, the TUI)
installs one callback for all of :data:`STOP_SIGNALS` with :func:`install_stop_handler`
(or the :func:`stop_signals` context manager). The callback runs in the main thread
between two Python bytecodes, like any Python signal handler: it should only request
the stop and leave the rest — the stop action, closing the run log, leaving — to the code
it interrupted. It must take no lock the interrupted code may hold (a ``threading.Event``'s
``set`` takes one): the front ends' E-stop is one message to the motion process, sent from
a helper thread when the handler interrupted a send (``MotionClient.estop``). SIGKILL cannot be
caught: a run left ``running`` by it is listed as ``killed`` (:mod:`spm_console.motion.logs.procid`).

Exit codes stay those of docs/cli-reference.md: a signal that stops a motion ends it as an E-stop
(20); a signal while nothing moves is an interruption (130).

One exception: a SIGHUP already *ignored* when the handler is installed stays ignored.
That is ``nohup spm-console execute …``: the operator asked for the run to outlive the
terminal, and an ignored SIGHUP does not end the process (nor lose the log) anyway.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType

STOP_SIGNALS: tuple[signal.Signals, ...] = (
    signal.SIGINT,   # Ctrl-C
    signal.SIGTERM,  # kill, systemd, the TUI's tests
    signal.SIGHUP,   # the terminal closed, the SSH session dropped
    signal.SIGQUIT,  # Ctrl-\
)
"""The signals that would otherwise end the process without the stop action."""

StopCallback = Callable[[signal.Signals], None]


def install_stop_handler(callback: StopCallback) -> Callable[[], None]:
    """Route every signal of :data:`STOP_SIGNALS` to ``callback(signal)``.

    Returns the function that puts the previous handlers back. Outside the main thread
    (where Python cannot install handlers) nothing is installed and that function does
    nothing. An ignored SIGHUP (``nohup``) is left ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, _frame: FrameType | None) -> None:
        callback(signal.Signals(signum))

    nohup = signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    old = {s: signal.signal(s, handler) for s in STOP_SIGNALS if not (nohup and s == signal.SIGHUP)}

    def restore() -> None:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
        old.clear()

    return restore


@contextlib.contextmanager
def stop_signals(callback: StopCallback) -> Iterator[None]:
    """:func:`install_stop_handler` for the duration of a ``with`` block."""
    restore = install_stop_handler(callback)
    try:
        yield
    finally:
        restore()
