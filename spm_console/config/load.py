"""Loading a profile file: bounded reading, validation (:func:`~spm_console.config.schema.parse_profile`)
and the checks that need the kinematics: the home pose in its assembly mode, feasible, with a
feasible grid node one step around it every way (room for the region P).

Above :mod:`spm_console.config.models` (the adapter to the core's models), which is above the
profile's schema (:mod:`spm_console.config.schema`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from spm_console.config.checks import Problem, check_physics, num, show, validation_message
from spm_console.config.models import geometry_of, link_model_of, model_of
from spm_console.config.schema import DEFAULT_PROFILE, Profile
from spm_console.core.kinematics.assess import assess
from spm_console.errors import ProfileError
from spm_console.safe_io import MB, FileRefusedError, parse_toml, read_capped

#: A component of v at home this close to 0 matches any seed sign.
SIGN_ZERO_TOL = 1e-6


def parse_profile(data: dict[str, object], source: str) -> Profile:
    """Validate a decoded TOML document: types, per-field ranges, then the cross-field physics
    (:func:`~spm_console.config.checks.check_physics`). Errors name ``source``, the key, the
    value and the allowed range."""
    try:
        prof = Profile.model_validate(data)
    except ValidationError as exc:
        raise ProfileError(validation_message(exc, source, Profile)) from None
    check_physics(prof, source)
    return prof


#: Largest profile file read (the shipped ones are under 5 kB).
MAX_PROFILE_BYTES = MB // 4


def load_profile(path: str | Path = DEFAULT_PROFILE) -> Profile:
    """Read and validate a profile file, including its home assembly mode
    (:func:`~spm_console.config.checks.check_home_mode`)."""
    p = Path(path)
    try:
        raw = read_capped(p, MAX_PROFILE_BYTES)
    except FileRefusedError as exc:
        reason = exc.reason.removeprefix("cannot read: ")
        raise ProfileError(f"{p}: cannot read profile: {reason}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProfileError(f"{p}: not valid TOML: {exc}") from None
    return parse_profile_text(text, str(p))


def parse_profile_text(text: str, source: str) -> Profile:
    """A profile's TOML text, validated as :func:`load_profile` validates a file."""
    data = parse_toml(text, source, ProfileError, "not a profile: values nested too deeply")
    prof = parse_profile(data, source)
    check_home_mode(prof, source)
    return prof


def with_grid_step(profile: Profile, step_deg: float, source: str = "--grid-step") -> Profile:
    """``profile`` with another workspace grid step Δ (deg), validated as a profile file would
    be (the range must hold a whole number of steps; the node cap applies). Everything built
    from it — the workspace cache, the certified set the runtime verifies plans against, plan
    hashes — is that grid's."""
    data = profile.model_dump(mode="json")
    data["workspace"] = {**data["workspace"], "step_deg": float(step_deg)}
    prof = parse_profile(data, source)
    check_home_mode(prof, source)  # room for a region around home on this grid
    return prof


def home_signs(v_home: Sequence[Sequence[float]]) -> list[int]:
    """Signs of [v1x v1y v1z v2x … v3z] at home, 0 where |v| ≤ SIGN_ZERO_TOL."""
    return [0 if abs(x) <= SIGN_ZERO_TOL else (1 if x > 0 else -1) for row in v_home for x in row]


def seed_mismatches(seed: Sequence[int], v_home: Sequence[Sequence[float]]) -> list[int]:
    """Indices where the seed disagrees with v at home (a v ≈ 0 matches any seed entry)."""
    signs = home_signs(v_home)
    return [k for k, (s, h) in enumerate(zip(seed, signs, strict=True)) if h != 0 and s != h]


#: Wrists whose home passed :func:`check_home_mode` in this process (its inputs: geometry, home,
#: links, grid), so loading one profile again does not solve its kinematics again.
_HOME_CHECKED: set[tuple[object, ...]] = set()
_HOME_CHECKED_MAX = 256


def check_home_mode(prof: Profile, source: str) -> None:
    """The home pose exists and is not singular, its signs are those of ``home.sign_seed``, and
    it is feasible (ζ ≥ ζ_min, links apart, inside the grid range: the workspace grows from it).
    A wrist that passed once in this process passes again without solving (a failure is
    checked, and worded, every time)."""
    ws = prof.workspace
    key = (geometry_of(prof), tuple(prof.home.theta_deg), tuple(prof.home.sign_seed),
           link_model_of(prof), ws.step_deg, ws.zeta_min, ws.theta_min_deg, ws.theta_max_deg)
    if key in _HOME_CHECKED:
        return
    _check_home_mode(prof, source)
    if len(_HOME_CHECKED) >= _HOME_CHECKED_MAX:
        _HOME_CHECKED.clear()
    _HOME_CHECKED.add(key)


