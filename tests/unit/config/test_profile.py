"""Profiles: the shipped ones load; each kind of broken or unphysical file raises ProfileError
(exit 3) naming the file, the key, the value and the allowed range; no mutation of one number
ends in anything else."""

from __future__ import annotations

import math
import os
import tempfile
import tomllib
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st

from spm_console.cli.main import main
from spm_console.config.checks import MAX_GRID_NODES, PTS_MAX, PTS_MIN
from spm_console.config.load import MAX_PROFILE_BYTES, load_profile, parse_profile
from spm_console.errors import ExitCode, ProfileError
from tests.support.paths import TESTS

DATA = TESTS / "data" / "profiles"

def test_shipped_profiles_load(agile, coaxial) -> None:  # type: ignore[no-untyped-def]
    assert agile.name == "agile_wrist"
    assert agile.geometry.beta_deg == pytest.approx(math.degrees(math.acos(1 / math.sqrt(3))), abs=1e-12)
    assert agile.home.theta_deg == (135.0, 135.0, 135.0)
    assert agile.home.sign_seed == (-1, 1, 1, 1, 1, 1, -1, -1, 1)
    assert agile.workspace.axis_deg[0] == 65.0 and agile.workspace.axis_deg[-1] == 155.0
    assert len(agile.workspace.axis_deg) == 46
    assert agile.servo.p == 32.22 and agile.servo.ts_s == 0.02
    assert coaxial.geometry.gamma_deg == 0.0

def test_digest_is_stable_and_sensitive(agile) -> None:  # type: ignore[no-untyped-def]
    again = load_profile("profiles/agile_wrist.toml")
    assert again.digest() == agile.digest()
    changed = agile.model_copy(update={"servo": agile.servo.model_copy(update={"p": 30.0})})
    assert changed.digest() != agile.digest()

@pytest.mark.parametrize(
    ("fixture", "key", "reason"),
    [
        ("bad_toml.toml", None, "not valid TOML"),
        ("missing_key.toml", "servo.p", "missing key"),
        ("wrong_type.toml", "servo.ts_s", "valid number"),
        ("out_of_range.toml", "workspace.zeta_min", "less than 1"),
        ("unknown_key.toml", "servo.gain", "unknown key"),
        ("home_outside_limits.toml", "bus.joints[1]", "outside the servo limits"),
        ("duplicate_ids.toml", "bus", "distinct servo ids"),
    ],
)
def test_broken_profile_names_file_key_reason(fixture: str, key: str | None, reason: str) -> None:
    path = DATA / fixture
    with pytest.raises(ProfileError) as info:
        load_profile(path)
    msg = info.value.message
    assert str(path) in msg
    if key is not None:
        assert f"'{key}'" in msg
    assert reason in msg
    assert info.value.exit_code == ExitCode.PROFILE_ERROR

def test_missing_file() -> None:
    with pytest.raises(ProfileError, match="cannot read profile"):
        load_profile("profiles/does_not_exist.toml")

# ------------------------------------------------------------------ physics, not only types

AGILE = Path("profiles/agile_wrist.toml")

def agile_doc() -> dict[str, Any]:
    """A fresh decoded copy of the shipped Agile Wrist profile."""
    return tomllib.loads(AGILE.read_text())

