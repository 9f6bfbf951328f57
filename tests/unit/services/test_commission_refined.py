"""The IMU stage's horn offsets move the zero it ran on, its fraction of a tick included (a
zero at rest has one; a jig's has none): true θ = θ read + δ, so the zero moves by −d·δ ticks."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import pytest

from spm_console.config.schema import Profile
from spm_console.services.commissioning.leg_map import LegMatch
from spm_console.services.commissioning.profile_out import commissioned_text
from spm_console.services.commissioning.stages import Commissioned, Discovery, refined

AGILE = Path(__file__).resolve().parents[3] / "profiles" / "agile_wrist.toml"


def _wired(profile: Profile) -> Commissioned:
    """``profile``'s wiring, mapped and zeroed as the profile has it (the IMU stage's input)."""
    joints = profile.bus.joints
    legs = tuple(LegMatch(j.id, k + 1, j.direction, 0.0, 0.0, 0.0)
                 for k, j in enumerate(joints))
    offsets = (joints[0].tick_offset, joints[1].tick_offset, joints[2].tick_offset)
    return Commissioned(Discovery("2.0", (), (1, 2, 3)), (legs[0], legs[1], legs[2]), None,
                        offsets, profile)


@pytest.mark.parametrize("trims", [(0.0, 0.0, 0.0), (0.31, -0.27, 0.05)])
def test_the_horns_move_the_zero_the_stage_ran_on(agile: Profile,
                                                   trims: tuple[float, float, float]) -> None:
    joints = agile.bus.joints
    legs = tuple(LegMatch(j.id, k + 1, j.direction, 0.0, 0.0, 0.0)
                 for k, j in enumerate(joints))
    offsets = (joints[0].tick_offset, joints[1].tick_offset, joints[2].tick_offset)
    before = Commissioned(Discovery("2.0", (), (1, 2, 3)), (legs[0], legs[1], legs[2]), None,
                          offsets, agile, tick_trims=trims)
    horn = (0.5, -0.25, 0.07)
    stage = SimpleNamespace(horn_deg=horn, arcs_deg=None, payload=None, tilt_deg=None)
    after = refined(before, stage)  # type: ignore[arg-type]
    tpd = agile.bus.ticks_per_turn / 360.0
    assert after.tick_offsets is not None
    for k, m in enumerate(legs):
        was = offsets[k] + trims[k]
        now = after.tick_offsets[k] + after.tick_trims[k]
        assert now == pytest.approx(was - m.direction * horn[k] * tpd, abs=1e-3)
        assert abs(after.tick_trims[k]) <= 0.5


def test_the_fitted_tilt_is_written_with_its_provenance(agile: Profile) -> None:
    """A tilt the IMU stage determined goes into ``[plant] base_tilt_deg`` (the load model's
    gravity), in the profile and in the text written, commented as the IMU fit's."""
    before = _wired(agile)
    stage = SimpleNamespace(horn_deg=(0.0, 0.0, 0.0), arcs_deg=None, payload=None,
                            tilt_deg=(1.23456, -2.5))
    after = refined(before, stage)  # type: ignore[arg-type]
    assert after.profile.plant.base_tilt_deg == (1.235, -2.5)
    text, back = commissioned_text(AGILE.read_text(), after, "test")
    assert back.plant.base_tilt_deg == (1.235, -2.5)
    line = next(ln for ln in text.splitlines() if ln.startswith("base_tilt_deg"))
    assert "IMU fit" in line


def test_the_port_is_written_and_an_unchanged_sign_seed_keeps_its_line(agile: Profile) -> None:
    """The bus the wrist was commissioned on becomes ``[bus] port`` (the template's empty
    port means the emulated bus: ``identify`` on the written profile would have identified
    that); arcs fitted that keep the home's sign seed leave its line (and its citation) as
    it was."""
    before = _wired(agile)
    g = agile.geometry
    stage = SimpleNamespace(horn_deg=(0.0, 0.0, 0.0), payload=None, tilt_deg=None,
                            arcs_deg=((0.1, 0.1, 0.1), (0.1, 0.1, 0.1)))  # the seed holds
    after = refined(before, stage)  # type: ignore[arg-type]
    assert after.profile.home.sign_seed == agile.home.sign_seed
    assert after.profile.geometry != g
    base = AGILE.read_text()
    text, back = commissioned_text(base, after, "test", port="/dev/ttyUSB0")
    assert back.bus.port == "/dev/ttyUSB0"
    seed = [ln for ln in base.splitlines() if ln.startswith("sign_seed")]
    assert seed and seed == [ln for ln in text.splitlines() if ln.startswith("sign_seed")]
    _text, same = commissioned_text(base, after, "test")
    assert same.bus.port == agile.bus.port  # none given: the base's kept


