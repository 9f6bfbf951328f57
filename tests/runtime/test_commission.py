"""``commission`` against a wrist wired otherwise than its profile says: the emulated bus
serves the wrist as built (ids permuted, a servo counting the other way, horn offsets), a real
emulated BNO055 on a pty reads its platform (the unique FK of the true joint angles, through a
mounting rotation); the command maps each servo to its leg, zeroes it on the home jig and writes
a profile that reads the true joint angles. Nothing moves more than the nudges' ball."""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.load import load_profile
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.model import newton
from spm_console.core.kinematics.rotations import expm_so3
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.devices.dynamixel.tick_map import joint_maps
from spm_console.devices.emulator.bno055 import EmulatedBno055, ImuTruth
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.motion.logs.runlog import load_run
from spm_console.motion.nudge import BALL_DEG
from tests.runtime.test_bus_emulator import relaxed
from tests.support.paths import ROOT
from tests.support.wiring import IDS, Operator, as_built

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

AGILE = ROOT / "profiles" / "agile_wrist.toml"


#: The IMU's mounting on the platform (rotation vector, deg), the base's tilt (about x, then
#: y, deg) and each leg's arcs as built (deg from 90°).
MOUNT_DEG = (6.0, -4.0, 8.0)
TILT_DEG = (2.0, -1.5)
ARC1_DEG = (0.3, -0.2, 0.1)
ARC2_DEG = (-0.1, 0.25, -0.3)


@pytest.fixture
def wrist(agile: Profile) -> Iterator[tuple[EmulatorHandle, EmulatedBno055, Profile]]:
    truth_profile = as_built(agile)
    switch = sys.getswitchinterval()
    sys.setswitchinterval(0.0005)  # three threads of this process answer serial lines
    em = start_emulator(truth_profile, record=False, link="socket")  # at home: the jig
    geometry = agile.geometry.model_copy(update={"alpha1_leg_offset_deg": ARC1_DEG,
                                                 "alpha2_leg_offset_deg": ARC2_DEG})
    model = model_of(agile.model_copy(update={"geometry": geometry}))  # the arcs as built
    mount = expm_so3(np.radians(MOUNT_DEG))
    tilt = expm_so3(np.radians([0.0, TILT_DEG[1], 0.0])) @ expm_so3(np.radians([TILT_DEG[0], 0.0, 0.0]))
    last = [np.eye(3)]  # the platform's rotation from home at the last sample

    last_theta = [model.theta_home.copy()]

    def truth() -> ImuTruth:  # (4) by Newton, continued from the last sample in steps ≤ 2°
        th = np.radians(em.joint_deg())
        steps = max(1, math.ceil(np.degrees(np.abs(th - last_theta[0]).max()) / 2.0))
        R = last[0]
        for k in range(1, steps + 1):
            at = last_theta[0] + (th - last_theta[0]) * k / steps
            Rs, res = newton(model.geom, model.geom.w(at[None]), R[None], model.v_home)
            assert res[0] < 1e-9
            R = Rs[0]
        last[0], last_theta[0] = R, th
        return ImuTruth.at_rest(tilt @ R @ mount)

    imu = EmulatedBno055(truth, seed=5)
    yield em, imu, truth_profile
    imu.stop()
    em.stop()
    sys.setswitchinterval(switch)


