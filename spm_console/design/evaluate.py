"""One design of a sweep: its profile (the base's TOML with the design's values), its
workspace (Algorithm 2 and P, eq. (30)), its figures of merit and, when the spec names
start/goal pairs, whether each can be planned (minimum time, eq. (31)).

:func:`evaluate` is what a sweep's worker runs: it holds no state between designs (all it
needs travels in its :class:`DesignTask`), so a task lost with its worker is simply run
again. A design that cannot be built — a profile the checks refuse, no forward kinematics or
a singular or infeasible home — is a row with its reason, never an exception.
"""

from __future__ import annotations

import math
import os
import socket
import time
import tomllib
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from spm_console.config.load import check_home_mode, home_signs, parse_profile
from spm_console.config.models import geometry_of, grid_spec, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.modes import home_model
from spm_console.core.workspace.metrics import WorkspaceMetrics, workspace_metrics
from spm_console.core.workspace_build import build_workspace
from spm_console.design.spec import PARAMETERS
from spm_console.errors import ProfileError, SpmError

#: How the reason of a design that met a bug begins (the sweep reports how many did, and a
#: resumed sweep runs them again).
INTERNAL_ERROR = "internal error"
#: How the reason of a design whose task killed its workers begins (run again on resume).
KILLED_WORKER = "its task killed"

#: The columns of a design's figures of merit: those of WorkspaceMetrics, in order, and the
#: torsion range.
METRICS = (*(f.name for f in fields(WorkspaceMetrics)), "torsion_range_deg")
#: The figures that are counts.
INT_FIGURES = frozenset(f.name for f in fields(WorkspaceMetrics) if f.type in ("int", int))


@dataclass(frozen=True)
class DesignTask:
    """Everything one design needs (plain data: it travels to a worker)."""

    index: int
    params: dict[str, float]
    """Parameter name -> value (deg or mm)."""
    base_text: str
    """The base profile's TOML."""
    step_deg: float
    """The workspace grid's Δ, deg."""
    pairs: tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...] = ()
    """(start, goal) motor angles, deg."""


@dataclass(frozen=True)
class DesignRow:
    """One design's result: parameters, figures of merit (NaN when it failed), cost."""

    index: int
    params: dict[str, float]
    ok: bool
    reason: str
    """Why the design could not be built ("" when ok)."""
    metrics: WorkspaceMetrics | None
    """The design's figures of merit (None when it could not be built)."""
    pair_times_s: tuple[float, ...] = ()
    """Minimum time of each start/goal pair, s (NaN: no plan)."""
    pair_reasons: tuple[str, ...] = ()
    """Why a pair has no plan ("" when it has one)."""
    seconds: float = 0.0
    """Wall time of the design on its worker, s."""
    worker: str = ""
    """host:pid of the process that computed it."""
    sign_seed: tuple[int, ...] = field(default_factory=tuple)
    """The home assembly mode's signs for this geometry (the base's mode, followed)."""

    @property
    def pairs_planned(self) -> int:
        return sum(1 for t in self.pair_times_s if math.isfinite(t))

    @property
    def retry(self) -> bool:
        """Not this design's own outcome (a bug, a killed worker): run again on resume."""
        return not self.ok and self.reason.startswith((INTERNAL_ERROR, KILLED_WORKER))

    def figure(self, name: str) -> float:
        """One figure of merit by its column name (:data:`METRICS`); NaN when not built."""
        m = self.metrics
        if m is None:
            return math.nan
        return m.torsion_range_deg if name == "torsion_range_deg" else float(getattr(m, name))

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        if self.metrics is not None:
            d["metrics"] = {k: (None if not math.isfinite(v) else v)
                            for k, v in asdict(self.metrics).items()}
        d["pair_times_s"] = [None if not math.isfinite(t) else t for t in self.pair_times_s]
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> DesignRow:
        """A row as :meth:`to_json` wrote it (ValueError, KeyError or TypeError otherwise)."""
        def num(x: Any) -> float:
            if isinstance(x, bool) or not isinstance(x, int | float | None):
                raise TypeError(f"not a number: {x!r}")
            return math.nan if x is None else float(x)

        m = d["metrics"]
        metrics = None
        if m is not None:
            if set(m) != {f.name for f in fields(WorkspaceMetrics)}:
                raise KeyError("metrics: not the figures of merit")
            values: dict[str, Any] = {k: (int(v) if k in INT_FIGURES and isinstance(v, int)
                                          else num(v)) for k, v in m.items()}
            metrics = WorkspaceMetrics(**values)
        return cls(
            index=int(d["index"]), params={str(k): num(v) for k, v in d["params"].items()},
            ok=bool(d["ok"]), reason=str(d["reason"]), metrics=metrics,
            pair_times_s=tuple(num(t) for t in d.get("pair_times_s", ())),
            pair_reasons=tuple(str(r) for r in d.get("pair_reasons", ())),
            seconds=float(d.get("seconds", 0.0)), worker=str(d.get("worker", "")),
            sign_seed=tuple(int(s) for s in d.get("sign_seed", ())),
        )