def test_a_weighed_mass_the_new_first_moment_does_not_place_is_taken_out_of_the_text(
        agile: Profile) -> None:
    """Re-commissioning a profile that holds a weighed mass: when the newly fitted first
    moment and that mass put the centre beyond ±300 mm, the mass's line is commented out
    (the profile otherwise keeps an old mass beside the new moment: refused, or wrong) and
    the report says why; a pseudo-terminal's port is not kept."""
    import numpy as np

    from spm_console.config.edit import with_values
    from spm_console.core.commissioning.payload import HoldingFit
    from spm_console.services.commissioning.payload_stage import PayloadReport
    from spm_console.services.commissioning.profile_out import commissioned_lines

    base_text, base = with_values(AGILE.read_text(), {
        ("plant", "payload_moment_kgmm"): [3.0, -1.5, 36.0], ("plant", "payload_kg"): 0.3},
        "weighed before", "base")
    before = _wired(base)
    fit = HoldingFit(np.array([0.0, 0.0, 0.12]), np.full(3, 0.001), 1.4, 0.05, 0.05,
                     np.ones(4), 24)  # 120 kg·mm: with 0.3 kg, 400 mm above the centre
    stage = SimpleNamespace(horn_deg=(0.0, 0.0, 0.0), arcs_deg=None, tilt_deg=None,
                            payload=PayloadReport(fit, 0.05), fit=SimpleNamespace(
                                parameters=[], undetermined_named=[]),
                            verification=SimpleNamespace(gravity_max_deg=0.05), motion_s=30.0)
    after = refined(before, stage)  # type: ignore[arg-type]
    assert after.profile.plant.payload_kg is None and after.payload_kg_weighed == 0.3
    text, back = commissioned_text(base_text, after, "test", port="/dev/pts/7")
    assert back.plant.payload_kg is None and back.plant.payload_moment_kgmm == (0.0, 0.0, 120.0)
    assert any(ln.startswith("# payload_kg = 0.3") for ln in text.splitlines()), text
    assert back.bus.port == base.bus.port  # a pty's name goes to the next terminal
    assert any("payload mass 0.3 kg (weighed) not written" in ln
               for ln in commissioned_lines(after))
    # and the report says the port was not written, and what the next commands need
    said = [ln for ln in commissioned_lines(after, "/dev/pts/7") if "[bus] port" in ln]
    assert len(said) == 1 and "/dev/pts/7 is a pseudo-terminal" in said[0]
    assert "give --port" in said[0] and "they drive the emulated bus" in said[0]
    assert not after.profile.bus.port  # the shipped profile: the emulated bus
    wired = after.profile.model_copy(update={"bus": after.profile.bus.model_copy(
        update={"port": "/dev/ttyUSB0"})})
    (kept,) = [ln for ln in commissioned_lines(dataclasses.replace(after, profile=wired), "/dev/pts/7")
               if "[bus] port" in ln]
    assert "they open /dev/ttyUSB0, the port it keeps" in kept
    assert not any("[bus] port" in ln for ln in commissioned_lines(after, "/dev/ttyUSB0"))


def test_a_jig_stage_that_found_the_servos_holding_warns_in_the_report(agile: Profile) -> None:
    """A wrist on its jig is powered with torque off: servos found holding (a wrist left held
    by an earlier run, not on its jig) make the jig's zero suspect; the report says so, and
    how to check it."""
    from dataclasses import replace

    from spm_console.services.commissioning.profile_out import commissioned_lines

    plain = _wired(agile)
    assert not any("warning" in ln for ln in commissioned_lines(plain))
    held = replace(plain, held_at_jig=(1, 3))
    (said,) = [ln for ln in commissioned_lines(held) if ln.startswith("warning")]
    assert "servo ids [1, 3] held the wrist (torque on)" in said
    assert "with the IMU stage to check it" in said
