"""Pointwise assessment of a pose (core.kinematics.assess) against link distances computed
here from the paper's points (18)-(23) and a search along one segment of the distance to the
other (not the closed form of core.links), and against verdict
thresholds set on either side of the pose's own figures. θ ranges in degrees, distances
in mm."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from spm_console.config.models import link_model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.assess import assess
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import Pose, SpmModel

#: Agile Wrist poses (deg) whose closest pair of links is unique by at least 0.1 mm.
POSES_DEG = [(110.9, 146.0, 81.5), (145.9, 94.9, 103.9), (72.2, 130.3, 113.1),
             (106.3, 80.7, 102.2), (92.4, 108.8, 148.5), (85.3, 76.5, 138.4),
             (89.6, 131.5, 86.9), (75.9, 90.6, 131.1)]
RANGE_DEG = (65.0, 155.0)


def _segment_gaps(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """min over s ∈ [0, 1] of the distance from p1 + s(q1 − p1) to segment [p2, q2] (rows of
    (n, 3)): the point-to-segment distance (projection, clipped) is convex in s, so a
    ternary search on s finds the minimum (to far below 1e-6 mm after 80 rounds)."""
    d1, d2 = q1 - p1, q2 - p2

    def gap(s: np.ndarray) -> np.ndarray:
        x = p1 + s[:, None] * d1
        t = np.clip(((x - p2) * d2).sum(1) / (d2 * d2).sum(1), 0.0, 1.0)
        return np.asarray(np.linalg.norm(x - p2 - t[:, None] * d2, axis=1))

    lo, hi = np.zeros(len(p1)), np.ones(len(p1))
    for _ in range(80):
        a, b = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        left = gap(a) <= gap(b)
        hi = np.where(left, b, hi)
        lo = np.where(left, lo, a)
    ends = np.minimum(gap(np.zeros(len(p1))), gap(np.ones(len(p1))))
    return np.minimum(gap(0.5 * (lo + hi)), ends)


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x)


def _reference(model: SpmModel, links: LinkModel, pose: Pose) -> dict[str, float]:
    """Distance of every pair of segments of different legs, keyed 'leg<i> <s> - leg<j> <s>'."""
    w = model.geom.w(pose.theta)
    u, v = model.u, pose.v
    ends: dict[tuple[int, str], tuple[np.ndarray, np.ndarray]] = {}
    for i in range(3):
        pts = {"A": links.oa * u[i], "B": links.ob * _unit(u[i] + w[i]), "C": links.oc * w[i],
               "D": links.od * w[i], "E": links.oe * _unit(v[i] + w[i]), "F": links.of * v[i]}
        for s in links.segments:
            ends[(i, s)] = (pts[s[0]], pts[s[1]])
    names, rows = [], []
    for i in range(3):
        for j in range(i + 1, 3):
            for s1 in links.segments:
                for s2 in links.segments:
                    names.append(f"leg{i + 1} {s1} - leg{j + 1} {s2}")
                    rows.append((*ends[(i, s1)], *ends[(j, s2)]))
    P1, Q1, P2, Q2 = (np.array(col) for col in zip(*rows, strict=True))
    return dict(zip(names, _segment_gaps(P1, Q1, P2, Q2).tolist(), strict=True))


@pytest.fixture(scope="module")
def poses(agile_model: SpmModel) -> list[Pose]:
    rs = agile_model.track_batch(np.radians(np.array(POSES_DEG)))
    assert all(r.ok and r.pose is not None for r in rs)
    return [r.pose for r in rs if r.pose is not None]


def test_closest_links_match_a_search_along_each_segment(
        agile: Profile, agile_model: SpmModel, poses: list[Pose]) -> None:
    """The smallest inter-leg distance and its pair's name agree with the distances of all
    27 pairs found here (to 1e-6 mm); at the profile's δ and ζ_min every pose is
    feasible, as its figures say it should be."""
    links = link_model_of(agile)
    pairs = set()
    for pose in poses:
        ref = _reference(agile_model, links, pose)
        best = sorted(ref, key=ref.__getitem__)
        assert ref[best[1]] - ref[best[0]] > 0.1  # the closest pair is unambiguous
        a = assess(agile_model, links, pose, 0.25, RANGE_DEG)
        assert a.min_link_distance_mm == pytest.approx(ref[best[0]], abs=1e-6)
        assert a.closest_pair == best[0]
        assert a.zeta == pose.zeta
        assert ref[best[0]] >= 2 * links.delta and pose.zeta >= 0.25
        assert a.in_range and a.feasible and a.reason == ""
        pairs.add(best[0])
    assert len(pairs) >= 4  # several legs and segments named, not one pair every time


def test_each_verdict_flips_at_its_threshold(agile: Profile, agile_model: SpmModel,
                                            poses: list[Pose]) -> None:
    """ζ_min just above / at the pose's ζ, δ just above / below half the reference distance,
    and a θ range just inside / at the pose's extreme angles: infeasible only on the wrong
    side, with the reason naming the check (ζ ≥ ζ_min, distance ≥ 2δ and a θ on the range's
    edge are feasible)."""
    pose = poses[2]
    links = link_model_of(agile)
    ref = min(_reference(agile_model, links, pose).values())
    th = np.degrees(pose.theta)
    lo, hi = float(th.min()), float(th.max())

    def verdict(zeta_min: float, delta: float, rng: tuple[float, float]) -> tuple[bool, str]:
        a = assess(agile_model, replace(links, delta=delta), pose, zeta_min, rng)
        return a.feasible, a.reason

    ok = (True, "")
    assert verdict(pose.zeta, links.delta, (lo, hi)) == ok
    feasible, reason = verdict(pose.zeta + 1e-3, links.delta, (lo, hi))
    assert not feasible and reason.startswith("singular")
    assert verdict(0.0, ref / 2 - 1e-3, RANGE_DEG) == ok
    feasible, reason = verdict(0.0, ref / 2 + 1e-3, RANGE_DEG)
    assert not feasible and reason.startswith("links collide")
    for rng in ((lo + 1e-3, 180.0), (0.0, hi - 1e-3)):
        feasible, reason = verdict(0.0, links.delta, rng)
        assert not feasible and reason.startswith("θ outside")
        assert not assess(agile_model, links, pose, 0.0, rng).in_range
    # all three at once: every reason, in the order of the checks
    _, reason = verdict(pose.zeta + 1e-3, ref / 2 + 1e-3, (lo + 1e-3, 180.0))
    assert [r.split(":")[0].split(" ")[0] for r in reason.split("; ")] == ["singular", "links", "θ"]
