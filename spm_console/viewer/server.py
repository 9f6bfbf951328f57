"""The meshcat server, run as a child process bound to the loopback interface only.

``python -m spm_console.viewer.server --parent PID`` starts meshcat's ZeroMQ ↔
WebSocket bridge with both sockets on 127.0.0.1 (meshcat 0.3.2's own server
listens for HTTP on every interface), prints one JSON line
``{"zmq_url": ..., "web_url": ...}`` on stdout, then serves until it is
terminated or its parent process goes away (checked twice a second, so the
server never outlives a killed console).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from collections.abc import Sequence
from typing import Any

#: The only interface the viewer listens on.
LOOPBACK = "127.0.0.1"
#: How often the server checks that its parent is alive, ms.
PARENT_POLL_MS = 500


def _bridge_class() -> Any:
    import tornado.web
    from meshcat.servers import zmqserver as zs

    class LoopbackApplication(tornado.web.Application):
        """A tornado application whose ``listen`` binds to 127.0.0.1 whatever it is asked."""

        def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
            return super().listen(port, address=LOOPBACK, **kwargs)

    class LoopbackBridge(zs.ZMQWebSocketBridge):
        """meshcat's bridge, with its HTTP/WebSocket server on the loopback interface."""

        def make_app(self) -> tornado.web.Application:
            return LoopbackApplication([
                (r"/static/(.*)", zs.StaticFileHandlerNoCache,
                 {"path": zs.VIEWER_ROOT, "default_filename": zs.VIEWER_HTML}),
                (r"/", zs.WebSocketHandler, {"bridge": self}),
            ])

    return LoopbackBridge


def _silence_stdout() -> None:
    """After the URL line nobody reads stdout: point it at /dev/null so writes never block."""
    sys.stdout.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--parent", type=int, default=0, help="exit when this process is gone")
    args = parser.parse_args(argv)
    import tornado.ioloop

    bridge = _bridge_class()(host=LOOPBACK)
    sys.stdout.write(json.dumps({"zmq_url": bridge.zmq_url, "web_url": bridge.web_url}) + "\n")
    _silence_stdout()
    loop = tornado.ioloop.IOLoop.current()

    loop.asyncio_loop.add_signal_handler(signal.SIGTERM, loop.stop)  # type: ignore[attr-defined]
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C in the console is the console's business

    def check_parent() -> None:
        if args.parent and os.getppid() != args.parent:
            loop.stop()

    tornado.ioloop.PeriodicCallback(check_parent, PARENT_POLL_MS).start()
    loop.start()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