def design_profile(base_text: str, params: dict[str, float], source: str,
                   step_deg: float | None = None) -> Profile:
    """The profile of one design: the base's TOML with ``params`` in ``[geometry]`` /
    ``[links]`` (and the grid step ``step_deg`` when given), and the home assembly mode the
    base's seed selects, followed to this geometry (its signs become the seed). ProfileError
    when the checks refuse it; ValueError when the home pose cannot be solved."""
    try:
        data: dict[str, Any] = tomllib.loads(base_text)
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ProfileError(f"{source}: the base profile is not valid TOML: {exc}") from None
    for name, value in params.items():
        data.setdefault(PARAMETERS[name], {})[name] = float(value)
    if step_deg is not None:
        data.setdefault("workspace", {})["step_deg"] = float(step_deg)
    prof = parse_profile(data, source)
    try:
        with np.errstate(all="ignore"):
            model = home_model(geometry_of(prof), np.radians(np.asarray(prof.home.theta_deg)),
                               np.asarray(prof.home.sign_seed, float))
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise ValueError(f"home: {exc}") from None
    if not np.isfinite(model.v_home).all():
        raise ValueError("home: the forward kinematics gives no finite pose")
    data["home"]["sign_seed"] = home_signs(model.v_home.tolist())
    prof = parse_profile(data, source)
    check_home_mode(prof, source)
    return prof


def _pairs(prof: Profile, region: Any, task: DesignTask) -> tuple[tuple[float, ...], tuple[str, ...]]:
    from spm_console.core.planning.mintime import solve_mintime

    model = servo_model_of(prof)
    times: list[float] = []
    reasons: list[str] = []
    for start, goal in task.pairs:
        try:
            res = solve_mintime(model, np.asarray(start), np.asarray(goal), region,
                                prof.limits.vmax_degps)
            times.append(res.N * prof.servo.ts_s)
            reasons.append("")
        except SpmError as exc:
            times.append(math.nan)
            reasons.append(exc.message)
    return tuple(times), tuple(reasons)


def evaluate(task: DesignTask) -> DesignRow:
    """Build and measure one design (see the module docstring). Never raises: a design that
    cannot be built, or meets a bug, is a row with its reason."""
    t0 = time.perf_counter()
    who = f"{socket.gethostname()}:{os.getpid()}"

    def failed(reason: str) -> DesignRow:
        return DesignRow(task.index, dict(task.params), False, reason, None,
                         seconds=time.perf_counter() - t0, worker=who)

    source = f"design {task.index}"
    try:
        prof = design_profile(task.base_text, task.params, source, task.step_deg)
        with np.errstate(all="ignore"):
            ws = build_workspace(grid_spec(prof), cover=False)
        m = workspace_metrics(ws)
        times, reasons = _pairs(prof, ws.region, task) if task.pairs else ((), ())
    except (SpmError, ValueError, np.linalg.LinAlgError) as exc:
        return failed(exc.message if isinstance(exc, SpmError) else str(exc))
    except Exception as exc:  # a bug on one design's geometry must not stop a whole sweep
        return failed(f"{INTERNAL_ERROR}: {type(exc).__name__}: {exc} (please report it with "
                      "this design's parameters)")
    return DesignRow(task.index, dict(task.params), True, "", m, times, reasons,
                     seconds=time.perf_counter() - t0, worker=who,
                     sign_seed=tuple(prof.home.sign_seed))
