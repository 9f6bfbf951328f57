"""The emulated bus serving a wrist as built, through our own DynamixelBus on its socket: servo
ids, Drive Mode and horn offsets as built; the home jig and the truth log on the physical
wrist."""

from __future__ import annotations

import csv
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.as_built import AsBuilt, load_as_built
from spm_console.config.schema import Plant, Profile
from spm_console.devices.dynamixel.bus import DynamixelBus, open_bus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.servo import reversed_zero
from spm_console.devices.emulator.truth_log import HEADER, TruthLog
from spm_console.devices.emulator.twin import true_wrist
from spm_console.errors import BusError
from tests.support.paths import ROOT

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

TWIN = ROOT / "tests" / "data" / "as_built" / "twin.toml"
TPD = 4096 / 360


def _relaxed(profile: Profile) -> Profile:
    """A 30 ms reply timeout: a loaded 2-core test machine delays the emulator's thread; these
    tests are not about timing."""
    return profile.model_copy(update={"bus": profile.bus.model_copy(update={"timeout_s": 0.03})})


def _physical(profile: Profile) -> Profile:
    return profile.model_copy(update={"plant": Plant(model="physical")})


@pytest.fixture
def twin(agile: Profile) -> Iterator[tuple[EmulatorHandle, DynamixelBus]]:
    """The ideal servos of tests/data/as_built/twin.toml (ids [3, 1, 2], leg 2 reversed)."""
    em = start_emulator(agile, link="socket", truth=true_wrist(agile, load_as_built(TWIN)))
    bus = open_bus(_relaxed(agile), em.port, exclusive=False)
    yield em, bus
    bus.close()
    em.stop()


def test_permuted_ids_answer_as_built(agile: Profile) -> None:
    """Ids [7, 1, 2]: id 7 answers, id 3 (the profile's joint 3) does not; id 7 drives leg 1."""
    em = start_emulator(agile, link="socket", truth=true_wrist(agile, AsBuilt(ids=(7, 1, 2))))
    bus = open_bus(_relaxed(agile), em.port, exclusive=False)
    try:
        assert bus.ping(7).model_number == 321 and bus.ping(1).id == 1
        with pytest.raises(BusError, match="no status packet from servo id 3"):
            bus.ping(3)
        goal = round(em.maps[0].to_ticks(125.0))
        bus.write(7, "goal_position", goal)
        bus.write(7, "torque_enable", 1)
        time.sleep(0.5)  # eq. (27) with the profile's p: settled
        assert np.allclose(em.joint_deg(), [125.0, 135.0, 135.0], atol=0.1)
        # an id written (torque off, EEPROM; a sync write, which no servo answers) is the
        # servo's from the next packet on
        bus.sync_write("id", {1: 9})
        assert bus.ping(9).id == 9
        with pytest.raises(BusError):
            bus.ping(1)
    finally:
        bus.close()
        em.stop()


def test_a_reversed_servo_shows_its_drive_mode_and_counts_the_other_way(
        twin: tuple[EmulatorHandle, DynamixelBus]) -> None:
    em, bus = twin
    assert [bus.read(i, "drive_mode") & 1 for i in (3, 1, 2)] == [0, 1, 0]  # legs 1, 2, 3
    before = [bus.read(i, "present_position") for i in (3, 1, 2)]
    em.set_joint_deg([140.0, 140.0, 140.0])  # every leg +5° (true θ)
    after = [bus.read(i, "present_position") for i in (3, 1, 2)]
    assert np.allclose(np.subtract(after, before), [5 * TPD, -5 * TPD, 5 * TPD], atol=1.0)


def test_the_horn_offset_as_built(agile: Profile,
                                  twin: tuple[EmulatorHandle, DynamixelBus]) -> None:
    """At true θ = its horn offset, a leg counted as the profile says reads the profile's
    tick_offset; the reversed leg reads it mirrored, and the profile's once its Drive Mode is
    cleared."""
    em, bus = twin
    ab = load_as_built(TWIN)
    em.set_joint_deg(list(ab.horn_offset_deg))
    offsets = [j.tick_offset for j in agile.bus.joints]
    assert bus.read(3, "present_position") == offsets[0]
    assert bus.read(2, "present_position") == offsets[2]
    assert bus.read(1, "present_position") == reversed_zero(4096) - offsets[1]
    bus.write(1, "drive_mode", 0)
    assert bus.read(1, "present_position") == offsets[1]


def test_the_jig_holds_the_true_home_and_the_truth_log_runs_at_100_hz(
        agile: Profile, tmp_path: Path) -> None:
    """A 2 kg payload that would fold the wrist with torque off: the jig holds it at the true
    home until torque goes on; the truth log's rows come every 10 ms with unit quaternions."""
    prof = _physical(agile)
    ab = AsBuilt(payload_kg=2.0, payload_com_mm=(150.0, 0.0, 150.0), horn_offset_deg=(3.0, 0, 0),
                 base_tilt_deg=(2.0, 0.0))
    tw = true_wrist(prof, ab)
    log = TruthLog(tmp_path / "truth.csv")
    em = start_emulator(prof, link="socket", truth=tw, jig=True, truth_log=log)
    bus = open_bus(_relaxed(prof), em.port, exclusive=False)
    try:
        time.sleep(1.0)
        assert em.wrist is not None and em.wrist.jig_held
        assert np.allclose(em.joint_deg(), agile.home.theta_deg, atol=0.01)
        # what the product reads: the true home through horns it does not know of
        reads = [bus.read(i, "present_position") for i in (1, 2, 3)]
        assert reads == [round(j.present_ticks(135.0)) for j in tw.joints]
        assert reads[0] == 2048 - round(3.0 * TPD)
        truth = em.truth()
        assert truth.theta_deg == pytest.approx((135.0, 135.0, 135.0), abs=0.01)
        for i in (1, 2, 3):
            bus.write(i, "goal_position", bus.read(i, "present_position"))
        bus.write(1, "torque_enable", 1)  # the jig comes off
        time.sleep(0.05)
        assert not em.wrist.jig_held
        for i in (2, 3):
            bus.write(i, "torque_enable", 1)
        time.sleep(0.5)
    finally:
        bus.close()
        em.stop()
    assert not log.open and not log.full
    with open(log.path, newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == HEADER
    data = np.array(rows[1:], float)
    t = data[:, 0]
    assert len(t) > 100 and t[0] == 0.0
    assert np.allclose(np.diff(t), 0.01, atol=3e-4)  # the wrist's 0.25 ms step
    assert np.allclose(np.linalg.norm(data[:, 1:5], axis=1), 1.0, atol=1e-8)
    assert (data[:, 1] >= 0).all()
    assert np.abs(data[0, 5:] - 135.0).max() < 0.01
