"""The smallest rotor inertia a profile accepts keeps the physical emulated wrist stable."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from spm_console.config.models import model_of
from spm_console.config.plant import PLANT_STEP_S, STALL_DAMPING_NMS
from spm_console.config.schema import Plant
from spm_console.description.mjcf import plant_params
from spm_console.devices.emulator.physical import PhysicalWrist
from tests.support.ws_helpers import agile_profile


def test_an_armature_the_emulator_cannot_integrate_is_not_a_plant() -> None:
    """At 1e-4 kg·m² (BAM measured 0.026 on the MX-106) the emulated drive's back-EMF damping
    alone rang the wrist up within milliseconds of torque-on."""
    with pytest.raises(ValidationError, match="armature_kgm2"):
        Plant(armature_kgm2=1e-4)


def test_at_the_smallest_armature_accepted_a_stalled_joint_leaves_the_others_on_goal() -> None:
    """The gear's play on (the rotor alone behind the back-EMF damping and the stall's stop):
    the bound keeps a factor of two from the explicit step's limit (0.45 of it went unstable
    within milliseconds of the stall)."""
    d = Plant()
    least = PLANT_STEP_S * (d.kt_nm_per_a**2 / d.resistance_ohm + STALL_DAMPING_NMS)
    plant = Plant(armature_kgm2=least)
    assert plant.backlash_deg > 0
    wrist = PhysicalWrist(model_of(agile_profile()), plant_params(plant))
    start = wrist.theta().copy()
    goal = start + math.radians(5.0)
    for i in range(3):
        wrist.command(i, float(goal[i]), True, i == 1)
    wrist.advance(1.0)
    err = np.degrees(np.abs(wrist.theta() - goal))
    assert np.all(np.isfinite(err)) and err[0] < 0.2 and err[2] < 0.2, err
    assert abs(err[1] - 5.0) < 0.5, err  # the stalled joint stayed where it stuck
