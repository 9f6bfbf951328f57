"""Physics checks of a profile, and the messages of every profile error.

:mod:`spm_console.config.schema` validates types and per-field ranges (pydantic). This
module adds what one field alone cannot say — the θ grid fits in memory, the
servo model is well sampled, the Bus Watchdog outlasts a sampling interval, δ is
smaller than the link radii, the servo limits map onto the encoder, the home sign
seed is the home's assembly mode and the home is feasible — and turns pydantic
errors into messages that name the file, the key, the value and the allowed range.

Import order: ``profile`` imports this module; this module only imports the
core lazily (the core's ``model_of`` takes a profile), never at import time.
"""

from __future__ import annotations

import json
import math
import types
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from spm_console.config.fields import ANGLE_LIMIT_DEG
from spm_console.config.schema import Profile
from spm_console.core.bounds import MX106_NO_LOAD_SPEED_DEGPS
from spm_console.errors import ProfileError

#: Largest θ grid, nodes. The shipped 2° grid has 46³ = 97,336 nodes and the 1° grid
#: (reproduction) 91³ = 753,571; 2,000,000 allows up to 125 values per axis.
MAX_GRID_NODES = 2_000_000
#: Peak memory of a workspace build per grid node, bytes (tracemalloc on the 3° and 2°
#: grids: ≈ 410 B/node for the FK flood fill — θ 24, R 72, v 72, w 72 B and temporaries —
#: and ≈ 600–700 B/node with the region construction; rounded up).
BYTES_PER_NODE = 700
#: Band of p·Ts (pole times sampling interval). Below, the homing plan's settle time
#: ⌈10/(p·Ts)⌉ exceeds 10,000 samples; above, the step response is within e^−10 ≈ 5e-5
#: of its goal after one sample: the sampled model (28) has no dynamics left, and plans
#: cannot keep the speed bound between samples (measured with Ts = 20 ms: MVN plans of
#: p = 600 and 1000 are refused by the runtime's verification, p = 500 passes).
PTS_MIN, PTS_MAX = 1e-3, 10.0
#: Unit of the Dynamixel Bus Watchdog register, ms; the register holds 1..127 units.
WATCHDOG_UNIT_MS = 20
WATCHDOG_MAX_UNITS = 127
#: Segment name -> the link radii (keys of ``links``) of its two end points.
SEGMENT_RADII = {"AB": ("oa_mm", "ob_mm"), "BC": ("ob_mm", "oc_mm"),
                 "DE": ("od_mm", "oe_mm"), "EF": ("oe_mm", "of_mm")}


@dataclass(frozen=True)
class Problem:
    """One invalid value: its key, the value, and the reason with the allowed range."""

    key: str
    value: object
    reason: str

    def line(self, source: str) -> str:
        return f"{source}: key '{self.key}' = {show(self.value)}: {self.reason}"


# ---------------------------------------------------------------- value and range text