def test_commission_maps_zeroes_and_writes_the_wrist_as_built(
        wrist: tuple[EmulatorHandle, EmulatedBno055, Profile], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    em, imu, truth = wrist
    start = em.joint_deg()
    out = tmp_path / "built.toml"
    rc = main(["commission", "--profile", str(AGILE), "--port", em.port, "--imu-port", imu.port,
               "--jig", "--no-imu-fit", "--out", str(out), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0, d
    assert d["zeroed"] and d["protocol"] == "2.0" and d["imu_fit"] is None
    assert sorted(f["id"] for f in d["found"]) == [1, 2, 3]
    assert [(leg["leg"], leg["id"], leg["direction"]) for leg in d["legs"]] == [
        (1, 3, 1), (2, 1, -1), (3, 2, 1)]
    built = load_profile(out)
    assert [j.id for j in built.bus.joints] == list(IDS)
    # its next commands drive this wrist, not the emulated bus the template's empty port means
    assert built.bus.port == em.port
    # the written profile reads the true joint angles from the servos' ticks
    maps = joint_maps(built)
    truth_maps = joint_maps(truth)
    for theta in (np.asarray(built.home.theta_deg), np.array([120.0, 140.0, 125.0])):
        for m, tm, th in zip(maps, truth_maps, theta, strict=True):
            assert m.id == tm.id
            assert m.to_deg(tm.to_ticks(th)) == pytest.approx(th, abs=360.0 / 4096)
    assert math.dist(em.joint_deg(), start) < BALL_DEG  # the nudges came back


@pytest.mark.slow  # the swings and a zero's fit: half a minute on the wall clock
def test_without_a_jig_the_imu_zeroes_the_wrist_where_it_rests(
        wrist: tuple[EmulatorHandle, EmulatedBno055, Profile], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """No jig: after the map each leg swings ±1.8° about its rest; the rotations the IMU
    measures give the joint angles at rest, so the profile written reads the true angles to
    its stated standard errors (and under a degree); nothing went past the nudges' ball."""
    em, imu, truth = wrist
    start = em.joint_deg()
    out = tmp_path / "built.toml"
    rc = main(["commission", "--profile", str(AGILE), "--port", em.port, "--imu-port", imu.port,
               "--no-imu-fit", "--out", str(out), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0, d
    assert d["zeroed"] and d["jig_ticks"] is None and d["imu_fit"] is None
    rest = d["zero_at_rest"]
    std = np.asarray(rest["theta_std_deg"])
    assert (std > 0).all() and (std < 2.0 / 3.0).all()
    np.testing.assert_allclose(rest["theta_deg"], start, atol=1.0)
    built = load_profile(out)
    for m, tm, e in zip(joint_maps(built), joint_maps(truth), std, strict=True):
        for th in (built.home.theta_deg[0] - 10.0, built.home.theta_deg[0] + 10.0):
            assert m.to_deg(tm.to_ticks(th)) == pytest.approx(th, abs=max(4.0 * e, 0.1))
    assert "zero: IMU at rest" in out.read_text()
    assert math.dist(em.joint_deg(), start) < BALL_DEG  # the swings came back


def test_an_imu_port_where_no_imu_answers_is_refused_before_anything_moves(
        agile: Profile, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    em = start_emulator(agile, record=False, link="socket")
    other = start_emulator(agile, record=False, link="pty")  # Dynamixel servos, not an IMU
    try:
        rc = main(["commission", "--profile", str(AGILE), "--port", em.port, "--imu-port",
                   other.port, "--jig", "--out", str(tmp_path / "x.toml"), "--json"])
        d = json.loads(capsys.readouterr().out)
        assert rc == 10 and "no reply from an IMU" in d["error"], d
        assert not (tmp_path / "x.toml").exists()
        assert em.stats.instructions == 0  # the servo bus was never touched
    finally:
        other.stop()
        em.stop()


@pytest.mark.slow  # 32 poses visited (about a minute of motion and settling)
def test_the_imu_stage_refines_the_jig_zero_and_verifies_it_on_held_out_poses(
        wrist: tuple[EmulatorHandle, EmulatedBno055, Profile], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    em, imu, truth = wrist
    out = tmp_path / "built.toml"
    rc = main(["commission", "--profile", str(AGILE), "--port", em.port, "--imu-port", imu.port,
               "--jig", "--out", str(out), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0, d
    fit = d["imu_fit"]
    assert fit["held_out_gravity_max_deg"] < 0.15 and fit["motion_s"] <= 60.0
    by_name = {p["name"]: p for p in fit["parameters"]}
    for k, want in enumerate(MOUNT_DEG):  # the mounting is found (rpy of a small rotation)
        got = by_name[("mount_roll", "mount_pitch", "mount_yaw")[k]]
        if got["status"] == "determined":
            assert got["value_deg"] == pytest.approx(want, abs=0.5)
    built = load_profile(out)
    for m, tm in zip(joint_maps(built), joint_maps(truth), strict=True):
        for th in (built.home.theta_deg[0] - 10.0, built.home.theta_deg[0] + 10.0):
            assert m.to_deg(tm.to_ticks(th)) == pytest.approx(th, abs=0.1)


@pytest.mark.slow  # the zero at rest, then 32 poses visited
def test_without_a_jig_the_imu_stage_refines_the_zero_at_rest_to_a_tenth_of_a_degree(
        wrist: tuple[EmulatorHandle, EmulatedBno055, Profile], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """No jig: the zero at rest, then the IMU stage with the three horns free (the Agile
    Wrist's gravity across P determines their common offset): the profile reads the true
    angles to 0.1°, as the jig and the IMU do."""
    em, imu, truth = wrist
    out = tmp_path / "built.toml"
    rc = main(["commission", "--profile", str(AGILE), "--port", em.port, "--imu-port", imu.port,
               "--out", str(out), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0, d
    fit = d["imu_fit"]
    assert d["zero_at_rest"] is not None and fit["held_out_gravity_max_deg"] < 0.15
    horns = [p for p in fit["parameters"] if p["name"].startswith("horn")]
    assert len(horns) == 3 and all(p["status"] == "determined" for p in horns), horns
    built = load_profile(out)
    for m, tm in zip(joint_maps(built), joint_maps(truth), strict=True):
        for th in (built.home.theta_deg[0] - 10.0, built.home.theta_deg[0] + 10.0):
            assert m.to_deg(tm.to_ticks(th)) == pytest.approx(th, abs=0.1)


def test_without_an_imu_the_operator_names_each_leg_and_its_way(
        wrist: tuple[EmulatorHandle, EmulatedBno055, Profile], agile: Profile,
        tmp_path: Path) -> None:
    """The map from the operator's answers: the same legs and directions as the IMU finds, a
    profile that reads the true joint angles, every question and answer in the run log."""
    from spm_console.services.client import EstopRelay
    from spm_console.services.commissioning.run import CommissionRequest, run_commissioning

    em, _imu, truth = wrist
    operator = Operator(em, agile)
    req = CommissionRequest(em.port, None, jig=True, out=tmp_path / "built.toml",
                            logs_root=tmp_path / "logs")
    done = run_commissioning(agile, AGILE, req, lambda _line: None, EstopRelay("commission"),
                             operator)
    assert [(m.leg, m.id, m.direction, m.source) for m in done.result.legs] == [
        (1, 3, 1, "operator"), (2, 1, -1, "operator"), (3, 2, 1, "operator")]
    assert len(operator.questions) == 7 and done.result.refinement is None
    nudges = [e for e in load_run(done.log_dir).events if e["event"] == "nudge"]
    assert len(nudges) == 8  # each servo out and back, the first twice
    built = load_profile(done.written)
    for m, tm in zip(joint_maps(built), joint_maps(truth), strict=True):
        for th in (built.home.theta_deg[0], 120.0):
            assert m.to_deg(tm.to_ticks(th)) == pytest.approx(th, abs=360.0 / 4096)
    asked = [e for e in load_run(done.log_dir).events if e["event"] == "asked"]
    assert [e["question"] for e in asked] == operator.questions
    assert "map: operator" in done.written.read_text()


def test_answers_naming_one_leg_twice_are_refused_and_nothing_is_written(
        wrist: tuple[EmulatorHandle, EmulatedBno055, Profile], agile: Profile,
        tmp_path: Path) -> None:
    from spm_console.errors import BusError
    from spm_console.services.client import EstopRelay
    from spm_console.services.commissioning.run import CommissionRequest, run_commissioning

    em, _imu, truth = wrist
    req = CommissionRequest(em.port, None, jig=True, out=tmp_path / "built.toml",
                            logs_root=tmp_path / "logs")
    with pytest.raises(BusError, match="two servos drive the same leg by the answers"):
        run_commissioning(agile, AGILE, req, lambda _line: None, EstopRelay("commission"),
                          lambda q, _a: "1" if "which leg" in q else "up")
    assert not (tmp_path / "built.toml").exists()
    (run_dir,) = (tmp_path / "logs").iterdir()
    assert load_run(run_dir).meta["outcome"] == "refused"
    # the jig came off at "map": a refusal after the nudges began leaves the wrist holding
    bus = open_bus(relaxed(truth), em.port)
    try:
        assert bus.torque() == [True, True, True]
        assert all(bus.read(i, "pwm_limit") == 885 for i in bus.ids)  # limits restored
    finally:
        bus.close()
