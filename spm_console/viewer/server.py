"""The meshcat server, run as a child process bound to the loopback interface only.

``python -m spm_console.viewer.server --parent PID`` starts meshcat's ZeroMQ ↔
WebSocket bridge with both sockets on 127.0.0.1 (meshcat 0.3.2's own server
listens for HTTP on every interface), prints one JSON line
``{"zmq_url": ..., "web_url": ...}`` on stdout, then serves until it is
terminated or its parent process goes away (checked twice a second, so the
server never outlives a killed console).

Binding to 127.0.0.1 does not stop a web page from reaching the server through
DNS rebinding (a foreign name that resolves to 127.0.0.1: the browser then sends
``Host: evil.example:PORT`` and the same origin). So the tornado application that
meshcat's bridge builds (:meth:`make_app`, the bridge's own extension point) is
ours: every request whose ``Host`` is not ``127.0.0.1:PORT`` or ``localhost:PORT``
(the port it listens on) gets 403 before any handler runs — the websocket upgrade
included — and a websocket whose ``Origin`` is not one of those is refused too
(cross-site websocket hijacking). No proxy, no patch of meshcat: tornado's router
(``Application.find_handler``) is the one place every request goes through.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from collections.abc import Sequence
from typing import Any

from spm_console.system.cpus import place_beside_loop

#: The only interface the viewer listens on.
LOOPBACK = "127.0.0.1"
#: How often the server checks that its parent is alive, ms.
PARENT_POLL_MS = 500
#: Most commands in one ``batch``.
MAX_BATCH = 256
#: Commands a ``batch`` may hold.
BATCHABLE = ("set_transform", "set_property")
#: Names of the loopback interface a browser may use in the Host header (with the port).
LOOPBACK_NAMES = (LOOPBACK, "localhost")


def allowed_hosts(port: int | None) -> frozenset[str]:
    """``Host`` values (lower case, with the port) the server answers; none before it listens."""
    return frozenset() if port is None else frozenset(f"{n}:{port}" for n in LOOPBACK_NAMES)


def origin_netloc(origin: str) -> str:
    """``host:port`` of an ``Origin`` header (lower case), '' when it is not http(s)."""
    from urllib.parse import urlsplit

    try:
        parts = urlsplit(origin)
    except ValueError:
        return ""
    return parts.netloc.lower() if parts.scheme in ("http", "https") else ""


def _bridge_class() -> Any:
    import tornado.web
    from meshcat.servers import zmqserver as zs

    class LoopbackApplication(tornado.web.Application):
        """A tornado application that binds to 127.0.0.1 whatever it is asked, and answers
        only requests addressed to that interface by name (``Host``): 403 otherwise."""

        port: int | None = None
        """The port it listens on (set by a successful :meth:`listen`)."""

        def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
            server = super().listen(port, address=LOOPBACK, **kwargs)
            self.port = port
            return server

        def find_handler(self, request: Any, **kwargs: Any) -> Any:
            host = request.headers.get("Host", "").strip().lower()
            if host not in allowed_hosts(self.port):
                return self.get_handler_delegate(request, tornado.web.ErrorHandler,
                                                  {"status_code": 403})
            return super().find_handler(request, **kwargs)

    class LoopbackWebSocketHandler(zs.WebSocketHandler):
        """meshcat's websocket, refused (403) to a page from any other origin."""

        def check_origin(self, origin: str) -> bool:
            app = self.application
            return origin_netloc(origin) in allowed_hosts(getattr(app, "port", None))

    class LoopbackBridge(zs.ZMQWebSocketBridge):
        """meshcat's bridge, with its HTTP/WebSocket server on the loopback interface, and
        one command of ours: ``batch`` (frames: "batch", then type, path, data for each of
        up to :data:`MAX_BATCH` ``set_transform``/``set_property`` commands), forwarded to the
        browsers in one go and answered once — a pose change reaches the page in one burst,
        so it draws one frame for it, not one per part (software WebGL pays per frame)."""

        def handle_zmq(self, frames: list[bytes]) -> None:
            if frames and frames[0] == b"batch":
                body = frames[1:]
                if len(body) % 3 or len(body) > 3 * MAX_BATCH:
                    self.zmq_socket.send(b"error: batch frames")
                    return
                for k in range(0, len(body), 3):
                    cmd = body[k].decode("utf-8", "replace")
                    if cmd not in BATCHABLE:
                        self.zmq_socket.send(b"error: batch holds set_transform/set_property only")
                        return
                for k in range(0, len(body), 3):
                    cmd, raw_path, data = body[k].decode(), body[k + 1], body[k + 2]
                    path = [x for x in raw_path.decode("utf-8", "replace").split("/") if x]
                    self.forward_to_websockets([body[k], raw_path, data])
                    node = zs.find_node(self.tree, path)
                    if cmd == "set_transform":
                        node.transform = data
                    else:
                        node.properties.append(data)
                self.zmq_socket.send(b"ok")
                return
            super().handle_zmq(frames)

        def make_app(self) -> tornado.web.Application:
            return LoopbackApplication([
                (r"/static/(.*)", zs.StaticFileHandlerNoCache,
                 {"path": zs.VIEWER_ROOT, "default_filename": zs.VIEWER_HTML}),
                (r"/", LoopbackWebSocketHandler, {"bridge": self}),
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

    place_beside_loop()  # never on the servo loop's CPU: see spm_console.system.cpus
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
