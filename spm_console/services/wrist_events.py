"""What the emulated physical wrist saw during a run, written into the run's log afterwards.

The wrist's legs may touch (events ``collision``: the legs, their segments, the distance, θ;
``t`` in seconds since the run was asked for, on the emulator's clock) and, in a preview, each
motor's largest winding current over the run is told (event ``peak_current``, A). The servo
loop sees neither: they come from the twin itself, in its own process
(:class:`~spm_console.devices.emulator.child.EmulatorChild`, asked by a flush) or in a thread
of this one (a preview's twin in simulated time,
:class:`~spm_console.devices.emulator.bus.EmulatorHandle`).
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import Any

from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import EmulatorHandle
from spm_console.devices.emulator.child import EVENTS_EVERY_S, EmulatorChild
from spm_console.devices.emulator.contacts import Collision
from spm_console.motion.logs.runlog import append_events

COLLISION_REPORT_S = 1.5 * EVENTS_EVERY_S
"""Wait after a motion on the physical emulated wrist (in its own process) for its last leg
contacts to arrive when it did not answer a flush."""

Emulator = EmulatorHandle | EmulatorChild | None


def physical(emu: Emulator) -> bool:
    """Whether ``emu`` serves the physical wrist (its contacts and currents are known)."""
    if isinstance(emu, EmulatorChild):
        return emu.physical
    return isinstance(emu, EmulatorHandle) and emu.wrist is not None


def start_window(emu: Emulator) -> bool:
    """Start the window of a run's peak current (contacts are kept by time, not by window);
    whether it started (the child answered)."""
    if isinstance(emu, EmulatorChild):
        return emu.physical and emu.flush()
    if isinstance(emu, EmulatorHandle) and emu.wrist is not None:
        emu.take_peak_current()
        return True
    return False


def _told(emu: EmulatorHandle | EmulatorChild, began: float, until: float,
          window: bool) -> tuple[list[Collision], list[float] | None]:
    """(the contacts that began in [began, until], the window's peak current or None)."""
    if isinstance(emu, EmulatorChild):
        flushed = emu.flush()
        if not flushed:  # the child did not answer: take what it told so far
            time.sleep(COLLISION_REPORT_S)
        return emu.collisions(began, until), emu.peak_current_a() if flushed and window else None
    peak = emu.take_peak_current()  # steps the wrist to now first
    assert emu.wrist is not None
    hits = [c for c in emu.wrist.contacts.take() if began <= c.t <= until]
    return hits, None if peak is None or not window else [float(a) for a in peak]


def log_wrist_events(emu: Emulator, profile: Profile, log_dir: str | Path | None,
                     began: float, until: float, window: bool) -> None:
    """Write what the physical emulated wrist saw between ``began`` and ``until`` into the
    run's log (and its MCAP); ``window``: the peak current's window started with the run."""
    if emu is None or log_dir is None or not physical(emu):
        return
    hits, peak = _told(emu, began, until, window)
    events: list[dict[str, Any]] = [
        {"t": c.t - began, "event": "collision", "source": "emulated wrist",
         "legs": [x + 1 for x in c.legs], "segments": list(c.segments),
         "distance_mm": c.distance_mm, "theta_deg": list(c.theta_deg)} for c in hits]
    if peak is not None:
        events.append({"t": until - began, "event": "peak_current", "source": "emulated wrist",
                       "peak_current_a": peak})
    if not events:
        return
    append_events(Path(log_dir), events)
    from spm_console.motion.logs.mcap_log import MCAP_NAME, write_run_mcap  # loads mcap

    if (Path(log_dir) / MCAP_NAME).exists():  # (a preview's log has none)
        with contextlib.suppress(Exception):  # the MCAP carries them too (the run stands)
            write_run_mcap(Path(log_dir), profile)