def num(x: float | int) -> str:
    """A bound or value as the operator would write it: 1000, 0.02, 1e-06, inf."""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    if math.isfinite(x) and x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def show(value: object, limit: int = 80) -> str:
    """A value as TOML spells it (true, "text", inf, nan, [1, 2]), cut at ``limit`` characters."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = repr(value)
    elif isinstance(value, int):
        text = str(value)
    elif isinstance(value, str):
        text = json.dumps(value, ensure_ascii=False)  # quoted, control characters escaped
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(show(v, limit) for v in value) + "]"
    elif isinstance(value, dict):
        text = "{" + ", ".join(f"{k} = {show(v, limit)}" for k, v in value.items()) + "}"
    else:
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _unwrap(tp: Any) -> tuple[Any, list[Any]]:
    """(base type, metadata) of a possibly ``Annotated`` type."""
    meta: list[Any] = []
    while get_origin(tp) is Annotated:
        args = get_args(tp)
        tp, meta = args[0], [*meta, *args[1:]]
    return tp, meta


def _flatten(meta: Sequence[Any]) -> list[Any]:
    out: list[Any] = []
    for m in meta:
        if isinstance(m, FieldInfo):
            out += _flatten(m.metadata)
        else:
            out.append(m)
    return out


def _leaf(root: type[BaseModel], loc: Sequence[int | str]) -> tuple[Any, list[Any]] | None:
    """The declared type and constraints at ``loc`` (a pydantic error location), if any."""
    tp: Any = root
    meta: list[Any] = []
    for item in loc:
        tp, _ = _unwrap(tp)
        meta = []
        if isinstance(item, str):
            if not (isinstance(tp, type) and issubclass(tp, BaseModel)) or item not in tp.model_fields:
                return None
            field = tp.model_fields[item]
            tp, meta = field.annotation, list(field.metadata)
        else:
            if get_origin(tp) is not tuple:
                return None
            args = get_args(tp)
            if len(args) == 2 and args[1] is Ellipsis:
                tp = args[0]
            elif 0 <= item < len(args):
                tp = args[item]
            else:
                return None
    tp, more = _unwrap(tp)
    return tp, _flatten([*meta, *more])


def _bounds(meta: Sequence[Any]) -> tuple[Any, bool, Any, bool]:
    """(low, low inclusive, high, high inclusive) of a field's constraints, as declared
    (None where there is none)."""
    low: Any = None
    high: Any = None
    low_in = high_in = False
    for m in meta:
        for attr in ("gt", "ge", "lt", "le"):
            bound = getattr(m, attr, None)
            if bound is None:
                continue
            if attr in ("gt", "ge"):
                low, low_in = bound, attr == "ge"
            else:
                high, high_in = bound, attr == "le"
    return low, low_in, high, high_in


def field_bounds(root: type[BaseModel], loc: Sequence[int | str]) -> tuple[float, bool, float, bool]:
    """(low, low inclusive, high, high inclusive) of the number at ``loc`` as the schema
    declares it; ±inf where it sets none (KeyError when ``loc`` names no field)."""
    found = _leaf(root, loc)
    if found is None:
        raise KeyError(".".join(map(str, loc)))
    low, low_in, high, high_in = _bounds(found[1])
    return (-math.inf if low is None else float(low), low_in,
            math.inf if high is None else float(high), high_in)


def allowed(root: type[BaseModel], loc: Sequence[int | str]) -> str | None:
    """The allowed values at ``loc``, e.g. ``0 < p ≤ 1000`` or ``one of "zoh", "tustin"``."""
    found = _leaf(root, loc)
    if found is None:
        return None
    tp, meta = found
    names = [x for x in loc if isinstance(x, str)]
    name = names[-1] if names else "value"
    if loc and isinstance(loc[-1], int):
        name += f"[{loc[-1]}]"
    if get_origin(tp) is Literal:
        return "one of " + ", ".join(show(a) for a in get_args(tp))
    if get_origin(tp) in (Union, types.UnionType):
        return None
    if tp not in (float, int):
        return None
    low, low_in, high, high_in = _bounds(meta)
    lo = "" if low is None else f"{num(low)} {'≤' if low_in else '<'} "
    hi = "" if high is None else f" {'≤' if high_in else '<'} {num(high)}"
    kind = "integer" if tp is int else "finite number"
    if not lo and not hi:
        return f"any {kind}"
    return f"{kind} {lo}{name}{hi}"


def validation_message(exc: ValidationError, source: str, root: type[BaseModel]) -> str:
    """One line per pydantic error: file, key, value (when it is one) and the allowed range."""
    lines: list[str | tuple[tuple[int | str, ...], object]] = []
    short: dict[tuple[int | str, ...], list[int]] = {}  # a fixed-length array given too few
    for err in exc.errors():
        loc = tuple(err["loc"])
        if err["type"] == "missing" and loc and isinstance(loc[-1], int):
            if loc[:-1] not in short:
                short[loc[:-1]] = []
                lines.append((loc[:-1], err.get("input")))  # said once, where it came first
            short[loc[:-1]].append(loc[-1])
            continue
        key = key_of(loc)
        reason = err["msg"].removeprefix("Value error, ")  # a cross-key rule says it all
        value: object = err.get("input")
        kind = err["type"]
        if kind == "extra_forbidden":
            reason = "unknown key"
        elif kind == "missing":
            reason = "missing key"
        elif kind == "finite_number":
            reason = "must be a finite number"
        elif kind in ("float_type", "int_type") and isinstance(value, bool | str):
            reason += f" (got a {'boolean' if isinstance(value, bool) else 'string'})"
        elif kind in ("model_type", "model_attributes_type", "dict_type"):
            reason = "must be a table ([section], or {key = value, …})"  # words of TOML
        elif kind in ("list_type", "tuple_type"):
            reason = "must be an array ([…])"
        elif kind in ("too_long", "too_short"):
            ctx = err.get("ctx") or {}
            bound = ctx.get("max_length" if kind == "too_long" else "min_length")
            reason = (f"must have {'at most' if kind == 'too_long' else 'at least'} {bound} "
                      f"items, got {ctx.get('actual_length', '?')}")
        rng = None if kind in ("missing", "extra_forbidden") else allowed(root, loc)
        if rng is not None:
            reason += f" (allowed: {rng})"
        if kind == "missing" or isinstance(value, dict):
            lines.append(f"{source}: key '{key}': {reason}")
        else:
            lines.append(f"{source}: key '{key}' = {show(value)}: {reason}")
    out = []
    for line in lines:
        if isinstance(line, tuple):
            parent, given = line
            idx = short[parent]
            out.append(f"{source}: key '{key_of(parent)}' = {show(given)}: must have "
                       f"{max(idx) + 1} items, got {min(idx)}")
        else:
            out.append(line)
    return "\n".join(out)


def key_of(loc: Sequence[int | str]) -> str:
    """Dotted key of a location: ``bus.joints[1].min_deg``; ``(top level)`` when empty."""
    parts: list[str] = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        else:
            parts.append(("." if parts else "") + item)
    return "".join(parts) or "(top level)"


def size_text(n_bytes: float) -> str:
    """Bytes as B/kB/MB/GB/TB/PB/EB (powers of 1000), 3 significant digits."""
    units = ("B", "kB", "MB", "GB", "TB", "PB", "EB")
    k = 0
    while n_bytes >= 1000 and k < len(units) - 1:
        n_bytes /= 1000
        k += 1
    return f"{n_bytes:.3g} {units[k]}"


# ---------------------------------------------------------------- cross-field physics


def grid_problems(prof: Profile) -> list[Problem]:
    """θ range ordered, whole number of steps, and a grid that fits in memory."""
    ws = prof.workspace
    return grid_step_problems(ws.theta_min_deg, ws.theta_max_deg, ws.step_deg)


def grid_step_problems(lo: float, hi: float, step: float) -> list[Problem]:
    """:func:`grid_problems` of the θ range ``lo``..``hi`` in steps of ``step`` (deg > 0)."""
    if hi <= lo:
        return [Problem("workspace.theta_max_deg", hi,
                        f"must be greater than workspace.theta_min_deg = {num(lo)} "
                        f"(allowed: {num(lo)} < theta_max_deg ≤ {num(ANGLE_LIMIT_DEG)})")]
    steps = (hi - lo) / step  # inf for a subnormal step
    max_axis = math.floor(MAX_GRID_NODES ** (1 / 3) + 1e-9)
    if not (steps < 1e6 and round(steps) + 1 <= max_axis):
        if steps < 1e6:
            per_axis = round(steps) + 1
            count = f"{per_axis}³ = {per_axis**3:,} nodes"
            need = size_text(per_axis**3 * BYTES_PER_NODE)
        else:
            count, need = f"{steps + 1:.3g} values per axis, more than 10^18 nodes", "more than 700 EB"
        return [Problem(
            "workspace.step_deg", step,
            f"the grid {num(lo)}..{num(hi)}° in steps of {num(step)}° has {count}; building it "
            f"would need ≈ {need} of memory (≈ {BYTES_PER_NODE} B per node) (allowed: at most "
            f"{MAX_GRID_NODES:,} nodes ≈ {size_text(MAX_GRID_NODES * BYTES_PER_NODE)}, i.e. "
            f"step_deg ≥ {(hi - lo) / (max_axis - 1):.4g}° for this range, or a narrower range)")]
    if abs(steps - round(steps)) > 1e-9:
        return [Problem(
            "workspace.step_deg", step,
            f"the θ range {num(lo)}..{num(hi)}° ({num(hi - lo)}°) is not a whole number of steps "
            f"(allowed: a step that divides {num(hi - lo)}°, at most 30°)")]
    return []


def watchdog_written_ms(ms: int) -> int:
    """The watchdog the bus writes for ``ms`` > 0: whole 20 ms units, 1..127 (``DynamixelBus.set_watchdog``)."""
    return WATCHDOG_UNIT_MS * min(WATCHDOG_MAX_UNITS, max(1, round(ms / WATCHDOG_UNIT_MS)))


def servo_problems(prof: Profile) -> list[Problem]:
    """p·Ts inside [PTS_MIN, PTS_MAX]; Bus Watchdog ≥ 2·Ts; tracking error ≥ 2 encoder ticks."""
    out = []
    p, ts = prof.servo.p, prof.servo.ts_s
    if not PTS_MIN <= p * ts <= PTS_MAX:
        out.append(Problem(
            "servo.p", p,
            f"p·Ts = {num(p)}·{num(ts)} = {p * ts:.4g} is outside [{num(PTS_MIN)}, {num(PTS_MAX)}]: "
            f"below, the servo needs more than {10 / PTS_MIN:,.0f} samples to settle; above, it "
            f"settles within one sample and the model has no dynamics left "
            f"(allowed: {PTS_MIN / ts:.4g} ≤ p ≤ {min(PTS_MAX / ts, 1000.0):.4g} rad/s "
            f"for servo.ts_s = {num(ts)} s)"))
    ms = prof.safety.watchdog_ms
    need_ms = 2000.0 * ts
    if ms > 0 and watchdog_written_ms(ms) < need_ms - 1e-9:
        least = next((m for m in range(1, WATCHDOG_MAX_UNITS * WATCHDOG_UNIT_MS + 1)
                      if watchdog_written_ms(m) >= need_ms - 1e-9), None)
        out.append(Problem(
            "safety.watchdog_ms", ms,
            f"the Bus Watchdog written ({watchdog_written_ms(ms)} ms, in {WATCHDOG_UNIT_MS} ms units) "
            f"is shorter than 2 sampling intervals (2·servo.ts_s = {num(need_ms)} ms): the servos "
            f"would stop between two cycles (allowed: 0 = off, or {least} ≤ watchdog_ms ≤ "
            f"{WATCHDOG_MAX_UNITS * WATCHDOG_UNIT_MS})"))
    out.extend(_watchdog_off_problems(prof))
    tick = 360.0 / prof.bus.ticks_per_turn
    err = prof.safety.tracking_error_deg
    if err < 2 * tick:
        out.append(Problem(
            "safety.tracking_error_deg", err,
            f"is below 2 encoder ticks (2 × 360/{prof.bus.ticks_per_turn} = {2 * tick:.4g}°): "
            f"quantization alone would stop every run (allowed: {2 * tick:.4g} ≤ "
            "tracking_error_deg ≤ 30)"))
    return out


def _watchdog_off_problems(prof: Profile) -> list[Problem]:
    """The Bus Watchdog off only with an explicit reason (logged with every run)."""
    ms, why = prof.safety.watchdog_ms, prof.safety.watchdog_off_reason
    if why and (" ".join(why.split()) != why or not why.isprintable()):
        return [Problem("safety.watchdog_off_reason", why,
                        "one printable line without leading, trailing or repeated spaces")]
    if prof.bus.protocol == "2.0" and ms == 0 and not why:
        return [Problem(
            "safety.watchdog_ms", ms,
            "switches the Bus Watchdog off: it is what stops the servos if the motion process "
            "dies. Keep it on (allowed: 2·servo.ts_s ≤ watchdog_ms ≤ 2540), or say why in "
            "safety.watchdog_off_reason (written to every run's log)")]
    if why and ms > 0:
        return [Problem("safety.watchdog_off_reason", why,
                        f"is set, but the Bus Watchdog is on (watchdog_ms = {ms}): remove it")]
    return []


def link_problems(prof: Profile) -> list[Problem]:
    """δ smaller than the radius of every point of the segments taking part."""
    lk = prof.links
    names = sorted({r for s in lk.segments for r in SEGMENT_RADII[s]})
    radius = {n: float(getattr(lk, n)) for n in names}
    smallest = min(radius, key=lambda n: radius[n])
    if lk.delta_mm < radius[smallest]:
        return []
    return [Problem(
        "links.delta_mm", lk.delta_mm,
        f"the capsule radius must be smaller than every link radius of the checked segments "
        f"{', '.join(lk.segments)} (smallest: links.{smallest} = {num(radius[smallest])} mm) "
        f"(allowed: 0 < delta_mm < {num(radius[smallest])})")]


#: Longest port name accepted, characters (a device path, or ``unix:`` and a socket path,
#: which Linux bounds at 107 bytes).
MAX_PORT_CHARS = 120


def port_problem(text: str, what: str) -> str:
    """Why ``text`` is no port name ("" when it is one)."""
    if not text.strip():
        return f"{what}: empty; type its port (e.g. /dev/ttyUSB0)"
    if len(text) > MAX_PORT_CHARS:
        return f"{what}: {len(text)} characters; at most {MAX_PORT_CHARS}"
    if text != text.strip() or any(c.isspace() or not c.isprintable() for c in text):
        return f"{what}: no spaces or control characters in a port name"
    return ""


def wiring_problems(prof: Profile) -> list[Problem]:
    """The port a name (or empty: the emulated bus); limits ordered; tick offset inside one
    turn; the limits map onto 0..ticks_per_turn−1; home inside the limits."""
    out = []
    port = prof.bus.port
    why = ("blank" if not port.strip() else port_problem(port, "a port name")) if port else ""
    if why:
        out.append(Problem("bus.port", port,
                           f"{why} (allowed: empty for the emulated bus, or a device path such "
                           "as /dev/ttyUSB0)"))
    tpt = prof.bus.ticks_per_turn
    for i, j in enumerate(prof.bus.joints):
        key = f"bus.joints[{i}]"
        if j.max_deg <= j.min_deg:
            out.append(Problem(f"{key}.max_deg", j.max_deg,
                               f"must be greater than {key}.min_deg = {num(j.min_deg)} "
                               f"(allowed: {num(j.min_deg)} < max_deg ≤ {num(ANGLE_LIMIT_DEG)})"))
            continue
        if j.tick_offset >= tpt:
            out.append(Problem(f"{key}.tick_offset", j.tick_offset,
                               f"must be below bus.ticks_per_turn = {tpt} "
                               f"(allowed: 0 ≤ tick_offset ≤ {tpt - 1})"))
            continue
        per_deg = tpt / 360.0
        zero = j.tick_offset + j.tick_trim
        # θ range whose ticks tick_offset + tick_trim + direction·θ·per_deg lie in [0, tpt − 1]
        a, b = -zero / per_deg, (tpt - 1 - zero) / per_deg
        lo_ok, hi_ok = (a, b) if j.direction == 1 else (-b, -a)
        for name, value in (("min_deg", j.min_deg), ("max_deg", j.max_deg)):
            ticks = zero + j.direction * value * per_deg
            if not 0 <= ticks <= tpt - 1:
                out.append(Problem(
                    f"{key}.{name}", value,
                    f"maps to tick {ticks:.1f}, outside the servo's 0..{tpt - 1} (ticks = tick_offset "
                    f"+ direction·θ·ticks_per_turn/360 = {num(zero)} {'+' if j.direction > 0 else '−'} "
                    f"θ·{per_deg:.5g}) (allowed: {lo_ok:.2f} ≤ {name} ≤ {hi_ok:.2f} for this wiring)"))
        h = prof.home.theta_deg[i]
        if not j.min_deg <= h <= j.max_deg:
            out.append(Problem(
                key, h,
                f"home θ{i + 1} = {num(h)}° is outside the servo limits [{num(j.min_deg)}, "
                f"{num(j.max_deg)}]° (allowed: min_deg ≤ home.theta_deg[{i}] ≤ max_deg)"))
    return out


def use_problems(prof: Profile) -> list[Problem]:
    """Values each valid alone that no run could use: every homing, or every plan, would be
    refused."""
    out = []
    home_v, vmax = prof.safety.home_speed_degps, prof.limits.vmax_degps
    if vmax > MX106_NO_LOAD_SPEED_DEGPS:
        out.append(Problem(
            "limits.vmax_degps", vmax,
            f"is above the MX-106's rated no-load speed {num(MX106_NO_LOAD_SPEED_DEGPS)} deg/s: "
            f"every plan would be refused (allowed: 0 < vmax_degps ≤ "
            f"{num(MX106_NO_LOAD_SPEED_DEGPS)})"))
    if home_v > vmax:
        out.append(Problem(
            "safety.home_speed_degps", home_v,
            f"is above the planning limit limits.vmax_degps = {num(vmax)} deg/s: every homing "
            "move would be refused by the runtime's plan verification (allowed: "
            f"0.5 ≤ home_speed_degps ≤ {num(vmax)})"))
    return out


def physics_problems(prof: Profile) -> list[Problem]:
    """Every cross-field problem of a profile that passed the per-field validation."""
    return [*grid_problems(prof), *servo_problems(prof), *link_problems(prof), *wiring_problems(prof),
            *use_problems(prof)]


def check_physics(prof: Profile, source: str) -> None:
    """ProfileError listing every cross-field problem (cheap: no kinematics)."""
    problems = physics_problems(prof)
    if problems:
        raise ProfileError("\n".join(p.line(source) for p in problems))


# ---------------------------------------------------------------- home assembly mode
