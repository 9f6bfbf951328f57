"""A design sweep's specification (``design sweep SPEC.toml``): which geometry parameters
vary and over what, the base profile for everything fixed, and the bounds that are checked
before anything starts.

Example (angles in deg, lengths in mm)::

    [sweep]
    base_profile = "../profiles/agile_wrist.toml"   # relative to this file
    sampling = "grid"          # every combination of the counts; or "lhs" (Latin hypercube)
    samples = 64               # lhs only: number of designs
    seed = 1                   # lhs only
    step_deg = 5.0             # the workspace grid's Δ for every design (default: the base's)

    [parameters.alpha1_deg]
    min = 70.0
    max = 100.0
    count = 4                  # grid only

    [[pairs]]                  # optional: can each design plan these moves (minimum time)?
    start_deg = [100.0, 100.0, 100.0]
    goal_deg = [130.0, 120.0, 110.0]

A parameter is a key of the profile's ``[geometry]`` (α1, α2, β, γ) or ``[links]`` (the
segment radii and δ); its range must lie inside that key's documented bounds.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from spm_console import __version__
from spm_console.config.checks import field_bounds, validation_message
from spm_console.config.load import parse_profile_text, with_grid_step
from spm_console.config.schema import Count, Profile, Real
from spm_console.core.workspace_build import FORMAT_VERSION
from spm_console.errors import BadInputError, ProfileError
from spm_console.safe_io import MB, FileRefusedError, read_capped

#: Largest spec file read.
MAX_SPEC_BYTES = MB // 4
#: Default and largest cap on the designs of one sweep (``--max-designs``).
DEFAULT_MAX_DESIGNS = 100_000
HARD_MAX_DESIGNS = 1_000_000
#: Default cap on one design's workspace grid nodes (``[sweep] max_nodes``); a profile's own
#: cap (2,000,000) is the largest allowed.
DEFAULT_MAX_NODES = 200_000
HARD_MAX_NODES = 2_000_000
#: Most start/goal pairs planned per design.
MAX_PAIRS = 16

#: The parameters a sweep may vary: name -> its profile section.
PARAMETERS: dict[str, str] = {
    **dict.fromkeys(("alpha1_deg", "alpha2_deg", "beta_deg", "gamma_deg"), "geometry"),
    **dict.fromkeys(("oa_mm", "ob_mm", "oc_mm", "od_mm", "oe_mm", "of_mm", "delta_mm"), "links"),
}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Range(_Strict):
    """One parameter's range."""

    min: Real
    max: Real
    count: Count = Field(default=1, ge=1, le=1000)
    """Values on the grid, evenly spaced from min to max (grid sampling only)."""


class SweepSection(_Strict):
    base_profile: str = Field(min_length=1, max_length=4096)
    sampling: Literal["grid", "lhs"] = "grid"
    samples: Count = Field(default=0, ge=0, le=HARD_MAX_DESIGNS)
    seed: Count = Field(default=0, ge=0, le=2**32 - 1)
    step_deg: Real | None = Field(default=None, gt=0.0, le=30.0)
    max_nodes: Count = Field(default=DEFAULT_MAX_NODES, ge=8, le=HARD_MAX_NODES)


class Pair(_Strict):
    start_deg: tuple[Real, Real, Real]
    goal_deg: tuple[Real, Real, Real]


class SpecFile(_Strict):
    sweep: SweepSection
    parameters: dict[str, Range] = Field(min_length=1, max_length=len(PARAMETERS))
    pairs: list[Pair] = Field(default_factory=list, max_length=MAX_PAIRS)


@dataclass(frozen=True)
class SweepSpec:
    """A checked sweep: its designs' parameter values and what every design shares."""

    source: str
    """The spec file's path."""
    base: Profile
    """The base profile, with the sweep's grid step."""
    base_text: str
    """The base profile's TOML text (the designs' profiles are edits of it)."""
    names: tuple[str, ...]
    """The varied parameters, in the spec's order."""
    values: np.ndarray
    """(designs, parameters) values, the parameters' units."""
    pairs: tuple[Pair, ...]
    sampling: str
    digest: str
    """SHA-256 of the spec's content, the base profile's text and the code's version: a sweep
    folder holds one."""

    @property
    def count(self) -> int:
        return int(self.values.shape[0])

    def params(self, index: int) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.values[index], strict=True)}


def _bounds(name: str) -> tuple[float, bool, float, bool]:
    """(low, low inclusive, high, high inclusive) of a parameter's profile field."""
    return field_bounds(Profile, (PARAMETERS[name], name))


def _check_range(name: str, r: Range, source: str) -> None:
    key = f"parameters.{name}"
    if name not in PARAMETERS:
        raise BadInputError(f"{source}: {key}: not a sweep parameter (allowed: "
                            f"{', '.join(PARAMETERS)})")
    if r.min > r.max:
        raise BadInputError(f"{source}: {key}: min {r.min:g} is above max {r.max:g}")
    lo, lo_in, hi, hi_in = _bounds(name)
    for end, v in (("min", r.min), ("max", r.max)):
        if v < lo or (v == lo and not lo_in) or v > hi or (v == hi and not hi_in):
            raise BadInputError(
                f"{source}: {key}.{end} = {v:g} is outside the profile's bounds for "
                f"{PARAMETERS[name]}.{name}: {'[' if lo_in else '('}{lo:g}, {hi:g}"
                f"{']' if hi_in else ')'}")