def _check_home_mode(prof: Profile, source: str) -> None:
    theta = list(prof.home.theta_deg)
    allowed_home = "(allowed: a home θ with a non-singular forward-kinematic solution)"
    try:
        with np.errstate(all="ignore"):  # degenerate geometries overflow inside the solver
            model = model_of(prof)
    except ValueError as exc:  # home_model: no FK solution or a singular home; LinAlgError too
        what = (f"the forward kinematics at home cannot be solved for this geometry ({exc})"
                if isinstance(exc, np.linalg.LinAlgError) else f"{exc} for this geometry")
        raise ProfileError(Problem("home.theta_deg", theta, f"{what} {allowed_home}").line(source)) from None
    if not (np.isfinite(model.v_home).all() and np.isfinite(model.working_signs).all()
            and np.isfinite(model.det_j1_sign)):
        raise ProfileError(Problem(
            "home.theta_deg", theta,
            f"the forward kinematics at home gives no finite pose for this geometry {allowed_home}"
        ).line(source))
    rows = [[float(x) for x in r] for r in model.v_home]
    bad = seed_mismatches(prof.home.sign_seed, rows)
    if bad:
        comp = [f"v{k // 3 + 1}{'xyz'[k % 3]}" for k in bad]
        shown = "[" + ", ".join(f"{x:.4f}" for r in rows for x in r) + "]"
        raise ProfileError(Problem(
            "home.sign_seed", list(prof.home.sign_seed),
            f"is not the home assembly mode: at home θ = {show(theta)}° the closest solution has "
            f"signs {show(home_signs(rows))} (v = {shown}); {', '.join(comp)} "
            f"{'differs' if len(comp) == 1 else 'differ'} "
            "(allowed: the home signs; a 0 there matches any seed entry)").line(source))
    ws = prof.workspace
    home = assess(model, link_model_of(prof), model.pose(model.theta_home, np.eye(3)), ws.zeta_min,
                  (ws.theta_min_deg, ws.theta_max_deg))
    if not home.feasible:
        raise ProfileError(Problem(
            "home.theta_deg", theta,
            f"the home configuration is not feasible ({home.reason}): the workspace grows from home "
            "(allowed: a home with ζ ≥ workspace.zeta_min, links of different legs at least "
            "2·links.delta_mm apart, inside [workspace.theta_min_deg, workspace.theta_max_deg]; "
            f"home.sign_seed = {show(list(prof.home.sign_seed))} chooses the assembly mode "
            "there: another mode's links may collide where the wrist's do not)"
        ).line(source))
    _check_room_at_home(prof, source, model)


def _check_room_at_home(prof: Profile, source: str, model: Any) -> None:
    """One grid step around home every way is feasible: the region P grows from home over
    the grid's nodes, and with less room it has no interior (a 30° step or ζ_min = 0.999
    used to fail only when the workspace was built, as a degenerate ellipsoid)."""

    import numpy as np


    ws = prof.workspace
    home = np.asarray(prof.home.theta_deg, float)
    cube = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
    nodes = home + ws.step_deg * cube
    links = link_model_of(prof)
    with np.errstate(all="ignore"):
        results = model.track_batch(np.radians(nodes))
    clear = _clear_nodes(model, links, results, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg))
    for th, r, sure in zip(nodes, results, clear, strict=True):
        if sure:
            continue
        shown = show([float(x) for x in th])
        if r.ok and r.pose is not None:
            a = assess(model, links, r.pose, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg))
            if a.feasible:
                continue
            why, key = a.reason, ("workspace.zeta_min" if a.zeta < ws.zeta_min else
                                  "workspace.step_deg")
        else:
            why, key = r.reason or "no forward-kinematic solution", "workspace.step_deg"
        value = ws.zeta_min if key == "workspace.zeta_min" else ws.step_deg
        raise ProfileError(Problem(
            key, value,
            f"leaves no room for a region around home: the grid node θ = {shown}° one step "
            f"(workspace.step_deg = {num(ws.step_deg)}°) from home is not feasible ({why}) "
            "(allowed: every node one grid step around home feasible: a smaller step, or a "
            "lower workspace.zeta_min)").line(source))


def _clear_nodes(model: Any, links: Any, results: list[Any], zeta_min: float,
                 theta_range_deg: tuple[float, float]) -> list[bool]:
    """Per tracked node: True when its pose is surely feasible by :func:`assess`'s own tests
    (ζ ≥ ζ_min, every link pair ≥ 2δ, θ in range), all nodes' link distances at once (one
    call each cost as much as all 26 together); False leaves the node to :func:`assess`."""
    import numpy as np

    solved = [k for k, r in enumerate(results) if r.ok and r.pose is not None]
    clear = [False] * len(results)
    if not solved:
        return clear
    poses = [results[k].pose for k in solved]
    theta = np.stack([p.theta for p in poses])
    with np.errstate(all="ignore"):  # a degenerate pose gives NaN: not cleared, assess says why
        dmin = links.pair_distances(model.u, model.geom.w(theta),
                                    np.stack([p.v for p in poses])).min(-1)
    lo, hi = theta_range_deg
    deg = np.degrees(theta)
    for k, p, d, th in zip(solved, poses, dmin, deg, strict=True):
        clear[k] = bool(p.zeta >= zeta_min and float(d) >= 2 * links.delta
                        and np.all(th >= lo - 1e-9) and np.all(th <= hi + 1e-9))
    return clear
