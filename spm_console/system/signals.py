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


class SignalInterrupt(KeyboardInterrupt):
    """What a terminating signal raises in the code it interrupts (its argument: the signal's
    name). A subclass, so every ``except KeyboardInterrupt`` takes it, but not
    KeyboardInterrupt itself: CPython notes a KeyboardInterrupt that leaves code run by
    ``exec`` of a string (dataclasses build their methods so, as modules load) even when a
    caller catches it, and ``python -m`` then ends by SIGINT whatever its exit code was; it
    compares the exception's exact type."""


_received: list[signal.Signals] = []
"""The terminating signals this process received since :func:`forget_signals`, in order."""


def note_signal(sig: signal.Signals) -> bool:
    """Record a terminating signal; True when it is the first. The first decides the exit code
    (an E-stop, an interruption): a second one (a double Ctrl-C, ``timeout`` after a group
    signal) changes nothing, raises nothing and kills nothing. Lock-free (list.append)."""
    _received.append(sig)
    return len(_received) == 1


def first_signal() -> signal.Signals | None:
    """The first terminating signal received (None if none)."""
    return _received[0] if _received else None


_raised: list[signal.Signals] = []
"""The signal whose interrupt the CLI's start-up handler raised (empty: none)."""


def note_raised(sig: signal.Signals) -> None:
    """The CLI's start-up handler raises the interrupt of ``sig`` (lock-free)."""
    _raised.append(sig)


def raised_interrupt() -> signal.Signals | None:
    """The signal whose interrupt the start-up handler raised in this command (None: none).
    A command still running after it had that interrupt lost: a library caught it."""
    return _raised[0] if _raised else None


def forget_signals() -> None:
    """A new command starts (callers of the CLI's ``main`` in one process, such as tests)."""
    _received.clear()
    _raised.clear()


def ignore_stop_signals() -> None:
    """The process's result is decided: from here until it exits, a terminating signal is
    ignored. Python gives the default action back to every signal it handled while it shuts
    down, so a signal then would kill the process and change its exit status; an ignored one
    stays ignored. Main thread only (elsewhere nothing is changed)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


def install_stop_handler(callback: StopCallback) -> Callable[[], None]:
    """Route every signal of :data:`STOP_SIGNALS` to ``callback(signal)``.

    Returns the function that puts the previous handlers back. Outside the main thread
    (where Python cannot install handlers) nothing is installed and that function does
    nothing. An ignored SIGHUP (``nohup``) is left ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, _frame: FrameType | None) -> None:
        note_signal(signal.Signals(signum))
        callback(signal.Signals(signum))  # an E-stop request: asked again, the same stop

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
