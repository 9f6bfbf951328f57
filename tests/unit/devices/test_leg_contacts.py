"""The physical wrist's collision envelopes against the workspace's link-interference model:
MuJoCo's capsule–capsule distance (its own collision code) equals the paper's segment distance
(eqs. 18–24, our closed form) less 2δ, and a contact begins exactly where the workspace says
two legs come within 2δ."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from spm_console.config.load import load_profile
from spm_console.config.models import link_model_of, model_of
from spm_console.description.mjcf import envelope_name
from spm_console.devices.emulator.physical import PhysicalWrist
from tests.support.paths import ROOT


@pytest.fixture(scope="module")
def setup():  # type: ignore[no-untyped-def]
    profile = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    links = link_model_of(profile)
    return PhysicalWrist(model_of(profile), links=links), links


@pytest.fixture(scope="module")
def contact_poses(setup) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    """40 random poses, some of which bring legs into contact (seeded; tracked once)."""
    return _poses(setup[0], 40, 2)


def _poses(wrist: PhysicalWrist, n: int, seed: int) -> list[np.ndarray]:
    """Random joint angles near home the continuation FK reaches (rad)."""
    rng = np.random.default_rng(seed)
    m = wrist.spm
    out = []
    while len(out) < n:
        th = m.theta_home + np.radians(rng.uniform(-40.0, 40.0, 3))
        if m.track(th).ok:
            out.append(th)
    return out


def test_mujocos_capsule_distance_is_the_segment_distance_less_two_delta(setup) -> None:  # type: ignore[no-untyped-def]
    wrist, links = setup
    m = wrist.spm
    fromto = np.zeros(6)
    for th in _poses(wrist, 12, 1):
        wrist.set_theta(th)
        fk = m.track(th)
        assert fk.pose is not None
        w = m.geom.w(th)
        ours = links.pair_distances(m.u, w, fk.pose.v)  # mm, in pairs() order
        for k, (i, s1, j, s2) in enumerate(links.pairs()):
            g1 = wrist.mj.geom(envelope_name(i, s1)).id
            g2 = wrist.mj.geom(envelope_name(j, s2)).id
            d = 1000.0 * mujoco.mj_geomDistance(wrist.mj, wrist.data, g1, g2, 1.0, fromto)
            assert d == pytest.approx(ours[k] - 2 * links.delta, abs=0.02), (k, np.degrees(th))


def test_a_contact_is_told_once_where_the_workspace_sees_the_legs_within_two_delta(setup, contact_poses) -> None:  # type: ignore[no-untyped-def]
    wrist, links = setup
    m = wrist.spm
    told = 0
    for th in contact_poses:
        wrist.set_theta(th)
        fk = m.track(th)
        assert fk.pose is not None
        closest = float(links.pair_distances(m.u, m.geom.w(th), fk.pose.v).min())
        wrist.contacts.touching = set()
        wrist.contacts.check(wrist.data, 0.0, wrist.theta)
        wrist.contacts.check(wrist.data, 0.002, wrist.theta)  # still touching: not again
        events = wrist.contacts.take()
        if closest < 2 * links.delta - 0.05:
            assert len(events) >= 1
            told += 1
            e = events[0]
            assert e.distance_mm < 0 and e.legs[0] != e.legs[1]
            assert e.segments[0] in links.segments and e.segments[1] in links.segments
        elif closest > 2 * links.delta + 0.05:
            assert events == []
    assert told > 0  # the poses reached some contacts


def test_the_pairs_left_unasked_are_apart_by_mujocos_own_distance(setup, contact_poses) -> None:  # type: ignore[no-untyped-def]
    """The contact check asks MuJoCo only for the pairs whose bounding spheres meet: every
    other pair is apart by ``mj_geomDistance`` itself, and in every pose some pairs are
    asked, some are not (the poses reach contacts, as above)."""
    wrist, _ = setup
    contacts = wrist.contacts
    fromto = np.zeros(6)
    asked = unasked = touching = 0
    for th in contact_poses:
        wrist.set_theta(th)
        near = set(contacts.near(wrist.data))
        for k, (g1, g2, *_) in enumerate(contacts.pairs):
            d = mujoco.mj_geomDistance(wrist.mj, wrist.data, g1, g2, 1.0, fromto)
            touching += d < 0.0
            if k in near:
                asked += 1
            else:
                unasked += 1
                assert d > 0.0, (k, np.degrees(th))
    assert asked > 0 and unasked > asked and touching > 0
