"""The forked row map: the same rows as one process, a helper only where it is safe, and no
helper left behind. The mechanics run in a fresh interpreter (one thread, as a build from the
command line); the exact checks and link distances of a real workspace are compared with the
serial computation here."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import threading

import numpy as np

from spm_console.core.workspace.check import exact_ok
from spm_console.system.forked import ForkedRows
from tests.support.ws_helpers import agile_workspace


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                         text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_rows_split_with_one_child_per_function_and_joined_in_order() -> None:
    out = _run("""
        import os, numpy as np
        from spm_console.system.forked import ForkedRows
        def twice(x):
            return np.column_stack([x * 2.0, np.full(len(x), os.getpid())])
        def pair(x, y):
            return x + y, x * y
        x = np.arange(5000.0)
        with ForkedRows(min_rows=100) as fr:
            got = fr(twice, x)
            assert np.array_equal(got[:, 0], 2.0 * x), "rows out of order"
            pids = set(got[:, 1].astype(int))
            assert len(pids) == 2 and os.getpid() in pids, pids   # half here, half in the child
            s, p = fr(pair, x, x + 1.0)
            assert np.array_equal(s, 2 * x + 1) and np.array_equal(p, x * (x + 1))
            assert fr(twice, x[:50]).shape == (50, 2)   # below min_rows: here
            print(fr.forks, fr.split_calls)
        try:
            os.waitpid(-1, os.WNOHANG)
            print("child left")
        except ChildProcessError:
            print("no child")
    """)
    assert out.split() == ["2", "2", "no", "child"]


def test_an_error_in_the_child_half_is_raised_here_and_a_dead_child_is_replaced_by_this_process(
) -> None:
    out = _run("""
        import os, signal, numpy as np
        from spm_console.system.forked import ForkedRows
        def picky(x):
            if (x < 10).any():
                raise ValueError("small")
            return x * 3.0
        x = np.arange(4000.0)
        with ForkedRows(min_rows=100) as fr:
            try:
                fr(picky, x)            # the child's half holds the small values
                print("no error")
            except ValueError as exc:
                print("raised", exc)
            got = fr(picky, x + 10)
            assert np.array_equal(got, (x + 10) * 3.0)
            os.kill(fr.child_pid, signal.SIGKILL)
            os.waitpid(fr.child_pid, 0)
            got = fr(picky, x + 10)       # the child is gone: all here
            assert np.array_equal(got, (x + 10) * 3.0)
            print(fr.enabled)
    """)
    assert out.split() == ["raised", "small", "False"]


def test_no_fork_from_a_process_running_threads() -> None:
    stop = threading.Event()
    t = threading.Thread(target=stop.wait, daemon=True)
    t.start()
    try:
        with ForkedRows(min_rows=1) as fr:
            got = fr(np.sqrt, np.arange(10.0))
            assert fr.forks == 0 and not fr.enabled
        assert np.array_equal(got, np.sqrt(np.arange(10.0)))
    finally:
        stop.set()
        t.join()


def test_exact_checks_and_link_distances_split_equal_the_serial_ones() -> None:
    """Row-wise for real: the verdicts and the distances do not depend on the split."""
    from functools import partial

    from spm_console.core.kinematics.model import platform_axes
    from spm_console.core.workspace.build import link_distances

    ws = agile_workspace()
    model, links = ws.exact_models()
    rng = np.random.default_rng(7)
    lo, hi = ws.range_deg()
    pts = rng.uniform(lo, hi, (6000, 3))
    serial = exact_ok(ws, model, links, pts)
    f = ws.feasible
    R = ws.R[f][:4000]
    th = np.radians(ws.theta_deg()[f][:4000])
    w, v = model.geom.w(th), platform_axes(R, model.v_home)
    d0, k0 = link_distances(links, model.u, w, v)
    with ForkedRows(min_rows=1000) as fr:
        split = fr(partial(exact_ok, ws, model, links), pts)
        d1, k1 = fr(partial(link_distances, links, model.u), w, v)
    assert 0.2 < serial.mean() < 0.95  # both verdicts occur
    assert np.array_equal(split, serial)
    assert np.array_equal(d1, d0) and np.array_equal(k1, k0)


def test_the_overlap_graph_split_equals_the_serial_one() -> None:
    from spm_console.core.regions.cover import cyclic_symmetric
    from spm_console.core.regions.cover_graph import overlap_graph

    ws = agile_workspace()
    assert ws.cover is not None
    regions, rmin = ws.cover.regions, ws.cover.min_overlap_deg
    sym = cyclic_symmetric(ws)
    e0, p0, r0 = overlap_graph(regions, rmin, sym)
    with ForkedRows(min_rows=10) as fr:
        e1, p1, r1 = overlap_graph(regions, rmin, sym, rowmap=fr)
    assert len(e0) > 100
    assert np.array_equal(e0, e1) and np.array_equal(p0, p1) and np.array_equal(r0, r1)
    assert np.array_equal(e0, ws.cover.edges)  # and the graph the build stored


def test_a_refined_build_with_the_helper_equals_the_serial_build() -> None:
    """The whole build (FK grid, link distances, P, refined cover, graph) through the forked
    row map gives the same arrays, regions and graph as in one process (5° grid: fast)."""
    from spm_console.config.models import grid_spec
    from spm_console.core.workspace.rowmap import serial
    from spm_console.core.workspace_build import build_workspace
    from tests.support.ws_helpers import agile_profile, with_step

    spec = grid_spec(with_step(agile_profile(), 5.0))
    a = build_workspace(spec, refined_cover=True, rowmap=serial)
    with ForkedRows(min_rows=10) as fr:
        b = build_workspace(spec, refined_cover=True, rowmap=fr)
    assert np.array_equal(a.min_link_mm, b.min_link_mm, equal_nan=True)
    assert np.array_equal(a.klass, b.klass)
    assert a.cover is not None and b.cover is not None
    assert a.cover.refined_cells > 0 and a.cover.size > 1
    for ra, rb in zip(a.cover.regions, b.cover.regions, strict=True):
        assert np.array_equal(ra.A, rb.A) and np.array_equal(ra.b, rb.b)
    assert np.array_equal(a.cover.edges, b.cover.edges)


def test_no_fork_under_a_real_time_policy() -> None:
    out = _run("""
        import os, numpy as np
        from spm_console.system.forked import ForkedRows
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except PermissionError:
            print("not permitted")
            raise SystemExit(0)
        with ForkedRows(min_rows=1) as fr:
            fr(np.sqrt, np.arange(1000.0))
            print(fr.forks, fr.enabled)
    """)
    if out.strip() == "not permitted":
        import pytest

        pytest.skip("this user may not set SCHED_FIFO")
    assert out.split() == ["0", "False"]


def test_an_error_in_this_process_half_stops_the_child_so_the_next_call_reads_no_stale_answer(
) -> None:
    out = _run("""
        import numpy as np
        from spm_console.system.forked import ForkedRows
        def picky(x):
            if (x > 3000).any():
                raise ValueError("large")
            return x * 2.0
        x = np.arange(4000.0)
        with ForkedRows(min_rows=100) as fr:
            try:
                fr(picky, x)            # this process's half holds the large values
            except ValueError as exc:
                print("raised", exc, fr.child_pid)
            y = np.arange(1000.0)
            assert np.array_equal(fr(picky, y), 2.0 * y)   # a new child, a fresh answer
            print(fr.forks)
    """)
    assert out.split() == ["raised", "large", "0", "2"]