@pytest.mark.parametrize(
    ("fixture", "key", "value", "reason"),
    [
        ("theta_max_inf.toml", "workspace.theta_max_deg", "inf", "must be a finite number"),
        ("theta_max_720.toml", "workspace.theta_max_deg", "720.0", "-360 ≤ theta_max_deg ≤ 360"),
        ("theta_range_reversed.toml", "workspace.theta_max_deg", "155.0", "155 < theta_max_deg"),
        ("step_not_dividing.toml", "workspace.step_deg", "7.0", "not a whole number of steps"),
        ("grid_too_fine.toml", "workspace.step_deg", "0.01", "9001³ = 729,243,027,001 nodes"),
        ("servo_p_tiny.toml", "servo.p", "1e-12", "0.05 ≤ p ≤ 500 rad/s"),
        ("servo_pts_large.toml", "servo.p", "32.22", "p·Ts = 32.22·1 = 32.22 is outside [0.001, 10]"),
        ("servo_p_nan.toml", "servo.p", "nan", "must be a finite number"),
        ("servo_p_bool.toml", "servo.p", "true", "got a boolean"),
        ("vmax_string.toml", "limits.vmax_degps", '"1.5"', "got a string"),
        ("process_noise_huge.toml", "estimation.process_noise_deg", "1e+300", "1e-06 ≤ process_noise_deg ≤ 10"),
        ("measurement_noise_zero.toml", "estimation.measurement_noise_deg", "0.0", "1e-06 ≤"),
        ("emulator_seed_negative.toml", "emulator.seed", "-1", "0 ≤ seed"),
        ("ticks_per_turn_1.toml", "bus.ticks_per_turn", "1", "256 ≤ ticks_per_turn ≤ 1048576"),
        ("baud_string.toml", "bus.baud", '"1000000"', "valid integer"),
        ("direction_bool.toml", "bus.joints[0].direction", "true", "one of 1, -1"),
        ("joint_limits_reversed.toml", "bus.joints[0].max_deg", "50.0", "60 < max_deg ≤ 360"),
        ("tick_offset_off_encoder.toml", "bus.joints[0].max_deg", "160.0", "outside the servo's 0..4095"),
        ("tracking_error_inf.toml", "safety.tracking_error_deg", "inf", "0 < tracking_error_deg ≤ 30"),
        ("region_margin_inf.toml", "safety.region_margin_deg", "inf", "0 ≤ region_margin_deg ≤ 10"),
        ("comm_failures_huge.toml", "safety.comm_failures", "1000", "1 ≤ comm_failures ≤ 50"),
        ("comm_failures_float.toml", "safety.comm_failures", "3.0", "valid integer"),
        ("watchdog_short.toml", "safety.watchdog_ms", "10", "30 ≤ watchdog_ms ≤ 2540"),
        ("delta_huge.toml", "links.delta_mm", "1000000.0", "0 < delta_mm ≤ 10000"),
        ("delta_inf.toml", "links.delta_mm", "inf", "must be a finite number"),
        ("delta_above_radius.toml", "links.delta_mm", "95.0", "0 < delta_mm < 90"),
        ("eta_nan.toml", "geometry.eta_deg[1]", "nan", "must be a finite number"),
        ("sign_seed_wrong.toml", "home.sign_seed", "[1, 1, 1, 1, 1, 1, -1, -1, 1]",
         "signs [-1, 1, 1, 1, 1, 1, 0, -1, 1]"),
        ("home_no_solution.toml", "home.theta_deg", "[0.0, 0.0, 0.0]", "cannot be solved"),
        ("alpha1_degenerate.toml", "home.theta_deg", "[135.0, 135.0, 135.0]", "no finite pose"),
        ("home_links_collide.toml", "home.theta_deg", "[135.0, 135.0, 135.0]", "links collide"),
        ("home_outside_grid.toml", "home.theta_deg", "[135.0, 135.0, 135.0]", "outside the workspace range"),
    ],
)
def test_unphysical_profile_names_file_key_value_range(
    fixture: str, key: str, value: str, reason: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = DATA / fixture
    with pytest.raises(ProfileError) as info:
        load_profile(path)
    msg = info.value.message
    assert f"{path}: key '{key}' = {value}: " in msg
    assert "allowed: " in msg and reason in msg
    assert info.value.exit_code == ExitCode.PROFILE_ERROR
    # the CLI: exit 3 with the same message, never a traceback
    assert main(["fk", "--theta", "100", "100", "100", "--profile", str(path)]) == ExitCode.PROFILE_ERROR
    err = capsys.readouterr().err
    assert f"key '{key}' = {value}: " in err and "Traceback" not in err

def test_int_for_float_accepted_bool_and_str_refused() -> None:
    doc = agile_doc()
    doc["servo"]["p"] = 32
    prof = parse_profile(doc, "t.toml")
    assert prof.servo.p == 32.0 and isinstance(prof.servo.p, float)
    for bad in (True, "32"):
        doc["servo"]["p"] = bad
        with pytest.raises(ProfileError, match=r"key 'servo\.p'"):
            parse_profile(doc, "t.toml")
    doc = agile_doc()
    doc["home"]["sign_seed"][0] = True
    with pytest.raises(ProfileError, match=r"key 'home\.sign_seed\[0\]' = true"):
        parse_profile(doc, "t.toml")

def test_grid_cap_allows_the_1_degree_grid_and_states_node_count() -> None:
    doc = agile_doc()
    doc["workspace"]["step_deg"] = 1.0  # 91³ = 753,571 nodes (reproduction's fine grid)
    assert len(parse_profile(doc, "t.toml").workspace.axis_deg) == 91
    doc["workspace"].update(theta_min_deg=-62.0, theta_max_deg=62.0)  # 125³ = 1,953,125
    assert MAX_GRID_NODES >= 125**3
    parse_profile(doc, "t.toml")
    doc["workspace"].update(theta_min_deg=-62.5, theta_max_deg=62.5)  # 126³ = 2,000,376
    with pytest.raises(ProfileError) as info:
        parse_profile(doc, "t.toml")
    assert "126³ = 2,000,376 nodes" in info.value.message and "1.4 GB" in info.value.message

@pytest.mark.parametrize("method", ["zoh", "tustin"])
@pytest.mark.parametrize(("p", "ts"), [(1.0, 0.001), (500.0, 0.02), (0.05, 0.02), (10.0, 1.0)])
def test_servo_band_corners_give_a_stable_finite_model(method: Literal["zoh", "tustin"], p: float,
                                                       ts: float) -> None:
    from spm_console.core.servo.model import discretize  # python-control: slow import, only here

    assert PTS_MIN <= p * ts <= PTS_MAX
    doc = agile_doc()
    doc["servo"].update(p=p, ts_s=ts, discretization=method)
    doc["safety"].update(watchdog_ms=0, watchdog_off_reason="Ts outlasts any watchdog")
    prof = parse_profile(doc, "t.toml")
    model = discretize(prof.servo.p, prof.servo.ts_s, method)
    assert np.isfinite(model.A).all() and np.isfinite(model.B).all()
    assert max(abs(np.linalg.eigvals(model.A))) < 1.0
    assert math.ceil(10.0 / (p * ts)) <= 10_000  # settle samples of a homing plan

def test_servo_band_edges_refused() -> None:
    doc = agile_doc()
    doc["safety"].update(watchdog_ms=0, watchdog_off_reason="Ts outlasts any watchdog")
    for p, ts in ((0.04, 0.02), (11.0, 1.0)):
        doc["servo"].update(p=p, ts_s=ts)
        with pytest.raises(ProfileError, match=r"key 'servo\.p' = .*outside \[0\.001, 10\]"):
            parse_profile(doc, "t.toml")

@pytest.mark.parametrize(("ms", "ok"), [(29, False), (30, True), (40, True), (2540, True)])
def test_watchdog_as_written_outlasts_two_periods(ms: int, ok: bool) -> None:
    doc = agile_doc()  # Ts = 20 ms: the written watchdog (20 ms units) must be ≥ 40 ms
    doc["safety"]["watchdog_ms"] = ms
    if ok:
        assert parse_profile(doc, "t.toml").safety.watchdog_ms == ms
    else:
        with pytest.raises(ProfileError, match=r"key 'safety\.watchdog_ms' = 29: .*\(20 ms, in 20 ms units\)"):
            parse_profile(doc, "t.toml")

@pytest.mark.parametrize(("section", "key", "value", "why"), [
    ("safety", "home_speed_degps", 360.0, "every homing move would be refused"),
    ("limits", "vmax_degps", 2000.0, "rated no-load speed 270 deg/s: every plan would be refused"),
    ("servo", "p", 1000.0, "is outside [0.001, 10]"),
    ("workspace", "step_deg", 30.0, "leaves no room for a region around home"),
    ("workspace", "zeta_min", 0.999, "leaves no room for a region around home"),
])
def test_a_profile_no_run_could_use_is_refused_at_load_naming_the_key(
        tmp_path: Path, section: str, key: str, value: float, why: str) -> None:
    """Each value is valid alone, but every homing or plan would be refused, or the workspace
    has no region (these used to fail only later, with exit 26 or 7)."""
    doc = agile_doc()
    doc[section][key] = value
    path = tmp_path / "p.toml"
    path.write_text(tomli_w.dumps(doc))
    with pytest.raises(ProfileError, match=f"key '{section}\\.{key}' = .*") as exc:
        load_profile(path)
    assert why in exc.value.message and exc.value.exit_code == ExitCode.PROFILE_ERROR

def test_the_watchdog_is_off_only_with_a_reason() -> None:
    doc = agile_doc()
    doc["safety"]["watchdog_ms"] = 0
    with pytest.raises(ProfileError, match=r"key 'safety\.watchdog_ms' = 0: switches the Bus "
                                           r"Watchdog off.*safety\.watchdog_off_reason"):
        parse_profile(doc, "t.toml")
    doc["safety"]["watchdog_off_reason"] = "bench test: servos on a stand, no load"
    prof = parse_profile(doc, "t.toml")
    assert prof.safety.watchdog_ms == 0
    doc["safety"]["watchdog_off_reason"] = "two\nlines"
    with pytest.raises(ProfileError, match=r"key 'safety\.watchdog_off_reason'.*one printable line"):
        parse_profile(doc, "t.toml")
    doc["safety"].update(watchdog_ms=100, watchdog_off_reason="left over")
    with pytest.raises(ProfileError, match=r"watchdog_off_reason' = .*the Bus Watchdog is on"):
        parse_profile(doc, "t.toml")

@pytest.mark.parametrize(("port", "why"), [
    ("/dev/ttyUSB0\nrm -rf", "no spaces or control characters"),
    ("/dev/tty\u0000USB0", "no spaces or control characters"),
    (" /dev/ttyUSB0", "no spaces or control characters"),
    ("   ", "blank (allowed: empty for the emulated bus"),
    ("/dev/" + "x" * 5000, "at most 120"),
])
def test_the_bus_port_is_a_port_name_or_empty(port: str, why: str) -> None:
    """A port is printed in messages and logs and opened by name: one printable word (a
    newline split the error over lines that looked like commands)."""
    doc = agile_doc()
    doc["bus"]["port"] = port
    with pytest.raises(ProfileError, match=r"key 'bus\.port'") as exc:
        parse_profile(doc, "t.toml")
    assert why in exc.value.message and "\n" not in exc.value.message.split(": ", 1)[1][:60]
    for ok in ("", "/dev/serial/by-id/usb-FTDI_FT232R-if00-port0", "unix:/tmp/spm-bus-ab/bus"):
        doc["bus"]["port"] = ok
        assert parse_profile(doc, "t.toml").bus.port == ok


@pytest.mark.parametrize("kind", ["fifo", "device", "directory", "huge"])
def test_a_profile_that_is_not_a_small_regular_file_is_refused_at_once(
        tmp_path: Path, kind: str) -> None:
    path = tmp_path / "p.toml"
    if kind == "fifo":
        os.mkfifo(path)  # opening it to read would wait for a writer for ever
    elif kind == "device":
        path = Path("/dev/zero")
    elif kind == "directory":
        path = tmp_path
    else:
        path.write_bytes(b"#" * (MAX_PROFILE_BYTES + 1))
    why = {"fifo": "a FIFO", "device": "a device", "directory": "a directory",
           "huge": "larger than the 256 kB limit"}[kind]
    with pytest.raises(ProfileError, match=f"cannot read profile: {why}") as exc:
        load_profile(path)
    assert exc.value.exit_code == ExitCode.PROFILE_ERROR

@pytest.mark.parametrize("name", ["a" * 65, "a" * 300, "../../etc/x", "x/y", "", "-rf", "tab\there",
                                  "é"])
def test_a_profile_name_that_cannot_be_a_file_name_is_refused(name: str) -> None:
    doc = agile_doc()
    doc["profile"]["name"] = name
    with pytest.raises(ProfileError, match=r"key 'profile\.name'") as exc:
        parse_profile(doc, "t.toml")
    assert exc.value.exit_code == ExitCode.PROFILE_ERROR

def test_tracking_error_must_exceed_two_ticks() -> None:
    doc = agile_doc()
    doc["bus"]["ticks_per_turn"] = 256  # 1.41°/tick
    doc["bus"]["joints"] = [dict(j, tick_offset=0) for j in doc["bus"]["joints"]]
    doc["safety"]["tracking_error_deg"] = 2.0
    with pytest.raises(ProfileError, match=r"key 'safety\.tracking_error_deg' = 2\.0: .*2\.812"):
        parse_profile(doc, "t.toml")

def test_sign_seed_zero_only_where_home_v_is_zero(tmp_path: Path) -> None:
    text = AGILE.read_text()
    seed = "sign_seed = [-1, 1, 1, 1, 1, 1, -1, -1, 1]"
    assert seed in text
    # v3x = 0 at the Agile Wrist's home: any entry matches there
    for entry in ("0", "1"):
        path = tmp_path / f"v3x_{entry}.toml"
        path.write_text(text.replace(seed, f"sign_seed = [-1, 1, 1, 1, 1, 1, {entry}, -1, 1]"))
        assert load_profile(path).home.sign_seed[6] == int(entry)
    path = tmp_path / "v1x_0.toml"  # v1x = −0.707 at home: a 0 there is not its sign
    path.write_text(text.replace(seed, "sign_seed = [0, 1, 1, 1, 1, 1, -1, -1, 1]"))
    with pytest.raises(ProfileError, match=r"key 'home\.sign_seed' = \[0, .*v1x differs"):
        load_profile(path)

def test_home_moved_without_its_seed_is_refused(tmp_path: Path) -> None:
    text = AGILE.read_text().replace("theta_deg = [135.0, 135.0, 135.0]", "theta_deg = [100.0, 100.0, 100.0]")
    path = tmp_path / "moved.toml"
    path.write_text(text)
    with pytest.raises(ProfileError, match=r"key 'home\.sign_seed' = .*v2y differs"):
        load_profile(path)

def _numeric_paths(node: object, path: tuple[str | int, ...] = ()) -> list[tuple[str | int, ...]]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _numeric_paths(v, (*path, k))]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _numeric_paths(v, (*path, i))]
    return [path] if isinstance(node, int | float) and not isinstance(node, bool) else []

