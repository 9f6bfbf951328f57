"""A stop that comes as one of the IMU stage's moves ends (the motion process has nothing left
to stop, and a stop it received while that run closed is not kept for the next) starts no
other move: the stage checks the E-stop before each."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.errors import BusError
from spm_console.services.client import EstopRelay

POSES = [(120.0, 120.0, 120.0), (110.0, 125.0, 118.0), (125.0, 112.0, 121.0)]


def test_a_stop_as_a_move_ends_starts_no_other_move(
        agile: Profile, monkeypatch: pytest.MonkeyPatch) -> None:
    import spm_console.services.commissioning.imu_stage as stage

    relay = EstopRelay("commission")
    moves: list[tuple[float, ...]] = []

    class Wrist:
        """A session whose every move completes, the stop pressed as it ends."""

        def __init__(self, profile: Profile, **_kw: object) -> None:
            self.theta = np.asarray(profile.home.theta_deg, float)
            self.wrist = SimpleNamespace(load_workspace=lambda: None)
            self.plans = SimpleNamespace(solve=self._solve)

        def connect(self) -> None:
            pass

        def require_bus(self) -> object:
            return SimpleNamespace(estop=lambda *_a: None)

        def home(self) -> object:
            return SimpleNamespace(ok=True)

        def read_position(self) -> np.ndarray:
            return self.theta.copy()

        @property
        def theta_deg(self) -> np.ndarray:
            return self.theta

        def _solve(self, _method: str, _start: object, goal: object, *_a: object,
                   **_kw: object) -> object:
            return getattr(goal, "values", None)

        def execute(self, plan: object) -> object:
            target = np.asarray(plan, float)
            moves.append(tuple(target))
            self.theta = target
            relay.estop("signal SIGINT")  # as the move ends
            return SimpleNamespace(ok=True)

        def close(self) -> None:
            pass

    design = SimpleNamespace(theta_deg=POSES, orientation_std_deg=0.1)
    monkeypatch.setattr(stage, "Session", Wrist)
    monkeypatch.setattr(stage, "_design", lambda *_a: (design, [False, False, True]))
    monkeypatch.setattr(stage, "SETTLE_S", 0.0)
    imu = SimpleNamespace(specific_force=lambda: np.array([0.0, 0.0, 9.81]))
    with pytest.raises(BusError, match="commission stopped: signal SIGINT"):
        stage.refine_with_imu(agile, "/dev/null", imu, lambda _m: None, stop=relay)  # type: ignore[arg-type]
    assert moves == [POSES[0]]
