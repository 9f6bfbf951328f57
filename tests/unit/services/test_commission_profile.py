"""What commissioning writes into a profile: the link arcs as fitted (the home sign seed follows
the home pose continued onto the new arcs: a component near 0 may change sign; the text parses
back through the loader's own home-mode check), and a zero between two ticks (``tick_trim``)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.edit import with_values
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.devices.dynamixel.tick_map import joint_maps
from spm_console.motion.logs.profile_record import wrist_digests
from spm_console.services.commissioning.stages import with_arcs

AGILE = Path(__file__).resolve().parents[3] / "profiles" / "agile_wrist.toml"
#: tests/data/as_built/twin.toml's arcs: they move v3x, 0 at the nominal home, to +0.0006.
ARC1 = (-0.4, 0.25, 0.1)
ARC2 = (0.2, -0.35, 0.3)


def test_arcs_that_move_a_home_component_across_zero_write_its_new_sign(agile: Profile) -> None:
    built = with_arcs(agile, ARC1, ARC2)
    assert built.geometry.alpha1_leg_offset_deg == ARC1
    before, after = model_of(agile).v_home, model_of(built).v_home
    assert np.abs(after - before).max() < 0.01  # the same mode, moved a little
    flipped = [k for k in range(9) if agile.home.sign_seed[k] != built.home.sign_seed[k]]
    assert flipped == [6] and abs(before[2, 0]) < 1e-9 < after[2, 0]  # v3x
    text, back = with_values(AGILE.read_text(), {
        ("geometry", "alpha1_leg_offset_deg"): list(ARC1),
        ("geometry", "alpha2_leg_offset_deg"): list(ARC2),
        ("home", "sign_seed"): list(built.home.sign_seed)}, "commissioned", "test")
    assert back.home.sign_seed == built.home.sign_seed
    assert "sign_seed = [" in text


def _with_trim(agile: Profile, trim: float) -> Profile:
    joints = list(agile.bus.joints)
    joints[1] = joints[1].model_copy(update={"tick_trim": trim})
    return Profile.model_validate(agile.model_copy(update={"bus": agile.bus.model_copy(
        update={"joints": tuple(joints)})}).model_dump(mode="python"))


def test_a_tick_trim_moves_the_joints_zero_by_a_fraction_of_a_tick(agile: Profile) -> None:
    trimmed = _with_trim(agile, 0.4)
    m0, m1 = joint_maps(agile)[1], joint_maps(trimmed)[1]
    assert m1.to_ticks(120.0) - m0.to_ticks(120.0) == pytest.approx(0.4, abs=1e-12)
    per_tick = 360.0 / agile.bus.ticks_per_turn
    assert m1.to_deg(2000.0) - m0.to_deg(2000.0) == pytest.approx(
        -m0.direction * 0.4 * per_tick, abs=1e-12)
    for bad in (0.6, -0.51):
        with pytest.raises(ValueError, match="tick_trim"):
            _with_trim(agile, bad)


def test_a_run_logs_wrist_digest_is_unchanged_until_a_trim_is_used(agile: Profile) -> None:
    data = agile.bus.model_dump(mode="json", exclude={"port", "baud", "timeout_s"})
    for joint in data["joints"]:
        del joint["tick_trim"]  # the bus section as it was digested before the key existed
    before = hashlib.sha256(json.dumps(data, sort_keys=True,
                                       separators=(",", ":")).encode()).hexdigest()
    assert wrist_digests(agile)["bus"] == before
    assert wrist_digests(_with_trim(agile, 0.25))["bus"] != before
