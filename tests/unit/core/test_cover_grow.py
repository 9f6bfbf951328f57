"""Growing one cover region, choosing its seed, and the throttled progress reports
(core.regions.cover_grow), against references computed here: window counts and distances to
the nearest non-candidate node by brute force over the grid, one linear program
(scipy.optimize.linprog) per obstacle cube and per box face, and a hand-driven clock.
Angles in degrees (θ of the grown regions and the obstacles)."""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import linprog

from spm_console.core.polytope.iris import Frame
from spm_console.core.polytope.region import Region
from spm_console.core.regions import cover_grow
from spm_console.core.regions.cover_grow import SEED_WINDOW, Grower, Reporter, deepest_seed, dense_seed

# ---------------------------------------------------------------- seeds


def _masks(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A random grid (feasible nodes f, their indices fidx) with uncovered and candidate
    nodes among the feasible ones."""
    rng = np.random.default_rng(seed)
    shape = tuple(int(n) for n in rng.integers(4, 12, 3))
    f = rng.random(shape) < 0.7
    fidx = np.argwhere(f)
    uncovered = rng.random(len(fidx)) < 0.6
    cand = uncovered & (rng.random(len(fidx)) < rng.uniform(0.3, 0.95))
    cand[int(np.flatnonzero(uncovered)[0])] = True
    return f, fidx, uncovered, cand


@pytest.mark.parametrize("seed", range(20))
def test_dense_seed_has_the_most_uncovered_nodes_around_it(seed: int) -> None:
    """The chosen candidate's window of (2·SEED_WINDOW + 1)³ nodes holds as many uncovered
    feasible nodes as any candidate's, counted node by node (L∞ distance ≤ SEED_WINDOW).
    Ties are not checked: the filter's rounding can reorder equal counts."""
    f, fidx, uncovered, cand = _masks(seed)
    U = fidx[uncovered]
    count = np.full(len(fidx), -1)
    for j in np.flatnonzero(cand):
        count[j] = int((np.abs(U - fidx[j]).max(1) <= SEED_WINDOW).sum())
    j = dense_seed(f, fidx, uncovered, cand)
    assert cand[j]
    assert count[j] == count.max()


def test_dense_seed_window_is_two_steps() -> None:
    """One candidate with a block of 2 uncovered nodes 2 steps away (inside its window) and
    one, first in C order, with a block of 3 nodes 3 steps away (outside): the former wins (a
    window of 1 step would tie them, one of 3 would prefer the latter)."""
    f = np.ones((12, 12, 12), bool)
    fidx = np.argwhere(f)
    at = {tuple(p): k for k, p in enumerate(fidx)}
    uncovered = np.zeros(len(fidx), bool)
    cand = np.zeros(len(fidx), bool)
    a, b = at[(9, 9, 9)], at[(2, 2, 2)]
    cand[[a, b]] = uncovered[[a, b]] = True
    uncovered[[at[(9, 9, 7)], at[(9, 8, 7)]]] = True  # 2 steps from a
    uncovered[[at[(2, 2, 5)], at[(2, 3, 5)], at[(3, 2, 5)]]] = True  # 3 steps from b
    assert dense_seed(f, fidx, uncovered, cand) == a


@pytest.mark.parametrize("seed", range(20))
def test_deepest_seed_is_farthest_from_the_non_candidates(seed: int) -> None:
    """The chosen candidate is the first (in fidx order) of those farthest, in Euclidean grid
    steps, from every grid node that is not a candidate (infeasible ones included; outside the
    grid does not count), distances computed pairwise."""
    f, fidx, _, cand = _masks(seed)
    is_cand = np.zeros(f.shape, bool)
    is_cand[tuple(fidx[cand].T)] = True
    others = np.argwhere(~is_cand)
    assert len(others)
    depth = np.full(len(fidx), -1.0)
    for j in np.flatnonzero(cand):
        depth[j] = np.sqrt(((others - fidx[j]) ** 2).sum(1).min())
    j = deepest_seed(f, fidx, cand)
    assert depth[j] == pytest.approx(depth.max(), abs=1e-12)
    assert j == int(np.flatnonzero(depth >= depth.max() - 1e-9)[0])


def test_deepest_seed_ignores_the_grid_faces() -> None:
    """A 7³ grid all candidates but one corner: the deepest node is the opposite corner (6·√3
    steps from it), not the centre (3·√3), since the grid's faces are no boundary."""
    f = np.ones((7, 7, 7), bool)
    fidx = np.argwhere(f)
    cand = np.ones(len(fidx), bool)
    cand[0] = False  # node (0, 0, 0)
    j = deepest_seed(f, fidx, cand)
    assert tuple(fidx[j]) == (6, 6, 6)


# ---------------------------------------------------------------- growing a region

FRAME = Frame(np.zeros(3), 30.0)  # the box [-30, 30]³ deg
HALF_DEG = 3.0
SEED_DEG = np.array([1.0, -2.0, 0.5])


def _obstacles() -> np.ndarray:
    """Cube centres (deg) scattered in the box, none within 8° (L∞) of the origin, and one
    whose cube ends 0.5° from the seed."""
    rng = np.random.default_rng(4)
    c = rng.uniform(-27.0, 27.0, (40, 3))
    c = c[np.abs(c).max(1) > 8.0]
    near = SEED_DEG + np.array([HALF_DEG + 0.5, 0.0, 0.0])
    return np.vstack([c, near])


def _objective() -> np.ndarray:
    g = np.arange(-28.0, 29.0, 4.0)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)


