"""Cost of the physical emulated wrist's physics: wall time per simulated second.

The emulated servos step the MuJoCo wrist up to each request before they answer it, and every
millisecond when idle; a reply is lost when that takes longer than the bus's 4 ms timeout. At
0.23 s per simulated second (before this benchmark) the serving thread was busy half its time
and CI lost three replies in a row (a communication-loss stop) in the identification
experiment. The target, 0.125 s per simulated second, keeps the serving thread busy an eighth
of its time, a request waiting at most a quarter of a millisecond for the step to it.
Ours: :meth:`PhysicalWrist.advance` with the drives' firmware loops, motor model and leg
contact checks, the three goals stepped by ±10° every 0.1 s, default profile (gear play on).
Baseline: MuJoCo's ``mj_step`` alone for as many steps, the floor no drive model goes below.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from benchmarks.common import Row
from spm_console.config.load import load_profile
from spm_console.config.models import link_model_of, model_of
from spm_console.description.mjcf import plant_params
from spm_console.devices.emulator.physical import PhysicalWrist

SIMULATED_S = 2.0
TARGET_S_PER_S = 0.125


def _wrist() -> PhysicalWrist:
    profile = load_profile("profiles/agile_wrist.toml")
    wrist = PhysicalWrist(model_of(profile), plant_params(profile.plant),
                          profile.bus.ticks_per_turn, link_model_of(profile))
    wrist.set_theta(np.radians(profile.home.theta_deg))
    wrist.t = 0.0
    return wrist


def _ours() -> float:
    wrist = _wrist()
    home = np.array(wrist.goal, float)
    t0 = time.perf_counter()
    for k in range(round(SIMULATED_S / 0.1)):
        goal = home + np.radians(10.0 if k % 2 == 0 else -10.0)
        for i in range(3):
            wrist.command(i, float(goal[i]), True, False)
        wrist.advance(0.1 * (k + 1))
    return (time.perf_counter() - t0) / SIMULATED_S


def _floor() -> float:
    wrist = _wrist()
    steps = round(SIMULATED_S / wrist.params.timestep_s)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(wrist.mj, wrist.data)
    return (time.perf_counter() - t0) / SIMULATED_S


def run() -> list[Row]:
    ours = min(_ours() for _ in range(3))
    floor = min(_floor() for _ in range(3))
    return [Row("physical wrist: wall s per simulated s", ours, "s",
                f"<= {TARGET_S_PER_S}", floor, ours <= TARGET_S_PER_S,
                note="baseline: MuJoCo's mj_step alone (no drives, no contact checks)")]