NUMERIC_PATHS = _numeric_paths(agile_doc())
ANY_VALUE = (st.floats() | st.integers(-(2**63), 2**63 - 1) | st.booleans() | st.text(max_size=6)
             | st.sampled_from([0, -0.0, 1e-300, 1e300, -1e300, 2**63 - 1, 1.0, 0.5, 359.9]))

@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(where=st.sampled_from(NUMERIC_PATHS), value=ANY_VALUE)
def test_any_single_mutation_loads_or_raises_profile_error(where: tuple[str | int, ...], value: object) -> None:
    doc = agile_doc()
    node: Any = doc
    for k in where[:-1]:
        node = node[k]
    node[where[-1]] = value
    with tempfile.TemporaryDirectory(prefix="spm-prof-") as tmp:
        path = Path(tmp) / "mutated.toml"
        path.write_text(tomli_w.dumps(doc))
        try:
            prof = load_profile(path)
        except ProfileError as exc:
            assert str(path) in exc.message and "key '" in exc.message
            assert exc.exit_code == ExitCode.PROFILE_ERROR
            return
    assert prof.name == "agile_wrist"


@pytest.mark.parametrize(("key", "value", "words"), [
    ("armature_kgm2", -0.026, "greater than or equal to 0.005"),
    ("armature_kgm2", math.nan, "finite"),
    ("link_mass_kg", math.inf, "finite"),
    ("resistance_ohm", 1e300, "less than or equal"),
    ("coulomb_nm", "0.1", "valid number"),
    ("model", "rubber", "'ideal' or 'physical'"),
])
def test_a_bad_plant_is_refused_naming_its_key(key: str, value: object, words: str) -> None:
    """[plant] figures are physics: a negative or NaN inertia, a mass of inf, a string for a
    number or an unknown model is refused at load with exit 3, naming plant.<key>."""
    doc = agile_doc()
    doc["plant"] = {"model": "physical", key: value}
    bad = parse_doc(doc)
    assert bad is not None and f"plant.{key}" in bad.message and words in bad.message, \
        bad.message if bad else None
    assert bad.exit_code == ExitCode.PROFILE_ERROR


