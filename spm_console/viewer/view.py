"""The wrist view behind one small interface: meshcat in a browser, or nothing (``--no-viewer``).

Callers (the TUI, the executor's telemetry) call :meth:`WristView.show_theta`
as often as they like from any thread; :class:`MeshcatView` keeps only the
latest request and sends at most one frame per ``min_interval_s`` from its own
thread, so nobody ever waits for the browser. Orientations for measured θ are
found by continuation FK from the last drawn pose (the unique solution, SPEC §3).
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics import SpmModel
from spm_console.core.links import LinkModel
from spm_console.models import link_model_of, model_of
from spm_console.profile import Profile
from spm_console.viewer import scene
from spm_console.viewer.process import ViewerError, ViewerServer

if TYPE_CHECKING:
    from spm_console.viewer.client import MeshcatClient

F = NDArray[np.float64]

#: Default minimum time between two drawn frames, s (10 frames per second).
MIN_INTERVAL_S = 0.1


class WristView(Protocol):
    """What the console needs from a 3D view."""

    @property
    def url(self) -> str | None:
        """Where to look at it (None: no view)."""
        ...

    def show_theta(self, theta_deg: F) -> None:
        """Draw the wrist at motor angles θ (deg); returns at once (throttled)."""
        ...

    def show_path(self, theta_path_deg: F) -> None:
        """Preview a planned path: rows of θ (deg)."""
        ...

    def clear_path(self) -> None:
        ...

    def close(self) -> None:
        ...


class NullView:
    """No 3D view (``--no-viewer``)."""

    url: str | None = None

    def show_theta(self, theta_deg: F) -> None:
        pass

    def show_path(self, theta_path_deg: F) -> None:
        pass

    def clear_path(self) -> None:
        pass

    def close(self) -> None:
        pass


_LEG_COLORS = (0xD1495B, 0x2E86AB, 0xEDAE49)
_PATH_COLOR = 0xFF00FF


class MeshcatView:
    """A meshcat server child plus a sender thread that draws the latest requested pose."""

    def __init__(self, profile: Profile, min_interval_s: float = MIN_INTERVAL_S) -> None:
        self.model: SpmModel = model_of(profile)
        self.links: LinkModel = link_model_of(profile)
        self.parts = scene.wrist_parts(self.model, self.links)
        self.min_interval_s = min_interval_s
        self.server = ViewerServer()
        self._client: MeshcatClient | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._pending_theta: F | None = None
        self._pending_path: F | None = None
        self._clear_path = False
        self._stop = False
        self._thread: threading.Thread | None = None
        self._theta = np.asarray(self.model.theta_home, float)
        self._R = np.eye(3)
        self.frames = 0
        """Poses drawn so far."""
        self.last_error = ""
        """Last problem met while drawing (empty when fine)."""
        self.drawn_theta_deg: F = np.degrees(self._theta)
        """θ of the pose on screen, deg."""

    @property
    def url(self) -> str | None:
        return self.server.urls.web_url if self.server.urls else None

    def start(self) -> str:
        """Start the server, draw the wrist at home; returns the URL (blocking, ~1 s)."""
        from spm_console.viewer.client import MeshcatClient

        urls = self.server.start_server()
        client = MeshcatClient(urls.zmq_url)
        self._client = client
        try:
            self._build(client)
            self._draw(client, self._theta, self._R)
        except ViewerError:
            self.close()
            raise
        self._thread = threading.Thread(target=self._run, name="meshcat-view", daemon=True)
        self._thread.start()
        return urls.web_url

    # ----------------------------------------------------------------- requests
    def show_theta(self, theta_deg: F) -> None:
        with self._lock:
            self._pending_theta = np.asarray(theta_deg, float).copy()
        self._wake.set()

    def show_path(self, theta_path_deg: F) -> None:
        with self._lock:
            self._pending_path = np.atleast_2d(np.asarray(theta_path_deg, float)).copy()
            self._clear_path = False
        self._wake.set()

    def clear_path(self) -> None:
        with self._lock:
            self._pending_path = None
            self._clear_path = True
        self._wake.set()

    def wait_idle(self, timeout_s: float = 5.0) -> bool:
        """Block until every request so far has been drawn (tests, benchmarks)."""
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            with self._lock:
                busy = (self._pending_theta is not None or self._pending_path is not None
                        or self._clear_path or self._wake.is_set())
            if not busy and not self._sending:
                return True
            time.sleep(0.01)
        return False

    def close(self) -> None:
        """Stop the sender thread and the server (idempotent)."""
        self._stop = True
        self._wake.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        client, self._client = self._client, None
        if client is not None:
            client.close()
        self.server.stop()

    # ------------------------------------------------------------------ drawing
    _sending = False

    def _run(self) -> None:
        last = 0.0
        while not self._stop:
            self._wake.wait()
            if self._stop:
                break
            wait = last + self.min_interval_s - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            with self._lock:
                self._wake.clear()
                theta, self._pending_theta = self._pending_theta, None
                path, self._pending_path = self._pending_path, None
                clear, self._clear_path = self._clear_path, False
                self._sending = True
            client = self._client
            try:
                if client is None:
                    continue
                self.last_error = ""
                if clear:
                    client.delete("path")
                if path is not None:
                    self._draw_path(client, path)
                if theta is not None:
                    self._update_theta(client, theta)
            except ViewerError as exc:
                self.last_error = exc.message
            finally:
                self._sending = False
                last = time.monotonic()

    def _update_theta(self, client: MeshcatClient, theta_deg: F) -> None:
        th = np.radians(theta_deg)
        r = self.model.track(th, self._theta, self._R)
        if not r.ok or r.pose is None:
            # retry from home (the last drawn pose may be on the other side of a bad path)
            r = self.model.track(th)
        if not r.ok or r.pose is None:
            self.last_error = f"cannot draw θ = {np.round(theta_deg, 2).tolist()}°: {r.reason}"
            return
        self._theta, self._R = r.pose.theta, r.pose.R
        self._draw(client, self._theta, self._R)

    def _draw(self, client: MeshcatClient, theta: F, R: F) -> None:
        for name, T in scene.pose_transforms(self.model, self.links, theta, R).items():
            client.set_transform(name, T)
        self.frames += 1
        self.drawn_theta_deg = np.degrees(theta)

    def _draw_path(self, client: MeshcatClient, path_deg: F) -> None:
        import meshcat.geometry as g

        normals = []
        t, R = self.model.theta_home, np.eye(3)
        for row in np.radians(path_deg):
            r = self.model.track(row, t, R)
            if not r.ok or r.pose is None:
                break
            t, R = r.pose.theta, r.pose.R
            normals.append(r.pose.n)
        if len(normals) < 2:
            return
        pts = scene.normal_tip_path(np.asarray(normals), self.parts.distal_reach)
        line = g.Line(g.PointsGeometry(pts), g.LineBasicMaterial(color=_PATH_COLOR, linewidth=3))
        client.set_object("path", line)

    def _build(self, client: MeshcatClient) -> None:
        """Send every part's geometry once (the server keeps them for late browsers)."""
        import meshcat.geometry as g

        c = client
        p = self.parts
        grey = g.MeshLambertMaterial(color=0x8C8C8C)
        base = g.TriangularMeshGeometry(p.base_points, np.array([[0, 1, 2], [0, 2, 1]]))
        c.set_object("base/plate", base, grey)
        for i in range(3):
            u = p.u[i]
            motor = g.Cylinder(0.04, radius=1.3 * p.delta)
            c.set_object(f"base/motor{i + 1}", motor, grey)
            c.set_transform(
                f"base/motor{i + 1}", scene.transform(scene.align_y(u), p.base_points[i] + 0.02 * u)
            )
            mat = g.MeshLambertMaterial(color=_LEG_COLORS[i])
            for s in scene.DRAWN_SEGMENTS:
                L = p.segment_length[s]
                name = f"legs/leg{i + 1}/{s}"
                c.set_object(f"{name}/body", g.Cylinder(L, radius=p.delta), mat)
                for k, y in (("end0", -L / 2), ("end1", L / 2)):
                    c.set_object(f"{name}/{k}", g.Sphere(p.delta), mat)
                    c.set_transform(f"{name}/{k}", scene.transform(np.eye(3), np.array([0, y, 0])))
            self._axis(c, f"axes/u{i + 1}", p.proximal_reach, 0x333333)
            c.set_transform(f"axes/u{i + 1}", scene.transform(scene.align_y(u), np.zeros(3)))
            self._axis(c, f"axes/w{i + 1}", p.proximal_reach, _LEG_COLORS[i])
            self._axis(c, f"platform/v{i + 1}", p.distal_reach, _LEG_COLORS[i])
            c.set_transform(
                f"platform/v{i + 1}", scene.transform(scene.align_y(p.v_home[i]), np.zeros(3))
            )
        plate = g.TriangularMeshGeometry(p.plate_points, np.array([[0, 1, 2], [0, 2, 1]]))
        c.set_object("platform/plate", plate, g.MeshLambertMaterial(color=0xF2F2F2, opacity=0.85))
        c.set_object("platform/frame", g.triad(0.6 * p.distal_reach))
        n_home = p.v_home.sum(0) / np.linalg.norm(p.v_home.sum(0))
        self._axis(c, "platform/normal", p.distal_reach, 0x000000)
        c.set_transform("platform/normal", scene.transform(scene.align_y(n_home), np.zeros(3)))
        c.set_property("/Cameras/default/rotated/<object>", "position", [0.3, 0.2, 0.3])
        c.set_property("/Axes", "visible", False)  # the world axes are 0.5 m long: clutter

    @staticmethod
    def _axis(c: MeshcatClient, name: str, length: float, color: int) -> None:
        """A thin line from the origin along the frame's y axis (oriented by its transform)."""
        import meshcat.geometry as g

        pts = np.array([[0.0, 0.0], [0.0, length], [0.0, 0.0]], dtype=np.float32)
        c.set_object(name, g.Line(g.PointsGeometry(pts), g.LineBasicMaterial(color=color)))


def make_view(profile: Profile, enabled: bool = True) -> MeshcatView | NullView:
    """The meshcat view when ``enabled`` (not started yet: call ``start()``), else a NullView."""
    return MeshcatView(profile) if enabled else NullView()
