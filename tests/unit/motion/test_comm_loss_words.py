"""What a communication loss says of its cause: on real servos the cable, power and port; on
the emulated bus an injected fault or a late machine; in simulated time, where the clock waits
for every reply, an injected fault or a gone emulator, never lateness."""

from __future__ import annotations

import pytest

from spm_console.config.schema import Profile
from spm_console.motion.safety import SafetyMonitor


def _lost(monitor: SafetyMonitor) -> str:
    for k in range(monitor.cfg.comm_failures):
        reason = monitor.comm(False, 1, 0.02 * k, k, "timeout")
    assert reason is not None and reason.kind == "comm"
    return reason.message


@pytest.mark.parametrize(("emulated", "simulated", "says", "not_said"), [
    (False, False, "check the cable, power and port", "emulated"),
    (True, False, "this machine did not run the emulated servos in time", "cable"),
    (True, True, "in simulated time, where no reply can be late", "in time ("),
])
def test_the_cause_named_is_one_the_bus_can_have(agile: Profile, emulated: bool,
                                                 simulated: bool, says: str,
                                                 not_said: str) -> None:
    text = _lost(SafetyMonitor(agile, emulated=emulated, simulated_time=simulated))
    assert text.startswith("communication lost:") and says in text
    assert not_said not in text
