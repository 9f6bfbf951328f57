"""The 3D viewer's server as a helper child (:mod:`spm_console.system.childproc`):
:class:`ViewerServer` is the loopback meshcat server (:mod:`spm_console.viewer.server`); it
fails with :class:`~spm_console.system.childproc.HelperProcessError`.
"""

from __future__ import annotations

from dataclasses import dataclass

from spm_console.system.childproc import START_TIMEOUT_S, ChildProcess, HelperProcessError


@dataclass(frozen=True)
class ViewerUrls:
    zmq_url: str
    """Where drawing commands go (tcp://127.0.0.1:…)."""
    web_url: str
    """What the operator opens in a browser (http://127.0.0.1:…/static/)."""


class ViewerServer(ChildProcess):
    """The meshcat server child (bound to 127.0.0.1)."""

    def __init__(self) -> None:
        super().__init__("spm_console.viewer.server", what="3D viewer")
        self.urls: ViewerUrls | None = None

    def start_server(self, timeout_s: float = START_TIMEOUT_S) -> ViewerUrls:
        if self.urls is not None and self.running:
            return self.urls
        data = self.start(timeout_s=timeout_s)
        try:
            self.urls = ViewerUrls(str(data["zmq_url"]), str(data["web_url"]))
        except KeyError:
            self.stop()
            raise HelperProcessError(f"3D viewer said {data!r}, not its URLs") from None
        return self.urls
