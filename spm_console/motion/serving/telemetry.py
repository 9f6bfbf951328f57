"""Telemetry from the servo loop to the client (:class:`TelemetryOut`): the loop appends, a
sender thread ships batches; the loop never waits for a slow client."""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

from spm_console.motion.protocol import Telemetry
from spm_console.motion.sample import Sample
from spm_console.system.realtime import HELPER_PRIORITY, request_realtime

#: Telemetry to the client at most this often, s (the loop itself runs every Ts).
TELEMETRY_S = 0.05
#: Most samples in one telemetry message (a pickle of this many takes well under 1 ms).
TELEMETRY_CHUNK = 10
#: Most samples kept for a client that does not read (10 s at Ts = 20 ms).
MAX_PENDING = 500


class TelemetryOut:
    """Samples from the servo loop to the client without ever blocking the loop.

    The loop only appends (:meth:`put`, O(1)); a sender thread ships what accumulated every
    :data:`TELEMETRY_S`. A client that reads too slowly (a busy UI) makes the socket block
    the *sender*, never the loop; beyond :data:`MAX_PENDING` samples the oldest are dropped
    from the telemetry (never from the run log) and counted in the next message.
    """

    def __init__(self, send: Callable[[object], None]) -> None:
        self._send = send
        self._q: deque[Sample] = deque()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.dropped = 0
        self._thread = threading.Thread(target=self._run, daemon=True, name="spm-telemetry")
        self._thread.start()

    def put(self, sample: Sample) -> None:
        with self._lock:
            if len(self._q) >= MAX_PENDING:
                self._q.popleft()
                self.dropped += 1
            self._q.append(sample)

    def _flush(self) -> None:
        """Ship what accumulated in messages of at most :data:`TELEMETRY_CHUNK` samples:
        pickling holds the GIL, and a backlog pickled at once kept the loop waiting for it
        (late cycles of 5-13 ms behind a slow client)."""
        while True:
            with self._lock:
                n = min(len(self._q), TELEMETRY_CHUNK)
                batch = tuple(self._q.popleft() for _ in range(n))
                dropped, self.dropped = self.dropped, 0
            if not (batch or dropped):
                return
            self._send(Telemetry(batch, dropped))

    def _run(self) -> None:
        request_realtime(HELPER_PRIORITY)
        while not self._stop.wait(TELEMETRY_S):
            self._flush()

    def close(self) -> None:
        """Stop the sender and ship the rest (before the motion's result)."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._flush()

