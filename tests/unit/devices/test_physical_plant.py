"""The physical emulated wrist against published figures and the paper's kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.config.load import load_profile
from spm_console.config.models import model_of
from spm_console.config.schema import Plant, Profile
from spm_console.description.mjcf import plant_params
from spm_console.devices.dynamixel.control_table import ControlTable, table_for
from spm_console.devices.dynamixel.tick_map import JointMap, joint_maps
from spm_console.devices.emulator.physical import PWM_FULL, Drive, DriveGains, PhysicalWrist
from spm_console.devices.emulator.plant_joint import PlantJoint
from spm_console.devices.emulator.servo import OVERLOAD, EmulatedServo
from tests.support.paths import ROOT

P = plant_params(Plant())
TICKS_PER_RAD = 4096 / (2 * math.pi)


def test_stall_torque_is_the_vendors_at_12_v() -> None:
    """MX-106 e-manual: 8.4 N·m stall torque at 12 V (full duty, shaft blocked)."""
    assert Drive(P, TICKS_PER_RAD).torque(1.0, 0.0) == pytest.approx(8.4, rel=0.01)


def test_no_load_speed_is_near_the_vendors() -> None:
    """Full duty against the joint's own friction only: the vendor says 45 rpm at 12 V. With
    BAM's torque constant (2.2 N·m/A) and the vendor's stall torque the model turns at about
    50 rpm: the two sources disagree by about a tenth, and the test says so."""
    d = Drive(P, TICKS_PER_RAD)
    # steady state: motor torque = Coulomb + viscous friction
    k = P.kt_nm_per_a / P.resistance_ohm
    omega = (k * P.supply_v - P.coulomb_nm) / (k * P.kt_nm_per_a + P.viscous_nms)
    assert d.torque(1.0, omega) == pytest.approx(P.coulomb_nm + P.viscous_nms * omega)
    rpm = omega * 60 / (2 * math.pi)
    assert 45 <= rpm <= 45 * 1.15, rpm


def test_the_firmware_duty_is_linear_up_to_the_pwm_limit() -> None:
    """Position P Gain 850 (K_PP = 850/128): full duty at 885·128/850 ≈ 133 ticks ≈ 11.7°."""
    edge = PWM_FULL * 128 / 850
    assert Drive(P, TICKS_PER_RAD).duty(edge / 2, 0.0) == pytest.approx(0.5)
    assert Drive(P, TICKS_PER_RAD).duty(edge, 0.0) == pytest.approx(1.0)
    assert Drive(P, TICKS_PER_RAD).duty(3 * edge, 0.0) == pytest.approx(1.0)
    assert Drive(P, TICKS_PER_RAD).duty(-3 * edge, 0.0) == pytest.approx(-1.0)


def _drive(wrist: PhysicalWrist, goal: np.ndarray) -> None:
    for i in range(3):
        wrist.command(i, float(goal[i]), True, False)


@pytest.fixture(scope="module")
def wrist() -> PhysicalWrist:
    return PhysicalWrist(model_of(load_profile(ROOT / "profiles" / "agile_wrist.toml")))


def test_the_chain_stays_closed_and_is_the_papers_fk(wrist: PhysicalWrist) -> None:
    """Over steps of several degrees the loop closures hold below 1e-5 rad (far below the
    encoder's 0.088°), and the platform's rotation is the continuation FK of the measured θ."""
    m = wrist.spm
    wrist.set_theta(m.theta_home)
    wrist.t = 0.0
    worst = 0.0
    t = 0.0
    for step_deg in ([5, -3, 4], [-6, 8, -2], [0, 0, 0]):
        _drive(wrist, m.theta_home + np.radians(step_deg))
        for _ in range(60):
            t += 0.005
            wrist.advance(t)
            worst = max(worst, wrist.closure_error() / P.link_radius_m)
        fk = m.track(wrist.theta())
        assert fk.ok and fk.pose is not None
        np.testing.assert_allclose(wrist.platform_rotation(), fk.pose.R, atol=1e-5)
    assert worst < 1e-5


def test_a_step_overshoots_unlike_the_papers_critically_damped_model(wrist: PhysicalWrist) -> None:
    """Eq. (27) with p = 32.22 never overshoots a step; the MX-106 on the wrist does, then
    friction holds it within a fraction of a degree of the goal (its dead band)."""
    m = wrist.spm
    wrist.set_theta(m.theta_home)
    wrist.t = 0.0
    goal = m.theta_home + np.radians([5.0, 0.0, 0.0])
    _drive(wrist, goal)
    peak = 0.0
    for k in range(1, 201):
        wrist.advance(k * 0.005)
        peak = max(peak, math.degrees(wrist.theta()[0] - m.theta_home[0]))
    assert peak > 5.05  # an overshoot eq. (27) cannot produce
    assert abs(math.degrees(wrist.theta()[0] - goal[0])) < 0.3


def test_with_torque_off_the_wrist_holds_its_own_weight(wrist: PhysicalWrist) -> None:
    """The gear driven from the output holds: a pose away from home stays put for 2 s, but
    for the output settling across the gear's play (placed mid-play, it sags to one side)."""
    m = wrist.spm
    start = np.radians([120.0, 140.0, 130.0])
    wrist.set_theta(start)
    for i in range(3):
        wrist.command(i, float(start[i]), False, False)
    wrist.t = 0.0
    wrist.advance(1.0)
    settled = wrist.theta()
    assert np.degrees(np.abs(settled - start)).max() < P.backlash_rad * 90.0 / math.pi + 0.02
    wrist.advance(2.0)
    assert np.degrees(np.abs(wrist.theta() - settled)).max() < 0.01
    assert m.track(wrist.theta()).ok


def test_the_gear_play_is_the_vendors(wrist: PhysicalWrist) -> None:
    """MX-106 e-manual: backlash 0.33°. Torque off (the gear held by its backdrive friction),
    a torque on one output shaft moves it across the play, each way, and no further; the
    encoder, on the output, reads the whole play."""
    m = wrist.spm
    wrist.set_theta(m.theta_home)
    for i in range(3):
        wrist.command(i, float(m.theta_home[i]), False, False)
    wrist.t = 0.0
    dof = wrist.mj.joint("leg1_play_joint").dofadr[0]  # the output shaft, against the rotor
    ends = []
    for torque in (0.4, -0.4, 0.4):
        wrist.data.qfrc_applied[dof] = torque
        wrist.advance(wrist.t + 0.4)
        ends.append(math.degrees(wrist.theta()[0]))
    wrist.data.qfrc_applied[dof] = 0.0
    assert abs(ends[0] - ends[1]) == pytest.approx(0.33, abs=0.02)
    assert ends[2] == pytest.approx(ends[0], abs=0.03)  # the drive side stayed (held by friction)
    assert abs(float(wrist.motor_angle()[0])) < math.radians(0.05)  # impacts nudge it only


def test_a_blocked_shaft_stays_where_it_stuck(wrist: PhysicalWrist) -> None:
    m = wrist.spm
    wrist.set_theta(m.theta_home)
    wrist.t = 0.0
    goal = m.theta_home + np.radians([6.0, -4.0, 3.0])
    _drive(wrist, goal)
    wrist.advance(0.02)
    stuck = float(wrist.theta()[1])
    wrist.command(1, float(goal[1]), True, True)
    wrist.advance(0.5)
    assert abs(math.degrees(wrist.theta()[1] - stuck)) < 0.1
    assert abs(math.degrees(wrist.theta()[0] - goal[0])) < 0.3  # the others reach their goals


def test_a_drive_straining_against_a_blocked_shaft_overloads_after_a_second(
        wrist: PhysicalWrist) -> None:
    m = wrist.spm
    wrist.set_theta(m.theta_home)
    wrist.t = 0.0
    goal = m.theta_home + np.radians([0.0, 20.0, 0.0])
    _drive(wrist, m.theta_home)
    wrist.command(1, float(goal[1]), True, True)  # blocked at home, asked 20° away: full duty
    wrist.advance(0.9)
    assert not wrist.overloaded(1)
    wrist.advance(1.1)
    assert wrist.overloaded(1) and not wrist.overloaded(0)
    wrist.command(1, float(m.theta_home[1]), False, True)  # torque off (the shutdown) ...
    wrist.command(1, float(m.theta_home[1]), True, True)  # ... and on again: strain anew
    assert not wrist.overloaded(1)


def _wrist_at_home() -> tuple[Profile, PhysicalWrist, list[JointMap], ControlTable]:
    """The default profile, its physical wrist at rest at home, its joints' tick maps and
    its servos' control table."""
    profile = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    m = model_of(profile)
    wrist = PhysicalWrist(m, P)
    wrist.set_theta(m.theta_home)
    return profile, wrist, joint_maps(profile), table_for(profile.bus.protocol)


def test_an_emulated_servo_stalled_on_the_physical_wrist_shuts_down_overloaded() -> None:
    """The servo's stall fault blocks its shaft; its drive strains at full duty against it and
    the firmware latches Overload (Hardware Error Status bit 5) and switches torque off."""
    profile, wrist, maps, table = _wrist_at_home()
    servos = [EmulatedServo(table, mp.id, profile.servo.p, mp.to_ticks(135.0), 0.0,
                            joint=PlantJoint(wrist, i, mp)) for i, mp in enumerate(maps)]
    for s in servos:
        s.write(table["torque_enable"].address, bytes([1]))
    blocked = servos[1]
    blocked.stall()
    goal = round(maps[1].to_ticks(155.0))
    reg = table["goal_position"]
    assert blocked.write(reg.address, reg.encode(goal)) == 0
    blocked.advance(0.8)
    assert blocked.torque and not blocked.hw_error
    blocked.advance(1.5)
    assert blocked.hw_error & OVERLOAD and not blocked.torque
    assert not servos[0].hw_error  # the others drive on


def test_the_drive_uses_the_gains_the_driver_wrote() -> None:
    """Position P Gain halved through the control table: half the duty for the same error."""
    profile, wrist, maps, table = _wrist_at_home()
    servo = EmulatedServo(table, maps[0].id, profile.servo.p, maps[0].to_ticks(135.0), 0.0,
                          joint=PlantJoint(wrist, 0, maps[0]))
    assert wrist.drives[0].gains.p == table["position_p_gain"].initial == 850
    reg = table["position_p_gain"]
    assert servo.write(reg.address, reg.encode(425)) == 0
    assert wrist.drives[0].gains.p == 425
    assert wrist.drives[0].duty(10.0, 0.0) == pytest.approx(425 / 128 * 10 / PWM_FULL)


def test_the_peak_current_is_the_largest_drive_current_step_by_step() -> None:
    """Reference: the drive's current (duty and the motor's speed as each step began) taken
    step by step with the public methods, its largest |value| per joint; with torque off
    nothing flows. A step of 20° asks for more than holding: the peak grows."""
    wrist = PhysicalWrist(model_of(load_profile(ROOT / "profiles" / "agile_wrist.toml")))
    wrist.advance(0.05)
    assert not wrist.take_peak_current().any()  # torque off: the windings are open
    _drive(wrist, wrist.theta() + np.radians([20.0, -15.0, 10.0]))
    dt, ref = P.timestep_s, np.zeros(3)
    for _ in range(round(0.4 / dt)):
        omega = wrist.motor_omega()
        wrist.advance(wrist.t + dt)
        d = Drive(P, TICKS_PER_RAD)
        ref = np.maximum(ref, [abs(d.current(float(wrist.duty[i]), float(omega[i])))
                               for i in range(3)])
    peak = wrist.take_peak_current()
    np.testing.assert_allclose(peak, ref, rtol=1e-12)
    assert (peak > 0.5).all()  # a 20° step drives at full duty for a while
    stall_a = P.supply_v / P.resistance_ohm
    assert (peak < 2 * stall_a).all()
    assert not wrist.take_peak_current().any()  # taken: a new window starts


def test_each_step_samples_the_firmware_as_the_drive_does() -> None:
    """The step loop inlines :meth:`Drive.duty`, :meth:`Drive.torque` and :meth:`Drive.current`
    (coefficients computed once per call): step by step, drives of the same gains fed the same
    goal and measured position give the same duty, the same motor torque (the actuator's
    control) and the same integral, to the last bit, also across a change of gains."""
    wrist = PhysicalWrist(model_of(load_profile(ROOT / "profiles" / "agile_wrist.toml")))
    assert wrist._motor_q  # the default plant has a gear play: the drive turns the rotor
    ref = [Drive(P, wrist.ticks_per_rad) for _ in range(3)]
    _drive(wrist, wrist.theta() + np.radians([12.0, -9.0, 5.0]))
    goal = [float(g) * wrist.ticks_per_rad for g in wrist.goal]
    for k in range(240):
        if k == 120:
            wrist.drives[1].gains = ref[1].gains = DriveGains(900, 300, 40, 600)
        present = [round(float(x) * wrist.ticks_per_rad) for x in wrist.theta()]
        omega = wrist.motor_omega()
        wrist.advance(wrist.t + P.timestep_s)
        for i in range(3):
            du = ref[i].duty(goal[i], present[i])
            assert float(wrist.duty[i]) == du, (k, i)
            assert float(wrist.data.ctrl[i]) == ref[i].torque(du, float(omega[i])), (k, i)
    assert [(d.integral, d.last_error, d.pwm) for d in wrist.drives] == \
        [(d.integral, d.last_error, d.pwm) for d in ref]
