"""The meshcat view without a browser: parts from the link model, throttled latest-wins
drawing, loopback-only server that refuses foreign Host / Origin (DNS rebinding), and no
server left behind (close, killed parent)."""

from __future__ import annotations

import http.client
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import numpy as np
import pytest

from spm_console.config.models import link_model_of, model_of
from spm_console.viewer import scene
from tests.support.net_helpers import listening
from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT


def test_capsules_sit_on_the_link_points(agile) -> None:
    model, links = model_of(agile), link_model_of(agile)
    r = model.track(np.radians([95.0, 110.0, 105.0]))
    assert r.ok and r.pose is not None
    T = scene.pose_transforms(model, links, r.pose.theta, r.pose.R)
    pts = links.points(model.u, model.geom.w(r.pose.theta), r.pose.v)
    parts = scene.wrist_parts(model, links)
    for i in range(3):
        for s in scene.DRAWN_SEGMENTS:
            a, b = scene.SEGMENT_ENDS[s]
            M = T[f"legs/leg{i + 1}/{s}"]
            half = 0.5 * parts.segment_length[s] * np.array([0.0, 1.0, 0.0])
            ends = [M[:3, :3] @ (-half) + M[:3, 3], M[:3, :3] @ half + M[:3, 3]]
            np.testing.assert_allclose(ends[0], pts[a][i] * scene.MM, atol=1e-9)
            np.testing.assert_allclose(ends[1], pts[b][i] * scene.MM, atol=1e-9)
            np.testing.assert_allclose(M[:3, :3].T @ M[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(T["platform"][:3, :3], r.pose.R)
    assert parts.delta == pytest.approx(agile.links.delta_mm * 1e-3)


def test_drawing_is_throttled_and_keeps_the_latest_pose(agile) -> None:
    from spm_console.viewer.view import MeshcatView

    v = MeshcatView(agile, min_interval_s=0.1)
    v.start()
    try:
        port = int(v.url.rsplit(":", 1)[1].split("/")[0])  # type: ignore[union-attr]
        assert v.url.startswith("http://127.0.0.1:")  # type: ignore[union-attr]
        assert listening(port) and all(a == "0100007F" for a in listening(port))
        assert v.drawn_theta_deg is None  # nothing measured yet: no solid wrist
        frames0 = v.frames
        t0 = time.monotonic()
        path = np.linspace([135.0, 135.0, 135.0], [95.0, 110.0, 105.0], 200)
        for th in path:  # 200 requests as fast as possible (a telemetry burst)
            v.show_theta(th)
        assert time.monotonic() - t0 < 0.2  # callers never wait for the viewer
        assert v.wait_idle(10.0)
        elapsed = time.monotonic() - t0
        drawn = v.frames - frames0
        assert 1 <= drawn <= elapsed / 0.1 + 2
        np.testing.assert_allclose(v.drawn_theta_deg, path[-1])  # the latest wins
        assert v.last_error == ""
    finally:
        v.close()
    time.sleep(0.2)
    assert not listening(port)


def test_an_unreachable_or_missing_pose_is_reported_not_drawn(agile) -> None:
    from spm_console.viewer.view import MeshcatView

    v = MeshcatView(agile, min_interval_s=0.01)
    v.start()
    try:
        v.show_theta(np.array([135.0, 135.0, 135.0]))
        assert v.wait_idle(10.0)
        np.testing.assert_allclose(v.drawn_theta_deg, [135, 135, 135])  # type: ignore[arg-type]
        v.show_theta(np.array([65.0, 155.0, 65.0]))
        assert v.wait_idle(10.0)
        assert "cannot draw" in v.last_error
        # the last good pose is not left on screen as if the wrist were still there
        assert v.drawn_theta_deg is None
        v.show_theta(np.array([np.nan, 135.0, 135.0]))  # no reply from servo 1
        assert v.wait_idle(10.0)
        assert "cannot draw" in v.last_error and v.drawn_theta_deg is None
        v.show_theta(np.array([95.0, 110.0, 105.0]))  # the view is still alive
        assert v.wait_idle(10.0) and v.last_error == ""
        np.testing.assert_allclose(v.drawn_theta_deg, [95, 110, 105])  # type: ignore[arg-type]
    finally:
        v.close()


def test_a_target_or_plan_never_moves_the_measured_wrist(agile) -> None:
    from spm_console.viewer.view import MeshcatView

    v = MeshcatView(agile, min_interval_s=0.01)
    v.start()
    try:
        home = np.array([135.0, 135.0, 135.0])
        goal = np.array([95.0, 110.0, 105.0])
        v.show_theta(home)
        path = np.linspace(home, goal, 40)
        v.show_plan(path)  # what the plan screen does after a solve
        assert v.wait_idle(10.0) and v.last_error == ""
        np.testing.assert_allclose(v.drawn_theta_deg, home)  # type: ignore[arg-type]
        np.testing.assert_allclose(v.target_theta_deg, goal)  # type: ignore[arg-type]
        assert v.path_rows == len(path)
        v.show_target(goal + 5.0)  # e.g. an FK result: only the ghost moves
        assert v.wait_idle(10.0) and v.last_error == ""
        np.testing.assert_allclose(v.drawn_theta_deg, home)  # type: ignore[arg-type]
        np.testing.assert_allclose(v.target_theta_deg, goal + 5.0)  # type: ignore[arg-type]
        v.show_theta(goal)  # the wrist got there: only the solid wrist moves
        assert v.wait_idle(10.0)
        np.testing.assert_allclose(v.drawn_theta_deg, goal)  # type: ignore[arg-type]
        np.testing.assert_allclose(v.target_theta_deg, goal + 5.0)  # type: ignore[arg-type]
        v.show_plan(path)
        v.show_theta(None)  # e.g. disconnected
        assert v.wait_idle(10.0)
        assert v.target_theta_deg is not None and v.path_rows and v.drawn_theta_deg is None
        v.clear_path()  # e.g. a failed solve: neither the old path nor its goal stays
        assert v.wait_idle(10.0)
        assert v.target_theta_deg is None and v.path_rows == 0
    finally:
        v.close()


def test_null_view_answers_every_request_of_the_protocol() -> None:
    from spm_console.viewer.view import NullView, WristView

    wanted = {n for n in vars(WristView) if not n.startswith("_")}
    assert wanted <= set(dir(NullView))
    v: WristView = NullView()
    theta = np.array([135.0, 135.0, 135.0])
    v.show_theta(theta)
    v.show_theta(None)
    v.show_target(theta)
    v.show_target(None)
    v.show_path(np.atleast_2d(theta))
    v.show_path(None)
    v.show_plan(np.atleast_2d(theta))
    v.show_plan(None)
    v.clear_path()
    assert v.url is None
    v.close()


PARENT = """
import json, sys, time
from spm_console.config.load import load_profile
from spm_console.viewer.view import MeshcatView
v = MeshcatView(load_profile("profiles/agile_wrist.toml"))
url = v.start()
print(json.dumps({"url": url, "server": v.server.pid}), flush=True)
time.sleep(600)
"""


def test_server_does_not_outlive_a_killed_console() -> None:
    p = subprocess.Popen([sys.executable, "-c", PARENT], cwd=ROOT, stdout=subprocess.PIPE,
                         text=True)
    try:
        info = json.loads(p.stdout.readline())  # type: ignore[union-attr]
        port = int(info["url"].rsplit(":", 1)[1].split("/")[0])
        assert listening(port)
        os.kill(p.pid, signal.SIGKILL)  # no atexit, no cleanup: the child must notice
        p.wait(5)
        t_end = time.monotonic() + 5
        while listening(port) and time.monotonic() < t_end:
            time.sleep(0.05)
        assert not listening(port)
        with pytest.raises(ProcessLookupError):
            for _ in range(50):
                os.kill(info["server"], 0)
                time.sleep(0.05)
    finally:
        if p.poll() is None:
            p.kill()


@pytest.fixture(scope="module")
def server_port() -> Iterator[int]:
    from spm_console.viewer.process import ViewerServer

    srv = ViewerServer()
    url = srv.start_server().web_url
    try:
        yield int(url.rsplit(":", 1)[1].split("/")[0])
    finally:
        srv.stop()


WS_UPGRADE = {"Upgrade": "websocket", "Connection": "Upgrade", "Sec-WebSocket-Version": "13",
              "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="}


def _status(port: int, host: str, path: str = "/static/", **headers: str) -> int:
    """Status of one GET to 127.0.0.1:port carrying exactly this Host header."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        conn.putrequest("GET", path, skip_host=True)
        conn.putheader("Host", host)
        for k, v in headers.items():
            conn.putheader(k, v)
        conn.endheaders()
        return conn.getresponse().status
    finally:
        conn.close()


def test_the_page_answers_only_to_its_loopback_name(server_port: int) -> None:
    p = server_port
    assert _status(p, f"127.0.0.1:{p}") == 200
    assert _status(p, f"LOCALHOST:{p}") == 200  # host names are case-insensitive
    # DNS rebinding: a foreign name resolving to 127.0.0.1, the page's own origin
    assert _status(p, f"evil.example:{p}", Origin=f"http://evil.example:{p}") == 403
    assert _status(p, "evil.example") == 403
    assert _status(p, f"127.0.0.1:{p + 1}") == 403  # another port: not this server's name
    assert _status(p, f"evil.example:{p}", "/static/index.html") == 403
    assert _status(p, f"evil.example:{p}", "/no/such/page") == 403  # before any routing


def test_the_websocket_is_refused_to_a_foreign_host_or_origin(server_port: int) -> None:
    p = server_port
    evil = f"http://evil.example:{p}"
    assert _status(p, f"evil.example:{p}", "/", Origin=evil, **WS_UPGRADE) == 403  # rebinding
    assert _status(p, f"127.0.0.1:{p}", "/", Origin=evil, **WS_UPGRADE) == 403  # cross-site
    assert _status(p, f"127.0.0.1:{p}", "/", Origin="null", **WS_UPGRADE) == 403
    assert _status(p, f"127.0.0.1:{p}", "/", Origin=f"http://127.0.0.1:{p}", **WS_UPGRADE) == 101
    assert _status(p, f"localhost:{p}", "/", Origin=f"http://localhost:{p}", **WS_UPGRADE) == 101


def test_a_batch_goes_out_in_one_burst_and_bad_batches_are_refused() -> None:
    """One reply for a whole pose; the bridge's scene (what a page opened later receives)
    holds the batched transforms; anything but transforms and properties is refused."""
    import umsgpack
    import zmq
    from meshcat.commands import SetObject, SetTransform
    from meshcat.geometry import Box
    from meshcat.path import Path as MPath

    from spm_console.system.childproc import HelperProcessError
    from spm_console.viewer.client import MeshcatClient, path_of
    from spm_console.viewer.process import ViewerServer

    srv = ViewerServer()
    urls = srv.start_server()
    c = MeshcatClient(urls.zmq_url)
    try:
        c.set_object("probe", Box([0.1, 0.1, 0.1]))
        sent = c.sent
        with c.batch():
            for k in range(5):
                c.set_transform("probe", np.diag([1.0, 1.0, 1.0, 1.0]) + k * 0.01)
            c.set_property("probe", "visible", True)
            assert c.sent == sent  # nothing went out yet
        assert c.sent == sent + 6  # one exchange acknowledged all six
        # the bridge's own scene (sent to a page opened later) has the last transform
        s = zmq.Context.instance().socket(zmq.REQ)
        s.setsockopt(zmq.RCVTIMEO, 5000)
        s.connect(urls.zmq_url)
        s.send_multipart([b"get_scene"])
        last = umsgpack.packb(SetTransform(np.diag([1.0, 1.0, 1.0, 1.0]) + 0.04,
                                           path_of("probe")).lower())
        import base64

        assert base64.b64encode(last) in s.recv()  # meshcat embeds each command in base64
        s.close(0)
        bad = SetObject(Box([0.1, 0.1, 0.1]), None, MPath(("meshcat", "x"))).lower()
        with pytest.raises(HelperProcessError, match="set_transform/set_property only"):
            c._exchange([b"batch", b"set_object", b"/meshcat/x", umsgpack.packb(bad)])
        with pytest.raises(HelperProcessError, match="batch frames"):
            c._exchange([b"batch", b"set_transform"])
    finally:
        c.close()
        srv.stop()
