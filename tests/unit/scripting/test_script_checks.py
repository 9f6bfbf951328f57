"""A script's targets and poses are checked before anything is powered, by the rules the
command line, target files and UDP messages use, and a refusal names the script's file, the
step, the key and the row. A follow step with a 100° roll passed the script's check (±360°),
homed the wrist and was then refused at step 2 (±90°, exit 4) with none of those named, while
``follow`` refused the same file before homing."""

from __future__ import annotations

import socket
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.follow_source import UdpTargets
from spm_console.config.load import parse_profile_text
from spm_console.config.schema import Profile
from spm_console.errors import ExitCode, SpmError
from spm_console.scripting.checks import check_script
from spm_console.scripting.steps import parse_script
from spm_console.store.target_file import read_target_csv, theta_of_rpy, timed_targets
from tests.support.paths import ROOT

FOLLOW = '[[step]]\ndo = "home"\n[[step]]\ndo = "follow"\nrpy = true\n'


def refusal(text: str, profile: Profile) -> SpmError | None:
    try:
        check_script(parse_script(text, "lab/s.toml"), profile)
    except SpmError as exc:
        return exc
    return None


def _udp(profile: Profile, rpy: list[float]) -> SpmError | None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with UdpTargets(profile, port) as src:
        try:
            src.parse(f'{{"rpy_deg": {rpy}}}'.encode())
        except SpmError as exc:
            return exc
    return None


#: Orientations from home, deg, and the exit code every source gives them (0: accepted).
ORIENTATIONS = [([100.0, 0.0, 0.0], 0), ([0.0, 0.0, -95.0], 0), ([0.0, 0.0, 360.0], 0),
                ([400.0, 0.0, 0.0], ExitCode.BAD_INPUT), ([0.0, -360.5, 0.0], ExitCode.BAD_INPUT),
                ([180.0, 0.0, 0.0], ExitCode.UNREACHABLE)]


@pytest.mark.parametrize(("rpy", "code"), ORIENTATIONS)
def test_a_script_a_target_file_and_udp_judge_an_orientation_alike(
        tmp_path: Path, agile: Profile, rpy: list[float], code: int) -> None:
    row = ", ".join(f"{x:g}" for x in rpy)
    csv = tmp_path / "rpy.csv"
    csv.write_text(f"0,0,0,0\n1,{row}\n")
    by_source: dict[str, SpmError | None] = {
        "inline": refusal(FOLLOW + f"targets = [[0, 0, 0, 0], [1, {row}]]\n", agile),
        "script file": refusal(FOLLOW + f'file = "{csv}"\n', agile),
        "udp": _udp(agile, rpy)}
    try:
        read_target_csv(agile, csv, True)
        by_source["follow --targets"] = None
    except SpmError as exc:
        by_source["follow --targets"] = exc
    codes = {k: 0 if e is None else int(e.exit_code) for k, e in by_source.items()}
    assert set(codes.values()) == {code}, codes
    if code:
        reasons = {(e.message if e else "").rsplit(": ", 1)[-1] for e in by_source.values()}
        assert len(reasons) == 1, by_source  # one rule, one reason


def test_the_refusal_names_the_script_the_step_the_key_and_the_row(agile: Profile) -> None:
    bad = refusal(FOLLOW + "targets = [[0, 0, 0, 0], [1, 5, 0, 0], [2, 400, 0, 0]]\n", agile)
    assert bad is not None and bad.exit_code == ExitCode.BAD_INPUT
    assert bad.message == ("lab/s.toml: step 2 (follow) key 'targets' row 3: roll must be in "
                           "[-360, 360] deg, got 400"), bad.message


def test_a_target_files_refusal_names_the_script_the_step_the_file_and_its_line(
        tmp_path: Path, agile: Profile) -> None:
    csv = tmp_path / "rpy.csv"
    csv.write_text("t,roll,pitch,yaw\n0,0,0,0\n# a comment\n1,180,0,0\n")
    bad = refusal(FOLLOW + f'file = "{csv}"\n', agile)
    assert bad is not None and bad.exit_code == ExitCode.UNREACHABLE
    assert bad.message.startswith(f"lab/s.toml: step 2 (follow) key 'file': {csv}:4: roll, "
                                  "pitch, yaw = "), bad.message
    assert "orientation out of reach" in bad.message


def test_target_times_are_refused_at_their_row(agile: Profile) -> None:
    bad = refusal('[[step]]\ndo = "follow"\ntargets = [[0, 130, 130, 130], [2, 131, 131, 131],'
                  ' [1, 132, 132, 132]]\n', agile)
    assert bad is not None and "step 1 (follow) key 'targets' row 3: target times must start " \
                               "at t ≥ 0 and increase strictly" in bad.message, bad