def _grower(iters: int, max_halfspaces: int, tick: Callable[[], None] | None = None) -> Grower:
    """A grower in the frame's scaled coordinates: obstacle centres and half-width / s."""
    return Grower(FRAME, FRAME.to_x(_obstacles()), HALF_DEG / FRAME.s, max_halfspaces, iters, 2.0,
                  tick=tick)


def _meets_open_cube(region: Region, centre: np.ndarray, half: float) -> bool:
    """LP: max t with A θ ≤ b and centre − half + t ≤ θ ≤ centre + half − t; the open cube
    meets the region iff t > 0."""
    m = len(region.b)
    A = np.vstack([np.hstack([region.A, np.zeros((m, 1))]),
                   np.hstack([-np.eye(3), np.ones((3, 1))]),
                   np.hstack([np.eye(3), np.ones((3, 1))])])
    b = np.r_[region.b, -(centre - half), centre + half]
    res = linprog(np.r_[0.0, 0.0, 0.0, -1.0], A_ub=A, b_ub=b,
                  bounds=[(None, None)] * 3 + [(None, half)], method="highs")
    assert res.status == 0
    return bool(-res.fun > 1e-7)


def _extent(region: Region) -> np.ndarray:
    """max of ±θ_i over the region (6 LPs), deg."""
    out = []
    for sign in (1.0, -1.0):
        for i in range(3):
            c = np.zeros(3)
            c[i] = -sign
            res = linprog(c, A_ub=region.A, b_ub=region.b, bounds=[(None, None)] * 3, method="highs")
            assert res.status == 0
            out.append(-res.fun)
    return np.array(out)


@pytest.mark.parametrize(("iters", "max_halfspaces"), [(1, 30), (3, 30), (3, 8)])
def test_grown_region_holds_the_seed_and_misses_every_cube(iters: int, max_halfspaces: int) -> None:
    """The region holds the seed (one cube ends 0.5° from it), meets no open obstacle cube
    (one LP per cube), stays in the frame's box [-30, 30]³ (one LP per face) and has at most
    the allowed rows."""
    region = _grower(iters, max_halfspaces).grow(SEED_DEG, _objective())
    assert region.contains(SEED_DEG)
    assert not any(_meets_open_cube(region, c, HALF_DEG) for c in _obstacles())
    assert _extent(region).max() <= 30.0 + 1e-6
    assert region.halfspaces <= max_halfspaces


def test_row_cap_binds_and_more_iterations_hold_no_fewer_points() -> None:
    """Without a cap the 3-iteration region needs more rows than 8 (so the cap of 8 binds).
    With 1, 2, 3, 4 iterations the region holds ever more or as many objective nodes
    (counted here point by point, A θ ≤ b + 1e-7): the best iterate is kept, not the last
    (on these obstacles the third iterate holds fewer nodes than the second)."""
    obj = _objective()

    def held(r: Region) -> int:
        return int(((obj @ r.A.T) <= r.b + 1e-7).all(1).sum())

    capped = _grower(3, 8).grow(SEED_DEG, obj)
    counts = [held(_grower(k, 30).grow(SEED_DEG, obj)) for k in (1, 2, 3, 4)]
    assert _grower(3, 30).grow(SEED_DEG, obj).halfspaces > 8 >= capped.halfspaces
    assert counts[0] > 0
    assert counts == sorted(counts), counts


class _CancelledError(Exception):
    pass


def test_tick_is_called_during_a_growth_and_can_cancel_it() -> None:
    """The tick runs between the steps of every iteration; an exception it raises ends the
    growth (a cancel)."""
    calls: list[int] = []
    _grower(3, 30, tick=lambda: calls.append(1)).grow(SEED_DEG, _objective())
    assert len(calls) >= 3

    def cancel() -> None:
        raise _CancelledError

    with pytest.raises(_CancelledError):
        _grower(3, 30, tick=cancel).grow(SEED_DEG, _objective())


# ---------------------------------------------------------------- progress reports


def test_reporter_throttles_to_every_tenth_of_a_second(monkeypatch: pytest.MonkeyPatch) -> None:
    """Against a hand-driven clock (s): a report only once REPORT_EVERY_S = 0.1 s has passed
    since the last one, or when forced; fractions are clipped to [0, 1]."""
    now = [0.0]
    monkeypatch.setattr(cover_grow, "time", SimpleNamespace(perf_counter=lambda: now[0]))
    assert cover_grow.REPORT_EVERY_S == 0.1
    seen: list[float] = []
    report = Reporter(seen.append)
    for t, fraction, force in [(0.05, 0.1, False),   # too soon
                               (0.1, 0.2, False),    # 0.1 s after the start: reported
                               (0.15, 0.3, False),   # 0.05 s after the last
                               (0.17, -0.5, True),   # forced, clipped to 0
                               (0.25, 0.5, False),   # 0.08 s after the forced one
                               (0.3, 1.7, False)]:   # 0.13 s: reported, clipped to 1
        now[0] = t
        report(fraction, force=force)
    assert seen == [0.2, 0.0, 1.0]
    Reporter(None)(0.5, force=True)  # no callback: nothing to call
