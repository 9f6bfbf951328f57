"""Live servo health and tools: the status read (both protocols, a silent servo), torque per
joint (no lunge, refused while moving), the jog (homed only, within the limits, an ordinary
verified and logged motion), reboot clearing an injected hardware error (and un-homing)."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.models import servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.devices.dynamixel.bus import DynamixelBus, open_bus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import BadInputError, BusError, RefusedError
from spm_console.motion.logs.runlog import list_runs
from spm_console.motion.plans import line_plan
from spm_console.motion.servo_tools import (
    JOG_MAX_STEP_DEG,
    jog_target,
    read_health,
    reboot_joint,
    set_joint_torque,
)
from spm_console.refusals import Refusal
from spm_console.services.session import Session
from tests.runtime.test_bus_emulator import protocol1, relaxed

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

START = (128.0, 141.0, 133.0)


@pytest.fixture
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return Path(os.environ.get("SPM_CONSOLE_CACHE") or tmp_path_factory.mktemp("cache"))


@pytest.fixture(params=["2.0", "1.0"])
def rig(request: pytest.FixtureRequest, agile: Profile) -> Iterator[tuple[EmulatorHandle,
                                                                          DynamixelBus]]:
    prof = agile if request.param == "2.0" else protocol1(agile)
    em = start_emulator(prof, record=False, initial_deg=START)
    bus = open_bus(relaxed(prof), em.port)
    yield em, bus
    bus.close()
    em.stop()


# ---------------------------------------------------------------------------- on the bus
def test_health_values_are_plausible_on_both_protocols(rig: tuple[EmulatorHandle,
                                                                  DynamixelBus]) -> None:
    em, bus = rig
    h = read_health(bus)
    assert h.protocol == bus.protocol and h.silent == [] and h.faulted == []
    assert [j.joint for j in h.joints] == [1, 2, 3] and [j.id for j in h.joints] == bus.ids
    assert h.position_deg is not None
    np.testing.assert_allclose(h.position_deg, em.joint_deg(), atol=0.1)
    for j in h.joints:
        assert j.voltage_v is not None and 9.0 <= j.voltage_v <= 16.0  # MX-106: 10..14.8 V
        assert j.temperature_c is not None and 0.0 <= j.temperature_c <= 80.0
        assert j.torque_on is False and j.hardware_text == "none"
        if bus.protocol == "2.0":
            assert j.current_a is not None and j.load_pct is None and j.load_text.endswith(" A")
        else:
            assert j.load_pct is not None and j.current_a is None and j.load_text.endswith(" %")


def test_a_silent_servo_is_no_reply_and_the_others_still_show(agile: Profile) -> None:
    prof = agile.model_copy(update={"bus": agile.bus.model_copy(update={"joints": (
        agile.bus.joints[0], agile.bus.joints[1],
        agile.bus.joints[2].model_copy(update={"id": 9}))})})
    with start_emulator(agile, record=False) as em:
        bus = open_bus(relaxed(prof), em.port)
        try:
            h = read_health(bus)
        finally:
            bus.close()
    assert h.silent == [3] and h.position_deg is None
    assert h.joints[2].hardware_text == "no reply" and h.joints[2].load_text == "no reply"
    assert h.joints[0].voltage_v is not None and h.joints[1].hardware_text == "none"


def test_torque_on_holds_the_joint_where_it_is(agile: Profile) -> None:
    with start_emulator(agile, record=False, initial_deg=START) as em:
        bus = open_bus(relaxed(agile), em.port)
        try:
            with em._lock:  # a goal left 20° away while torque was off
                servo = em.servos[1]
                servo._set("goal_position", round(servo.pos + 20 * 4096 / 360))
            before = em.joint_deg()
            set_joint_torque(bus, 2, True)
            time.sleep(0.3)
            np.testing.assert_allclose(em.joint_deg(), before, atol=0.1)  # no lunge
            assert [j.torque_on for j in read_health(bus).joints] == [False, True, False]
            set_joint_torque(bus, 2, False)
            assert not any(j.torque_on for j in read_health(bus).joints)
        finally:
            bus.close()


def test_reboot_clears_a_latched_hardware_error(agile: Profile) -> None:
    with start_emulator(agile, record=False, faults=[parse_fault("hwerror:1")]) as em:
        bus = open_bus(relaxed(agile), em.port)
        try:
            h = read_health(bus)
            assert h.faulted == [1] and h.joints[0].hardware_text == "0x20 overload"
            with pytest.raises(BusError, match="reboot the servo first"):
                set_joint_torque(bus, 1, True)
            reboot_joint(bus, 1)
            h = read_health(bus)
            assert h.faulted == [] and h.joints[0].torque_on is False
            set_joint_torque(bus, 1, True)  # accepted again
        finally:
            bus.close()


def test_protocol1_has_no_reboot(agile: Profile) -> None:
    prof = protocol1(agile)
    with start_emulator(prof, record=False) as em:
        bus = open_bus(relaxed(prof), em.port)
        try:
            with pytest.raises(BusError, match="power-cycle"):
                reboot_joint(bus, 1)
        finally:
            bus.close()


def test_jog_target_stays_within_the_servo_limits(agile: Profile) -> None:
    limits = servo_limits_deg(agile)
    lo, hi = limits[0][0], limits[1][0]
    np.testing.assert_allclose(jog_target([135, 135, 135], 2, -2.5, limits), [135, 132.5, 135])
    assert jog_target([hi - 1, 135, 135], 1, 1.0, limits)[0] == hi  # onto the limit: fine
    with pytest.raises(BadInputError, match="outside its servo limits"):
        jog_target([hi - 1, 135, 135], 1, 1.5, limits)
    with pytest.raises(BadInputError, match="outside its servo limits"):
        jog_target([lo + 0.5, 135, 135], 1, -1.0, limits)
    for bad in (0.0, JOG_MAX_STEP_DEG + 0.5, float("nan"), float("inf")):
        with pytest.raises(BadInputError, match="step"):
            jog_target([135, 135, 135], 1, bad, limits)
    with pytest.raises(BadInputError, match="joint 4"):
        jog_target([135, 135, 135], 4, 1.0, limits)


# ------------------------------------------------------------------ through the runtime
def _session(agile: Profile, tmp_path: Path, cache: Path, **kw: object) -> Session:
    s = Session(agile, sim=True, logs_root=tmp_path / "logs", cache_dir=cache, **kw)  # type: ignore[arg-type]
    s.connect()
    return s


def test_status_through_the_runtime_and_tools_refused_while_a_jog_runs(
        agile: Profile, tmp_path: Path, cache: Path, paced_clock: None) -> None:
    # paced: in free-running simulated time the jog's 0.5 s can end before its first sample
    # reaches the callback, and the runtime, idle again, rightly answers the bus's requests
    s = _session(agile, tmp_path, cache, initial_deg=START)
    try:
        emu = s.emulator
        assert isinstance(emu, EmulatorHandle)
        h = s.tools.servo_status()
        assert s.tools.health is h and h.faulted == [] and h.position_deg is not None
        np.testing.assert_allclose(h.position_deg, START, atol=0.1)
        np.testing.assert_allclose(s.theta_deg, h.position_deg)  # θ follows the status
        assert all(j.voltage_v == pytest.approx(12.0) for j in h.joints)

        assert s.home().ok
        moving = threading.Event()
        refusals: list[str] = []

        def while_moving(_sample: object) -> None:
            if moving.is_set():
                return
            moving.set()
            bus = s.bus
            assert bus is not None
            for call in (lambda: s.tools.set_torque(2, False), s.tools.servo_status,
                         lambda: s.tools.reboot_servo(1), lambda: s.tools.jog(1, 1.0),
                         lambda: bus.set_torque(2, False), bus.status, lambda: bus.reboot(1)):
                try:
                    call()
                except BadInputError as exc:
                    refusals.append(exc.message)

        before = s.read_position()
        res = s.tools.jog(3, -JOG_MAX_STEP_DEG, while_moving)  # 0.5 s at 20°/s: heartbeats apply
        assert res.ok, res.message
        assert moving.is_set() and len(refusals) == 7, refusals
        assert all("moving" in m or "already running" in m for m in refusals), refusals
        assert s.homed  # nothing was switched off
        after = s.read_position()
        np.testing.assert_allclose(after, before + np.array([0, 0, -JOG_MAX_STEP_DEG]), atol=0.1)
        np.testing.assert_allclose(emu.joint_deg(), after, atol=0.1)
        jog_run = list_runs(tmp_path / "logs")[-1]  # logged like every motion
        assert jog_run.meta["outcome"] == "completed" and jog_run.meta["homing"] == "done"
        assert jog_run.meta["plans"][0]["source"].startswith("jog: joint 3 by -10°")

        # torque off un-homes the wrist, in the session and in the motion process
        h = s.tools.set_torque(1, False)
        assert [j.torque_on for j in h.joints] == [False, True, True] and not s.homed
        with pytest.raises(BadInputError, match="not homed"):
            s.tools.jog(2, 1.0)
        assert s.bus is not None
        plan = line_plan(agile, after, after + np.array([0, 1.0, 0]), 20.0)
        with pytest.raises(BadInputError, match="not homed"):
            s.bus.execute(plan)
    finally:
        s.close()


def test_jog_refused_unless_homed_and_within_the_limits(agile: Profile, tmp_path: Path,
                                                        cache: Path) -> None:
    hi = float(servo_limits_deg(agile)[1][0])
    s = _session(agile, tmp_path, cache, initial_deg=(hi - 2.0, 135.0, 135.0))
    try:
        with pytest.raises(BadInputError, match="not homed"):
            s.tools.jog(1, -1.0)
        assert s.bus is not None
        s.bus.homed = True  # a client that believes it is homed: its own checks come first …
        with pytest.raises(BadInputError, match="outside its servo limits"):
            s.tools.jog(1, 3.0)
        assert list_runs(tmp_path / "logs") == []  # nothing sent, nothing moved
        assert not s.homed  # … and the motion process's next answer corrected its belief
        theta0 = s.read_position()
        jog = line_plan(agile, theta0, theta0 + np.array([-1.0, 0.0, 0.0]),
                        agile.safety.home_speed_degps, kind="jog")
        with pytest.raises(RefusedError, match="not homed") as refused:  # the runtime decides
            s.bus.execute(jog)
        assert refused.value.reason == Refusal.NOT_HOMED
        runs = list_runs(tmp_path / "logs")
        assert [r.meta["outcome"] for r in runs] == ["refused"]
        np.testing.assert_allclose(s.read_position(), [hi - 2.0, 135, 135], atol=0.1)
    finally:
        s.close()


def test_reboot_clears_an_injected_hwerror_and_unhomes(agile: Profile, tmp_path: Path,
                                                       cache: Path) -> None:
    s = _session(agile, tmp_path, cache, faults=[parse_fault("hwerror:1")],
                 emulator_process=True)  # the console's emulator child takes the fault
    try:
        h = s.tools.servo_status()
        assert h.faulted == [1] and "overload" in h.joints[0].hardware_text
        with pytest.raises(BusError, match="reboot"):
            s.tools.set_torque(1, True)
        assert s.bus is not None
        s.bus.homed = True  # forged: the motion process's answer to the reboot says otherwise
        h = s.tools.reboot_servo(1)
        assert h.faulted == [] and h.joints[0].hardware_text == "none"
        assert not s.homed and s.tools.health is h
        assert s.tools.servo_status().faulted == []  # and it stays cleared
        assert s.tools.set_torque(1, True).joints[0].torque_on
    finally:
        s.close()
