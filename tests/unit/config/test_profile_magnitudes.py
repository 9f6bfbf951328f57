"""No key of a profile holds a number too small to mean anything: a subnormal float anywhere,
or a physical figure of the emulated wrist far below any real one, is refused at load (exit 3,
naming the key). ``plant.link_mass_kg = 1e-320`` used to end in a MuJoCo error (exit 10) and
``plant.armature_kgm2 = 1e-320`` in an emulated wrist that read 179.7° before any command."""

from __future__ import annotations

import sys
from typing import Any

import pytest

from spm_console.config.checks import field_bounds, key_of
from spm_console.config.load import parse_profile
from spm_console.config.plant import PLANT_STEP_S, STALL_DAMPING_NMS
from spm_console.config.schema import Profile
from spm_console.errors import ExitCode, ProfileError
from tests.support.ws_helpers import agile_profile

SUBNORMAL = sys.float_info.min / 2**20  # about 2e-314: nonzero, below the smallest normal float


def full_doc() -> dict[str, Any]:
    """The Agile Wrist with every section and every optional number of [servo] given."""
    doc: dict[str, Any] = agile_profile().model_dump(mode="json")
    doc["servo"].update(linear_range_deg=5.0, residual_bound_deg=0.5, load_deg_per_nm=1.0,
                        coulomb_deg=0.1)
    return doc


def _float_paths(node: object, path: tuple[str | int, ...] = ()) -> list[tuple[str | int, ...]]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _float_paths(v, (*path, k))]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _float_paths(v, (*path, i))]
    return [path] if isinstance(node, float) else []


FLOAT_KEYS = _float_paths(full_doc())


def refusal(doc: dict[str, Any]) -> ProfileError | None:
    try:
        parse_profile(doc, "p.toml")
    except ProfileError as exc:
        return exc
    return None


def _set(doc: dict[str, Any], path: tuple[str | int, ...], value: float) -> dict[str, Any]:
    node: Any = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return doc


def test_the_full_document_loads_and_the_walk_sees_every_section() -> None:
    assert refusal(full_doc()) is None
    assert {p[0] for p in FLOAT_KEYS} >= {"geometry", "home", "links", "workspace", "servo",
                                          "limits", "bus", "safety", "estimation", "emulator",
                                          "plant", "settle"}


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("path", FLOAT_KEYS, ids=key_of)
def test_a_subnormal_number_is_refused_in_every_key(path: tuple[str | int, ...],
                                                    sign: float) -> None:
    bad = refusal(_set(full_doc(), path, sign * SUBNORMAL))
    assert bad is not None and bad.exit_code == ExitCode.PROFILE_ERROR
    assert f"key '{key_of(path)}' = " in bad.message, bad.message
    low = field_bounds(Profile, path)[0]
    if sign * SUBNORMAL > low:  # inside the declared range: refused for being subnormal
        assert "subnormal" in bad.message, bad.message


@pytest.mark.parametrize("path", [("settle", "duration_s"), ("plant", "coulomb_nm"),
                                  ("geometry", "gamma_deg"), ("emulator", "noise_deg")],
                         ids=key_of)
def test_zero_is_still_a_number(path: tuple[str | int, ...]) -> None:
    assert refusal(_set(full_doc(), path, 0.0)) is None


@pytest.mark.parametrize(("key", "value"), [
    ("link_mass_kg", 1e-300), ("link_mass_kg", 1e-9), ("platform_mass_kg", 1e-12),
    ("armature_kgm2", 1e-4), ("link_radius_mm", 1e-3), ("supply_v", 1e-3),
    ("kt_nm_per_a", 1e-6), ("resistance_ohm", 1e-6),
])
def test_a_physical_figure_far_below_any_real_one_is_refused(key: str, value: float) -> None:
    """A link of a nanogram made the emulated wrist unstable; below 1e-12 kg MuJoCo refuses
    the model (exit 10 once the bus opened); an armature of 1e-4 kg·m² is unstable at the
    emulator's step."""
    doc = full_doc()
    doc["plant"][key] = value
    bad = refusal(doc)
    assert bad is not None and f"key 'plant.{key}' = " in bad.message, bad
    assert "greater than or equal to" in bad.message and "(allowed: finite number" in bad.message


def test_a_bus_reply_timeout_of_a_femtosecond_is_refused() -> None:
    doc = full_doc()
    doc["bus"]["timeout_s"] = 1e-15  # every read would time out: exit 10 at connect
    bad = refusal(doc)
    assert bad is not None and "key 'bus.timeout_s' = 1e-15" in bad.message, bad


def test_the_armature_must_outlast_the_drives_back_emf_damping_at_the_emulators_step() -> None:
    """kt²/R acts on the rotor once a step (explicitly): a strong motor on the MX-106's
    armature would make the emulated wrist ring up, so the armature's bound follows kt²/R."""
    doc = full_doc()
    doc["plant"].update(kt_nm_per_a=20.0, resistance_ohm=0.5)  # kt²/R = 800 N·m·s/rad
    bad = refusal(doc)
    least = PLANT_STEP_S * (20.0**2 / 0.5 + STALL_DAMPING_NMS)
    assert bad is not None and "plant.armature_kgm2" in bad.message, bad
    assert f"allowed: armature_kgm2 ≥ {least:.3g}" in bad.message and "Value error" not in bad.message
    doc["plant"]["armature_kgm2"] = least
    assert refusal(doc) is None
