"""Start and stop the loopback meshcat server (:mod:`spm_console.viewer.server`) as a child.

The child is stopped by :meth:`ViewerServer.stop` (called by the console on exit
and on SIGTERM, and registered with :mod:`atexit`); if the console is killed
outright the child notices its parent is gone and exits by itself.
"""

from __future__ import annotations

import atexit
import json
import os
import subprocess
import sys
import threading
from dataclasses import dataclass

from spm_console.errors import SpmError

#: Seconds to wait for the server to report its URLs.
START_TIMEOUT_S = 15.0


class ViewerError(SpmError):
    """The 3D viewer could not be started (the console keeps working without it)."""


@dataclass(frozen=True)
class ViewerUrls:
    zmq_url: str
    """Where drawing commands go (tcp://127.0.0.1:…)."""
    web_url: str
    """What the operator opens in a browser (http://127.0.0.1:…/static/)."""


class ViewerServer:
    """One meshcat server child process."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen[bytes] | None = None
        self.urls: ViewerUrls | None = None

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def start(self, timeout_s: float = START_TIMEOUT_S) -> ViewerUrls:
        """Spawn the server and wait for its URLs (blocking: call from a worker thread)."""
        if self.urls is not None and self.running:
            return self.urls
        cmd = [sys.executable, "-u", "-m", "spm_console.viewer.server", "--parent", str(os.getpid())]
        self._proc = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            start_new_session=True,  # Ctrl-C in the terminal does not reach it; we stop it
        )
        atexit.register(self.stop)
        line = self._read_line(timeout_s)
        try:
            data = json.loads(line)
            self.urls = ViewerUrls(str(data["zmq_url"]), str(data["web_url"]))
        except (ValueError, KeyError, TypeError):
            self.stop()
            raise ViewerError(f"3D viewer did not start (said {line[:200]!r})") from None
        return self.urls

    def _read_line(self, timeout_s: float) -> str:
        assert self._proc is not None and self._proc.stdout is not None
        out: list[bytes] = []
        reader = threading.Thread(target=lambda: out.append(self._proc.stdout.readline()),  # type: ignore[union-attr]
                                  daemon=True)
        reader.start()
        reader.join(timeout_s)
        if not out:
            self.stop()
            raise ViewerError(f"3D viewer did not start within {timeout_s:.0f} s")
        return out[0].decode("utf-8", "replace").strip()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Terminate the child (then kill it if it lingers); safe to call twice."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout_s)
        if proc.stdout is not None:
            proc.stdout.close()
        atexit.unregister(self.stop)