def test_the_step_takes_the_targets_the_check_accepted(agile: Profile) -> None:
    """The follow step builds its targets with the check's own rule: a 100° roll is a target
    (the follower projects what lies beyond its region, as for any θ), not a refusal after
    the homing."""
    text = FOLLOW + "targets = [[0, 0, 0, 0], [1, 100, 0, 0]]\n"
    assert refusal(text, agile) is None
    step = parse_script(text, "s.toml").step[1]
    timed = timed_targets(agile, [("row", r) for r in step.targets or ()], True)  # type: ignore[union-attr]
    np.testing.assert_allclose(timed.theta_deg[1], theta_of_rpy(agile, [100.0, 0.0, 0.0]))


def test_a_plan_pose_given_as_an_orientation_is_checked_as_its_motor_angles(
        agile: Profile) -> None:
    """As ``plan --start/--goal``: the θ an orientation names must lie in the servo limits
    and the grid, refused before the bus opens rather than at the plan step."""
    bad = refusal('[[step]]\ndo = "plan"\ngoal = {rpy = [100, 0, 0]}\n', agile)
    assert bad is not None and bad.exit_code == ExitCode.BAD_INPUT
    assert "lab/s.toml: step 1 (plan) key 'goal.rpy': θ1 = " in bad.message, bad.message
    assert "outside joint 1's servo limits" in bad.message
    assert refusal('[[step]]\ndo = "plan"\ngoal = {rpy = [10, 5, -15]}\n', agile) is None


def test_an_fk_orientation_ik_cannot_place_is_refused_before_anything_runs(
        agile: Profile) -> None:
    bad = refusal('[[step]]\ndo = "home"\n[[step]]\ndo = "fk"\nrpy = [180, 0, 0]\n', agile)
    assert bad is not None and bad.exit_code == ExitCode.UNREACHABLE
    assert bad.message.startswith("lab/s.toml: step 2 (fk) key 'rpy': "), bad.message


def test_yaw_beyond_90_degrees_is_what_a_wider_wrist_follows() -> None:
    """Why the bound of orientation targets is ±360° (as ``ik --rpy`` and θ targets), not the
    ±90° the follower's sources had: a coaxial wrist (γ = 0) with a wider grid and wider servo
    limits, a profile the schema accepts, reaches a 120° yaw inside both."""
    text = (ROOT / "profiles" / "coaxial_spm.toml").read_text()
    for old, new in (("theta_min_deg = -30.0", "theta_min_deg = -150.0"),
                     ("theta_max_deg = 30.0", "theta_max_deg = 150.0"),
                     ("step_deg = 2.0 ", "step_deg = 3.0 "),
                     ("min_deg = -60.0", "min_deg = -160.0"), ("max_deg = 60.0", "max_deg = 160.0")):
        assert old in text
        text = text.replace(old, new)
    wide = parse_profile_text(text, "wide.toml")
    theta = theta_of_rpy(wide, [0.0, 0.0, 120.0])
    np.testing.assert_allclose(theta, [120.0, 120.0, 120.0], atol=1e-9)
    assert all(wide.workspace.theta_min_deg <= t <= wide.workspace.theta_max_deg for t in theta)


#: Scripts whose steps' order alone is wrong, and what the refusal names.
ORDER = [
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "assert"\n', "step 2 (assert): no condition given"),
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "execute"\n[[step]]\ndo = "plan"\ngoal = "home"\n',
     "step 2 (execute): no plan step before it"),
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "assert"\nmax_duration_s = 3\n',
     "step 2 (assert) key 'max_duration_s': no plan step before it"),
    ('[[step]]\ndo = "home"\n' + '[[step]]\ndo = "wait"\nseconds = 3600\n' * 25,
     "the wait steps add up to 90000 s"),
]


@pytest.mark.parametrize(("text", "words"), ORDER)
def test_what_the_steps_order_decides_is_refused_before_the_bus_opens(
        agile: Profile, text: str, words: str) -> None:
    """Before these checks the wrist homed first, and only then was the script refused (or,
    for the waits, it waited)."""
    exc = refusal(text, agile)
    assert exc is not None and exc.exit_code == ExitCode.BAD_INPUT
    assert exc.message.startswith("lab/s.toml: ") and words in exc.message, exc.message


def test_a_plan_before_the_execute_and_24_hours_of_waits_pass(agile: Profile) -> None:
    ok = ('[[step]]\ndo = "plan"\ngoal = "home"\n[[step]]\ndo = "execute"\n'
          '[[step]]\ndo = "assert"\nmax_duration_s = 3\n'
          + '[[step]]\ndo = "wait"\nseconds = 3600\n' * 24)
    assert refusal(ok, agile) is None
    assert refusal((ROOT / "examples" / "session.toml").read_text(), agile) is None


def test_a_bad_fault_names_the_script_and_the_item(agile: Profile) -> None:
    exc = refusal('[session]\nfaults = ["stall:2@1", "explode:3"]\n[[step]]\ndo = "home"\n', agile)
    assert exc is not None and exc.exit_code == ExitCode.BAD_INPUT
    assert exc.message.startswith("lab/s.toml: [session] key 'faults' item 2"), exc.message
