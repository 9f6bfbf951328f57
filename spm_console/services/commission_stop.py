"""An E-stop that reaches commissioning wherever it is: commissioning opens a motion process
of its own for each stage (scan, map, IMU poses), so a front end holds this switch instead of
a session. Pressed from any thread (a key, a signal handler), it stops the running nudge or
move in the motion process attached now, and the stages that follow refuse to start."""

from __future__ import annotations

from typing import TYPE_CHECKING

from spm_console.errors import BusError

if TYPE_CHECKING:
    from spm_console.services.client import MotionClient


class CommissionStop:
    """The E-stop of one commissioning run (plain attribute writes: safe from a signal
    handler, no lock)."""

    def __init__(self) -> None:
        self.reason = ""
        """Why it was pressed ("" until then)."""
        self._client: MotionClient | None = None

    def attach(self, client: MotionClient) -> None:
        """The motion process the next stage runs in; refused with
        :class:`~spm_console.errors.BusError` when the switch was pressed already."""
        self._client = client
        self.check()

    def detach(self) -> None:
        """That motion process is closing."""
        self._client = None

    def estop(self, reason: str, by_signal: bool = False) -> bool:
        """Stop the running nudge or move (the motion process keeps an E-stop that comes
        between two of them for the next one); True."""
        if not self.reason:
            self.reason = reason
        client = self._client
        if client is not None:
            client.estop(reason, by_signal)
        return True

    def check(self) -> None:
        """Raise :class:`~spm_console.errors.BusError` once the switch was pressed."""
        if self.reason:
            raise BusError(f"commission stopped: {self.reason}; the wrist holds or is "
                           "torque off. Nothing was written")