def parse_doc(doc: dict[str, Any]) -> ProfileError | None:
    try:
        parse_profile(doc, "profile")
    except ProfileError as exc:
        return exc
    return None


@pytest.mark.parametrize(("key", "value", "words"), [
    ("zeta", 0.1, "greater than or equal to 0.2"),
    ("zeta", float("nan"), "finite"),
    ("delay_s", 0.02, "below servo.ts_s"),
    ("delay_s", -0.001, "greater than or equal to 0"),
    ("linear_range_deg", 0.0, "greater than 0"),
    ("residual_bound_deg", "0.1", "valid number"),
])
def test_a_bad_identified_servo_model_is_refused_naming_its_key(key: str, value: object,
                                                                words: str) -> None:
    doc = agile_doc()
    doc["servo"] = {**doc["servo"], key: value}
    bad = parse_doc(doc)
    assert bad is not None and "servo" in bad.message and words in bad.message, \
        bad.message if bad else None
    assert bad.exit_code == ExitCode.PROFILE_ERROR


def test_an_identified_servo_model_loads_and_a_p_alone_means_the_paper(agile) -> None:  # type: ignore[no-untyped-def]
    assert (agile.servo.zeta, agile.servo.delay_s, agile.servo.linear_range_deg) == (1.0, 0.0, None)
    doc = agile_doc()
    doc["servo"] = {**doc["servo"], "p": 44.3, "zeta": 0.79, "delay_s": 0.001,
                    "linear_range_deg": 9.5, "residual_bound_deg": 0.3,
                    "identified": {"date": "2026-11-27T06:00:00Z", "source": "logs/x",
                                   "samples": 1800, "fit_rms_deg": 0.05}}
    prof = parse_profile(doc, "profile")
    assert prof.servo.zeta == 0.79 and prof.servo.identified is not None
    assert prof.digest() != agile.digest()


