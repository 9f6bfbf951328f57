"""The wrist view behind one small interface: meshcat in a browser, or nothing (``--no-viewer``).

Two wrists are drawn, and never confused (:mod:`spm_console.viewer.draw`):

- the **measured** pose (:meth:`WristView.show_theta`), opaque, labelled "measured":
  only ever where the servos say the wrist is; hidden, with "measured pose unknown"
  in its place, before the first reading, after ``show_theta(None)`` and when a reading
  cannot be assembled;
- a **target** pose (:meth:`WristView.show_target`, :meth:`WristView.show_plan`), a
  translucent ghost labelled "target": a plan's goal, an FK/IK or workspace result;

plus the planned path (:meth:`WristView.show_path`, the platform normal's tip) and a
"leg i" label by each motor.

Callers (the TUI, the executor's telemetry) call these as often as they like from any
thread; :class:`MeshcatView` keeps only the latest request of each kind and sends at
most one frame per ``min_interval_s`` from its own thread, so nobody ever waits for the
browser. Orientations are found by continuation FK (the unique solution): the
measured pose from the last measured one, a target from the measured pose, a plan's
path and goal along the path.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import Pose, SpmModel
from spm_console.formatting import fmt_deg
from spm_console.system.childproc import HelperProcessError
from spm_console.viewer import draw, scene
from spm_console.viewer.process import ViewerServer

if TYPE_CHECKING:
    from spm_console.viewer.client import MeshcatClient

F = NDArray[np.float64]

#: Default minimum time between two drawn frames, s (10 frames per second).
MIN_INTERVAL_S = 0.1


class WristView(Protocol):
    """What the console needs from a 3D view. Every call returns at once."""

    @property
    def url(self) -> str | None:
        """Where to look at it (None: no view)."""
        ...

    def show_theta(self, theta_deg: F | None) -> None:
        """The **measured** motor angles θ (deg), drawn solid; None: the measured pose is
        unknown (not connected, no reply), so the solid wrist is hidden. Never pass a
        computed or wished-for pose here: that is :meth:`show_target`."""
        ...

    def show_target(self, theta_deg: F | None) -> None:
        """A pose the wrist is not known to be in (θ, deg) as a translucent ghost; None:
        no ghost."""
        ...

    def show_path(self, theta_path_deg: F | None) -> None:
        """Preview a path: rows of θ (deg); None: no path."""
        ...

    def show_plan(self, theta_path_deg: F | None) -> None:
        """A plan: its path (:meth:`show_path`) and its last row as the ghost
        (:meth:`show_target`); None clears both."""
        ...

    def clear_path(self) -> None:
        """Same as ``show_plan(None)``: no path, no ghost (a failed or discarded plan)."""
        ...

    def close(self) -> None:
        ...


class NullView:
    """No 3D view (``--no-viewer``): every request is accepted and ignored."""

    url: str | None = None

    def show_theta(self, theta_deg: F | None) -> None:
        pass

    def show_target(self, theta_deg: F | None) -> None:
        pass

    def show_path(self, theta_path_deg: F | None) -> None:
        pass

    def show_plan(self, theta_path_deg: F | None) -> None:
        pass

    def clear_path(self) -> None:
        pass

    def close(self) -> None:
        pass


@dataclass(frozen=True)
class _Request:
    """One pending request: draw ``value`` (None: hide that part)."""

    value: F | None
    along_path: bool = False
    """For a target: take the pose reached along the path requested with it."""


def _rows(theta_deg: F | None, ndim: int) -> F | None:
    if theta_deg is None:
        return None
    a = np.asarray(theta_deg, float).copy()
    return np.atleast_2d(a) if ndim == 2 else a


class MeshcatView:
    """A meshcat server child plus a sender thread that draws the latest requests."""

    def __init__(self, profile: Profile, min_interval_s: float = MIN_INTERVAL_S) -> None:
        self.model: SpmModel = model_of(profile)
        self.links: LinkModel = link_model_of(profile)
        self.parts = scene.wrist_parts(self.model, self.links)
        self.min_interval_s = min_interval_s
        self.server = ViewerServer()
        self._client: MeshcatClient | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._measured: _Request | None = None
        self._target: _Request | None = None
        self._path: _Request | None = None
        self._stop = False
        self._sending = False
        self._thread: threading.Thread | None = None
        self._seed: tuple[F, F] = (np.asarray(self.model.theta_home, float), np.eye(3))
        """Last measured pose drawn (θ rad, R), where the next measured FK starts."""
        self._path_end: Pose | None = None
        self._visible = {draw.MEASURED.root: False, draw.TARGET.root: False}
        self.frames = 0
        """Measured poses drawn so far."""
        self.last_error = ""
        """Last problem met while drawing (empty when fine)."""
        self.drawn_theta_deg: F | None = None
        """θ of the measured pose on screen, deg (None: hidden, the pose is unknown)."""
        self.target_theta_deg: F | None = None
        """θ of the ghost on screen, deg (None: no ghost)."""
        self.path_rows = 0
        """Rows of the path on screen (0: none)."""

    @property
    def url(self) -> str | None:
        return self.server.urls.web_url if self.server.urls else None

    def start(self) -> str:
        """Start the server, send the scene (the measured pose unknown until
        :meth:`show_theta`); returns the URL (blocking, ~1 s)."""
        from spm_console.viewer.client import MeshcatClient

        urls = self.server.start_server()
        client = MeshcatClient(urls.zmq_url)
        self._client = client
        try:
            draw.build_scene(client, self.parts)
        except HelperProcessError:
            self.close()
            raise
        self._thread = threading.Thread(target=self._run, name="meshcat-view", daemon=True)
        self._thread.start()
        return urls.web_url

    # ----------------------------------------------------------------- requests
    def show_theta(self, theta_deg: F | None) -> None:
        self._request("_measured", _Request(_rows(theta_deg, 1)))

    def show_target(self, theta_deg: F | None) -> None:
        self._request("_target", _Request(_rows(theta_deg, 1)))

    def show_path(self, theta_path_deg: F | None) -> None:
        self._request("_path", _Request(_rows(theta_path_deg, 2)))

    def show_plan(self, theta_path_deg: F | None) -> None:
        path = _rows(theta_path_deg, 2)
        with self._lock:
            self._path = _Request(path)
            self._target = _Request(None if path is None else path[-1], along_path=True)
        self._wake.set()

    def clear_path(self) -> None:
        self.show_plan(None)

    def _request(self, slot: str, request: _Request) -> None:
        with self._lock:
            setattr(self, slot, request)
        self._wake.set()

    def wait_idle(self, timeout_s: float = 5.0) -> bool:
        """Block until every request so far has been drawn (tests, benchmarks)."""
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            with self._lock:
                busy = (self._measured is not None or self._target is not None
                        or self._path is not None or self._wake.is_set() or self._sending)
            if not busy:
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
                measured, self._measured = self._measured, None
                target, self._target = self._target, None
                path, self._path = self._path, None
                self._sending = True
            client = self._client
            try:
                if client is None:
                    continue
                self.last_error = ""
                with client.batch():  # one burst to the browser: one frame drawn for it
                    if measured is not None:
                        self._draw_measured(client, measured.value)
                    if path is not None:
                        self._draw_path(client, path.value)
                    if target is not None:
                        self._draw_target(client, target)
            except HelperProcessError as exc:
                self.last_error = exc.message
            except Exception as exc:  # the view must outlive one bad request
                self.last_error = f"3D view: {type(exc).__name__}: {exc}"
            finally:
                self._sending = False
                last = time.monotonic()

    def _solve(self, theta_deg: F, seed: tuple[F, F] | None) -> Pose | None:
        """Continuation FK of θ (deg) from ``seed`` (θ rad, R), then from home."""
        if theta_deg.shape != (3,) or not np.all(np.isfinite(theta_deg)):
            self.last_error = f"cannot draw θ = {theta_deg.tolist()}°: not three numbers"
            return None
        th = np.radians(theta_deg)
        r = self.model.track(th, *seed) if seed is not None else self.model.track(th)
        if (not r.ok or r.pose is None) and seed is not None:
            r = self.model.track(th)  # the seed may be on the other side of a bad path
        if not r.ok or r.pose is None:
            self.last_error = f"cannot draw θ = {fmt_deg(theta_deg)}: {r.reason}"
            return None
        return r.pose

    def _set_visible(self, client: MeshcatClient, look: draw.Look, visible: bool) -> None:
        if self._visible[look.root] != visible:
            client.set_property(look.root, "visible", visible)
            if look is draw.MEASURED:
                client.set_property("labels/unknown", "visible", not visible)
            self._visible[look.root] = visible

    def _draw_measured(self, client: MeshcatClient, theta_deg: F | None) -> None:
        pose = None if theta_deg is None else self._solve(theta_deg, self._seed)
        if pose is None:  # unknown, or not a pose the wrist can be in: show nothing
            self._set_visible(client, draw.MEASURED, False)
            self.drawn_theta_deg = None
            return
        self._seed = (pose.theta, pose.R)
        draw.draw_pose(client, draw.MEASURED,
                       scene.pose_transforms(self.model, self.links, pose.theta, pose.R))
        self._set_visible(client, draw.MEASURED, True)
        self.frames += 1
        self.drawn_theta_deg = np.degrees(pose.theta)

    def _measured_seed(self) -> tuple[F, F] | None:
        return self._seed if self.drawn_theta_deg is not None else None

    def _draw_target(self, client: MeshcatClient, request: _Request) -> None:
        pose = None
        if request.value is not None:
            pose = self._path_end if request.along_path else None
            if pose is None:
                pose = self._solve(request.value, self._measured_seed())
        if pose is None:
            self._set_visible(client, draw.TARGET, False)
            self.target_theta_deg = None
            return
        draw.draw_pose(client, draw.TARGET,
                       scene.pose_transforms(self.model, self.links, pose.theta, pose.R))
        self._set_visible(client, draw.TARGET, True)
        self.target_theta_deg = np.degrees(pose.theta)

    def _draw_path(self, client: MeshcatClient, path_deg: F | None) -> None:
        self._path_end = None
        normals: list[F] = []
        if path_deg is not None and len(path_deg):
            pose = self._solve(path_deg[0], self._measured_seed())
            rows = iter(path_deg[1:])
            while pose is not None:
                normals.append(pose.n)
                row = next(rows, None)
                if row is None:
                    self._path_end = pose
                    break
                r = self.model.track(np.radians(row), pose.theta, pose.R)
                pose = r.pose if r.ok else None
            if self._path_end is None:
                self.last_error = f"the path preview stops after {len(normals)} of " \
                                  f"{len(path_deg)} rows: FK lost the pose"
        if len(normals) < 2:
            client.delete("path")
            self.path_rows = 0
            return
        draw.draw_path(client, np.asarray(normals), self.parts.distal_reach)
        self.path_rows = len(normals)


