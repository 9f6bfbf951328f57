"""The offsets the runtime adds for an identified load, and the checks on what it sends."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.config.load import load_profile
from spm_console.config.models import servo_model_of
from spm_console.config.servo_section import with_servo
from spm_console.description.weight import holding_torque_nm
from spm_console.errors import PlanRefusedError
from spm_console.motion.goals.load_offsets import (
    MAX_OFFSET_DEG,
    LoadTracker,
    load_model,
    load_offsets,
    sent_references,
    step_limited,
)
from tests.support.paths import ROOT

PROFILE = ROOT / "profiles" / "agile_wrist.toml"


def _loaded(k: float | None, c: float | None):  # type: ignore[no-untyped-def]
    p = load_profile(PROFILE)
    return p.model_copy(update={"servo": p.servo.model_copy(
        update={"load_deg_per_nm": k, "coulomb_deg": c})})


def _ramp() -> tuple[np.ndarray, np.ndarray]:
    a, b = np.array([127.53, 83.23, 85.25]), np.array([66.8, 155.0, 131.48])
    s = np.linspace(0.0, 1.0, 120)[:, None]
    return a, np.vstack([a + s * (b - a), np.repeat(b[None], 40, axis=0)])


def test_without_a_load_model_nothing_is_added() -> None:
    p = _loaded(None, None)
    a, refs = _ramp()
    assert load_offsets(p, servo_model_of(p), refs, a) is None
    assert sent_references(refs, None, np.zeros(3), np.full(3, 360.0), a) is refs


def test_the_offset_is_the_holding_torque_at_rest_and_friction_in_motion() -> None:
    k, c = 1.4, 0.09
    p = _loaded(k, c)
    a, refs = _ramp()
    d = load_offsets(p, servo_model_of(p), refs, a)
    assert d is not None and d.shape == refs.shape
    # at rest at the goal: the weight only, at the goal's pose
    np.testing.assert_allclose(d[-1], k * holding_torque_nm(p, refs[-1:])[0], atol=1e-6)
    # mid-ramp each joint's friction term pushes along its motion
    mid = d[60] - k * holding_torque_nm(p, refs[:61])[-1]
    np.testing.assert_allclose(np.sign(mid), np.sign(refs[-1] - refs[0]))
    assert np.abs(mid).max() <= c + 0.05  # the model's pose differs a little from the reference


def test_an_offset_beyond_the_bound_is_refused() -> None:
    p = _loaded(100.0, None)
    a, refs = _ramp()
    with pytest.raises(PlanRefusedError, match="offset"):
        load_offsets(p, servo_model_of(p), refs, a)
    assert MAX_OFFSET_DEG < 100.0 * 0.3


def test_sent_references_stay_in_the_limits_and_steps() -> None:
    refs = np.array([[10.0, 10.0, 10.0], [10.5, 10.5, 10.5]])
    off = np.array([[0.5, -0.5, 0.0], [0.5, -0.5, 0.0]])
    sent = sent_references(refs, off, np.full(3, 0.0), np.array([10.8, 20.0, 20.0]), None)
    np.testing.assert_allclose(sent, [[10.5, 9.5, 10.0], [10.8, 10.0, 10.5]])
    with pytest.raises(PlanRefusedError, match="steps"):
        sent_references(refs, off, np.zeros(3), np.full(3, 90.0), np.array([-5.0, 10.0, 10.0]))


def test_the_profile_writer_keeps_the_load() -> None:
    p = _loaded(1.3871, 0.0857)
    text, back = with_servo(PROFILE.read_text(encoding="utf-8"), p.servo, "test")
    assert back.servo.load_deg_per_nm == pytest.approx(1.3871)
    assert back.servo.coulomb_deg == pytest.approx(0.0857)
    assert "load_deg_per_nm" in text


def test_the_live_tracker_gives_the_planned_offsets_pose_after_pose() -> None:
    """Live following computes the offset cycle by cycle, continuing the FK from the last
    pose: along a path it equals the offsets computed for the whole path at once."""
    k, c = 1.4, 0.09
    p = _loaded(k, c)
    a, refs = _ramp()
    load = load_model(p)
    assert load is not None
    tracker = LoadTracker(p, load, a)
    vel = np.tile([-20.0, 25.0, 15.0], (len(refs), 1))
    live = np.array([tracker.offset(th, v) for th, v in zip(refs, vel, strict=True)])
    whole = k * holding_torque_nm(p, refs) + c * np.tanh(vel / 2.0)
    np.testing.assert_allclose(live, whole, atol=1e-9)


def test_a_sent_reference_is_limited_to_the_step_and_the_servo_limits() -> None:
    lo, hi = np.zeros(3), np.full(3, 100.0)
    out = step_limited(np.array([50.0, 50.0, 99.0]), np.array([65.0, 45.0, 101.0]), lo, hi)
    np.testing.assert_allclose(out, [60.0, 45.0, 100.0])
    np.testing.assert_allclose(step_limited(None, np.array([-1.0, 5.0, 7.0]), lo, hi),
                               [0.0, 5.0, 7.0])
