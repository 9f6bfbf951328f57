"""An E-stop in simulated time acts at the simulated instant it was sent, however long its
message waits on a busy machine: time waits for the motion process to take it."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import start_emulator
from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.motion.protocol import EStop
from spm_console.motion.sample import Sample
from spm_console.services.client import MotionClient
from spm_console.system.simclock import SimClock
from tests.support.exec_helpers import PAPER_START

GOAL = np.array([100.0, 120.0, 110.0])
#: How long the front end's E-stop message is held before it is written: five periods.
HELD_S = 0.1


def test_an_e_stop_message_held_up_acts_at_its_stamp(agile: Profile, tmp_path: Path,
                                                     tmp_path_factory: pytest.TempPathFactory) -> None:
    clock = SimClock.create(rate=1.0)  # paced at real time: the loop runs on while it waits
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START), sim=clock)
    cache = Path(os.environ.get("SPM_CONSOLE_CACHE") or tmp_path_factory.mktemp("cache"))
    client = MotionClient(agile, emu.port, cache_dir=cache, logs_root=tmp_path, sim_clock=clock)
    send = client.conn.send

    def held_send(msg: object) -> None:  # a front end kept off the core with its message
        if isinstance(msg, EStop):
            threading.Event().wait(HELD_S)
        send(msg)

    client.conn.send = held_send  # type: ignore[method-assign]
    stopped = threading.Event()

    def on_sample(s: Sample) -> None:
        if s.k == 25 and not stopped.is_set():
            stopped.set()
            threading.Thread(target=client.estop, args=("test E-stop",)).start()

    try:
        res = client.execute(synthetic_plan(agile, PAPER_START, GOAL, 4.0), on_sample,
                             skip_homing="test")
    finally:
        client.close()
        emu.stop()
        clock.close()
    assert res.exit_code == ExitCode.STOP_ESTOP and "test E-stop" in res.message
    stop, = (e for e in load_run(res.log_dir).events if e["event"] == "stop")
    ts = agile.servo.ts_s
    # held five periods on the wall clock, met within the period of its stamp all the same
    assert stop["detected_t"] - stop["requested_t"] <= ts, stop
    assert stop["done_t"] - stop["detected_t"] <= 2 * ts, stop
