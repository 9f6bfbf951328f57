"""The scripted-session file format (TOML): typed, validated steps.

See :mod:`spm_console.scripting.runner` for the format's documentation and the runner.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, Strict, ValidationError, field_validator

from spm_console.config.plant import PlantModel
from spm_console.config.schema import Count, Real
from spm_console.core.bounds import MX106_NO_LOAD_SPEED_DEGPS, N_MAX
from spm_console.errors import BadInputError, ExitCode, SpmError
from spm_console.input_rules import STEPS_MIN
from spm_console.safe_io import MB, parse_toml, read_text

#: Largest script file read.
MAX_SCRIPT_BYTES = 1 * MB

#: A boolean, never a number or a string.
Flag = Annotated[bool, Strict()]
Vec3 = tuple[Real, Real, Real]


class ScriptAssertionError(SpmError):
    """A scripted ``assert`` step found a condition false."""

    exit_code = ExitCode.ASSERTION_FAILED


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    @field_validator("*", mode="after")
    @classmethod
    def _finite(cls, v: Any) -> Any:
        vals = v if isinstance(v, tuple) else (v,)
        if any(isinstance(x, float) and not math.isfinite(x) for x in vals):
            raise ValueError("must be finite")
        return v


class SessionSpec(_Model):
    """The ``[session]`` table."""

    profile: str | None = None
    port: str = ""
    initial_deg: Vec3 | None = None
    faults: tuple[str, ...] = ()
    logs: str | None = None
    plant: PlantModel | None = None
    """The emulated wrist (as ``--plant``): None keeps the profile's ``[plant] model``."""


class ThetaPose(_Model):
    theta: Vec3


class RpyPose(_Model):
    rpy: Vec3


PoseIn = Literal["current", "home"] | ThetaPose | RpyPose


class HomeStep(_Model):
    do: Literal["home"]


class FkStep(_Model):
    do: Literal["fk"]
    theta: Vec3 | None = None
    rpy: Vec3 | None = None
    all_modes: Flag = False


class WorkspaceStep(_Model):
    do: Literal["workspace"]
    rebuild: Flag = False
    check: Vec3 | None = None


class PlanStep(_Model):
    do: Literal["plan"]
    method: Literal["mvn", "mintime"] = "mvn"
    start: PoseIn = "current"
    goal: PoseIn
    steps: Count = Field(default=150, ge=STEPS_MIN, le=N_MAX)
    vmax: Real | None = Field(default=None, gt=0.0, le=MX106_NO_LOAD_SPEED_DEGPS)


class ExecuteStep(_Model):
    do: Literal["execute"]
    allow_stop: Flag = False


class FollowStep(_Model):
    """Live following of timed targets: rows ``[t, a, b, c]`` (s; θ in degrees, or roll, pitch,
    yaw in degrees from home with ``rpy``) or a CSV ``file`` of the same rows."""

    do: Literal["follow"]
    targets: tuple[tuple[Real, Real, Real, Real], ...] | None = Field(
        default=None, min_length=1, max_length=100_000)
    file: str | None = None
    rpy: Flag = False
    allow_stop: Flag = False


class WaitStep(_Model):
    do: Literal["wait"]
    seconds: Real = Field(ge=0.0, le=3600.0)


class AssertStep(_Model):
    do: Literal["assert"]
    outcome: Literal["completed", "stopped"] | None = None
    exit_code: Count | None = None
    theta_near: Vec3 | None = None
    tol_deg: Real = Field(default=0.5, gt=0.0, le=360.0)
    feasible: Flag | None = None
    zeta_min: Real | None = Field(default=None, ge=0.0, le=1.0)
    max_duration_s: Real | None = Field(default=None, gt=0.0, le=3600.0)


Step = Annotated[
    HomeStep | FkStep | WorkspaceStep | PlanStep | ExecuteStep | FollowStep | WaitStep
    | AssertStep,
    Field(discriminator="do"),
]


class Script(_Model):
    session: SessionSpec = SessionSpec()
    step: tuple[Step, ...] = Field(min_length=1)
    _source: str = PrivateAttr(default="script")

    @property
    def source(self) -> str:
        """The file the script was read from: what its refusals name."""
        return self._source


def _where(loc: tuple[int | str, ...], data: dict[str, Any]) -> str:
    """'step 3 (plan) key goal' from a pydantic error location."""
    if len(loc) >= 2 and loc[0] == "step" and isinstance(loc[1], int):
        i = loc[1]
        steps = data.get("step")
        do = steps[i].get("do", "?") if isinstance(steps, list) and i < len(steps) and \
            isinstance(steps[i], dict) else "?"
        rest = [str(x) for x in loc[2:] if x not in ("home", "fk", "workspace", "plan", "execute", "follow",
                                                    "wait", "assert")]
        rest = [r for r in rest if r not in ("ThetaPose", "RpyPose") and not r.startswith("literal")]
        return f"step {i + 1} ({do})" + (f" key '{'.'.join(rest)}'" if rest else "")
    return "key '" + ".".join(str(x) for x in loc) + "'"


def parse_script(text: str, source: str) -> Script:
    """Validate a script; errors name the file, the step and the key."""
    data = parse_toml(text, source, BadInputError,
                      "not valid TOML: arrays or tables nested too deeply")
    try:
        script = Script.model_validate(data)
        script._source = source
        return script
    except ValidationError as exc:
        seen: list[str] = []
        for err in exc.errors():
            loc = tuple(err["loc"])
            if loc and isinstance(loc[-1], int) and len(loc) > 2:  # an item of a θ triple
                loc = loc[:-1]
                err = {**err, "type": "triple", "msg": "expected three finite numbers (degrees)"}
            reason = {"extra_forbidden": "unknown key", "missing": "missing key",
                      "union_tag_invalid": "unknown step kind (do = home, fk, workspace, "
                      "plan, execute, follow, wait or assert)"}.get(err["type"], err["msg"])
            if loc == ("step",):
                if data.get("step"):
                    continue  # a consequence of the failing steps reported above
                reason = "no [[step]] tables: nothing to do"
            if (len(loc) >= 4 and loc[0] == "step" and loc[2] == "plan"
                    and loc[3] in ("start", "goal") and err["type"] != "missing"):
                loc = loc[:4]
                reason = ('expected "current", "home", {theta = [θ1, θ2, θ3]} or '
                          '{rpy = [roll, pitch, yaw]} (degrees)')
            if isinstance(err.get("input"), float) and not math.isfinite(err["input"]):
                reason = "must be a finite number"
            line = f"{source}: {_where(loc, data)}: {reason}"
            if line not in seen:
                seen.append(line)
        raise BadInputError("\n".join(seen[:8])) from None


def load_script(path: str | Path) -> Script:
    p = Path(path)
    return parse_script(read_text(p, "script", MAX_SCRIPT_BYTES, BadInputError), str(p))