def _values(spec: SpecFile, names: list[str], source: str, max_designs: int) -> np.ndarray:
    ranges = [spec.parameters[n] for n in names]
    if spec.sweep.sampling == "grid":
        if spec.sweep.samples:
            raise BadInputError(f"{source}: sweep.samples: only for sampling = \"lhs\" (a grid "
                                "has the product of the parameters' counts)")
        count = math.prod(r.count for r in ranges)
        if count > max_designs:
            raise BadInputError(f"{source}: parameters: the grid has {count} designs, more than "
                                f"the {max_designs} allowed (--max-designs)")
        axes = [np.linspace(r.min, r.max, r.count) for r in ranges]
        return np.array(list(itertools.product(*axes)), float).reshape(-1, len(names))
    for n, r in zip(names, ranges, strict=True):
        if r.count != 1:
            raise BadInputError(f"{source}: parameters.{n}.count: only for sampling = \"grid\" "
                                "(lhs draws sweep.samples designs)")
    if spec.sweep.samples < 1:
        raise BadInputError(f"{source}: sweep.samples: lhs sampling needs samples ≥ 1")
    if spec.sweep.samples > max_designs:
        raise BadInputError(f"{source}: sweep.samples = {spec.sweep.samples} designs, more than "
                            f"the {max_designs} allowed (--max-designs)")
    from scipy.stats import qmc

    u = qmc.LatinHypercube(d=len(names), seed=np.random.default_rng(spec.sweep.seed)).random(
        spec.sweep.samples)
    lo = np.array([r.min for r in ranges])
    hi = np.array([r.max for r in ranges])
    return np.asarray(lo + u * (hi - lo), float)


def _base(spec: SpecFile, path: Path) -> tuple[Profile, str]:
    bp = Path(spec.sweep.base_profile)
    if not bp.is_absolute():
        bp = path.parent / bp
    try:
        text = read_capped(bp, MAX_SPEC_BYTES).decode("utf-8")
    except (FileRefusedError, UnicodeDecodeError) as exc:
        reason = exc.reason if isinstance(exc, FileRefusedError) else "not UTF-8 text"
        raise BadInputError(f"{path}: sweep.base_profile: {bp}: {reason}") from None
    try:
        prof = parse_profile_text(text, str(bp))
    except ProfileError as exc:
        raise ProfileError(f"{path}: sweep.base_profile: {exc.message}") from None
    if spec.sweep.step_deg is not None:
        try:
            prof = with_grid_step(prof, spec.sweep.step_deg, "step")
        except ProfileError as exc:
            why = exc.message.split(":", 1)[-1].strip()
            raise BadInputError(f"{path}: sweep.step_deg = {spec.sweep.step_deg:g}: {why}") from None
    return prof, text


def load_spec(path: str | Path, max_designs: int = DEFAULT_MAX_DESIGNS) -> SweepSpec:
    """Read and check a sweep spec: every refusal (BadInputError, ProfileError) names the key,
    before any design is computed."""
    p = Path(path)
    if not 1 <= max_designs <= HARD_MAX_DESIGNS:
        raise BadInputError(f"--max-designs must be within 1..{HARD_MAX_DESIGNS}, got {max_designs}")
    try:
        raw = read_capped(p, MAX_SPEC_BYTES).decode("utf-8")
        data: dict[str, Any] = tomllib.loads(raw)
    except FileRefusedError as exc:
        raise BadInputError(f"{p}: cannot read the sweep spec: {exc.reason}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError) as exc:
        raise BadInputError(f"{p}: not a valid TOML sweep spec: {exc}") from None
    try:
        spec = SpecFile.model_validate(data)
    except ValidationError as exc:
        raise BadInputError(validation_message(exc, str(p), SpecFile)) from None
    names = list(spec.parameters)
    for n in names:
        _check_range(n, spec.parameters[n], str(p))
    base, text = _base(spec, p)
    w = base.workspace
    nodes = (round((w.theta_max_deg - w.theta_min_deg) / w.step_deg) + 1) ** 3
    if nodes > spec.sweep.max_nodes:
        raise BadInputError(f"{p}: sweep.step_deg: Δ = {w.step_deg:g}° gives {nodes} grid nodes "
                            f"per design, more than sweep.max_nodes = {spec.sweep.max_nodes}")
    lo, hi = w.theta_min_deg, w.theta_max_deg
    for k, pair in enumerate(spec.pairs):
        for end in ("start_deg", "goal_deg"):
            th = getattr(pair, end)
            if not all(lo <= x <= hi for x in th):
                raise BadInputError(f"{p}: pairs[{k}].{end} = {list(th)} is outside the "
                                    f"workspace grid's {lo:g}..{hi:g}°")
    values = _values(spec, names, str(p), max_designs)
    # the code's version too: rows of another release are not mixed into a resumed sweep
    content = json.dumps({"spec": spec.model_dump(mode="json"), "base": text,
                          "version": __version__, "workspace_format": FORMAT_VERSION},
                         sort_keys=True)
    return SweepSpec(source=str(p), base=base, base_text=text, names=tuple(names), values=values,
                     pairs=tuple(spec.pairs), sampling=spec.sweep.sampling,
                     digest=hashlib.sha256(content.encode()).hexdigest())
