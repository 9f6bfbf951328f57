"""Run in each local sweep worker as it starts (a Dask preload): the terminal's Ctrl-C and
Ctrl-\\ are for the sweep's own process, which closes the cluster in order; a worker that
took them would die with a traceback, and Dask would start it again. (Workers started by the
sweep's own cluster hold both signals from birth; this covers any other.)"""

from __future__ import annotations

import contextlib
import signal
from typing import Any


def dask_setup(worker: Any) -> None:
    """Dask's preload hook: ignore SIGINT and SIGQUIT in this worker process."""
    for sig in (signal.SIGINT, signal.SIGQUIT):
        with contextlib.suppress(ValueError):  # not the main thread: the held mask covers it
            signal.signal(sig, signal.SIG_IGN)