@pytest.mark.parametrize("step_deg", [2.0, 12.0, 20.0, 30.0])
def test_the_room_at_home_check_clears_only_what_assess_finds_feasible(agile, step_deg: float) -> None:  # type: ignore[no-untyped-def]
    """The load-time check of the nodes one grid step around home clears them all at once;
    each node it clears is feasible by :func:`assess` itself, and each it leaves is not
    (steps from 2° to 30°: both verdicts occur)."""
    import itertools

    from spm_console.config.load import _clear_nodes
    from spm_console.config.models import link_model_of, model_of
    from spm_console.core.kinematics.assess import assess

    model, links, ws = model_of(agile), link_model_of(agile), agile.workspace
    home = np.asarray(agile.home.theta_deg, float)
    cube = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
    results = model.track_batch(np.radians(home + step_deg * cube))
    clear = _clear_nodes(model, links, results, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg))
    for r, sure in zip(results, clear, strict=True):
        feasible = r.ok and r.pose is not None and assess(
            model, links, r.pose, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg)).feasible
        assert sure == feasible
    if step_deg == 30.0:
        assert not all(clear)
    if step_deg == 2.0:
        assert all(clear)


def test_a_wrist_whose_home_passed_is_not_solved_again_but_a_changed_one_is(
        agile, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """Loading a profile again does not solve its home again; a profile that differs in what
    the check reads (here the grid step) is checked, and a refused one is refused every time."""
    import spm_console.config.load as load

    monkeypatch.setattr(load, "_HOME_CHECKED", set())  # (what other tests loaded: not here)
    text = (TESTS.parent / "profiles" / "agile_wrist.toml").read_text()
    load.parse_profile_text(text, "first")
    calls: list[str] = []
    real = load._check_home_mode
    monkeypatch.setattr(load, "_check_home_mode",
                        lambda prof, source: (calls.append(source), real(prof, source))[1])
    load.parse_profile_text(text, "again")
    assert calls == []
    data = tomllib.loads(text)
    data["workspace"]["step_deg"] = 3.0 if agile.workspace.step_deg != 3.0 else 5.0
    load.parse_profile_text(tomli_w.dumps(data), "coarser")
    assert calls == ["coarser"]
    data["workspace"]["step_deg"] = 30.0
    for k in range(2):
        with pytest.raises(ProfileError, match="leaves no room for a region around home"):
            load.parse_profile_text(tomli_w.dumps(data), f"no room {k}")
    assert calls == ["coarser", "no room 0", "no room 1"]


@pytest.mark.parametrize("value", ["yes", "no", 1, 0, 1.0])
def test_a_flag_is_true_or_false_never_a_word_or_a_number(value: object) -> None:
    """``workspace.refined_cover = "yes"`` (or 1) turned the refined cover on, ``"no"`` (or 0)
    off, silently: a flag is now as strict as a number (exit 3, naming the key)."""
    data = tomllib.loads((TESTS.parent / "profiles" / "agile_wrist.toml").read_text())
    data["workspace"]["refined_cover"] = value
    with pytest.raises(ProfileError, match=r"workspace\.refined_cover"):
        parse_profile(data, "lab.toml")
    data["workspace"]["refined_cover"] = True
    assert parse_profile(data, "lab.toml").workspace.refined_cover is True


def test_a_home_that_collides_in_the_seeds_mode_names_the_seed_too(tmp_path: Path) -> None:
    """Every sign flipped picks the mirrored assembly mode at home, whose links collide: the
    message blamed the home θ alone."""
    doc = agile_doc()
    doc["home"]["sign_seed"] = [-s for s in doc["home"]["sign_seed"]]
    path = tmp_path / "p.toml"
    path.write_text(tomli_w.dumps(doc))
    with pytest.raises(ProfileError, match=r"key 'home\.theta_deg'") as exc:
        load_profile(path)
    assert "home.sign_seed = [" in exc.value.message and "assembly mode" in exc.value.message
