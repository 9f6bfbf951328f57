"""A small meshcat client: drawing commands over ZeroMQ with timeouts.

meshcat's own ``Visualizer`` pulls in IPython and PIL and blocks forever when the
server is gone; this client sends the same commands (``meshcat.commands``,
msgpack-encoded, three frames) and gives up after a timeout instead.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import umsgpack
import zmq
from meshcat.commands import Delete, SetObject, SetProperty, SetTransform
from meshcat.path import Path

from spm_console.system.childproc import HelperProcessError

#: Reply timeout of one command, ms.
REPLY_TIMEOUT_MS = 2000


def path_of(name: str) -> Path:
    """meshcat path /meshcat/<name>; a name starting with '/' is absolute (e.g. /Cameras/…)."""
    parts = [p for p in name.split("/") if p]
    return Path(tuple(parts) if name.startswith("/") else ("meshcat", *parts))


class MeshcatClient:
    """REQ socket to the server; one command at a time, from one thread."""

    def __init__(self, zmq_url: str, timeout_ms: int = REPLY_TIMEOUT_MS) -> None:
        self.zmq_url = zmq_url
        self.timeout_ms = timeout_ms
        self._ctx = zmq.Context()
        self._sock = self._connect()
        self._batch: list[bytes] | None = None
        self.sent = 0
        """Commands acknowledged by the server."""

    def _connect(self) -> zmq.Socket[Any]:
        s = self._ctx.socket(zmq.REQ)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
        s.setsockopt(zmq.SNDTIMEO, self.timeout_ms)
        s.connect(self.zmq_url)
        return s

    def _send(self, command: Any) -> None:
        data = command.lower()
        frames = [data["type"].encode(), data["path"].encode(), umsgpack.packb(data)]
        if self._batch is not None and data["type"] in ("set_transform", "set_property"):
            self._batch.extend(frames)
            return
        self._exchange(frames)

    @contextlib.contextmanager
    def batch(self) -> Iterator[None]:
        """Transforms and properties sent inside the block go to the browser in one burst
        (one frame drawn for all of them); sent when the block ends."""
        self._batch = []
        try:
            yield
            frames, self._batch = self._batch, None
            if frames:
                self._exchange([b"batch", *frames], count=len(frames) // 3)
        finally:
            self._batch = None

    def _exchange(self, frames: list[bytes], count: int = 1) -> None:
        try:
            self._sock.send_multipart(frames)
            reply = self._sock.recv()
        except zmq.ZMQError as exc:
            # a REQ socket is unusable after a missed reply: start a fresh one
            self._sock.close(0)
            self._sock = self._connect()
            raise HelperProcessError(f"3D viewer did not answer ({exc})") from None
        if reply != b"ok" and frames[0] == b"batch":
            raise HelperProcessError(f"3D viewer refused a batch: {reply.decode('utf-8', 'replace')}")
        self.sent += count

    def set_object(self, name: str, geometry: Any, material: Any = None) -> None:
        self._send(SetObject(geometry, material, path_of(name)))

    def set_transform(self, name: str, matrix: np.ndarray) -> None:
        self._send(SetTransform(np.asarray(matrix, float), path_of(name)))

    def set_property(self, name: str, key: str, value: Any) -> None:
        self._send(SetProperty(key, value, path_of(name)))

    def delete(self, name: str) -> None:
        self._send(Delete(path_of(name)))

    def close(self) -> None:
        self._sock.close(0)
        self._ctx.term()
