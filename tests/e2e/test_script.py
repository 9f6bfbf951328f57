"""Headless scripted sessions: the example, results, assertions, faults, bad files, signals."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.errors import BadInputError, ExitCode
from spm_console.motion.logs.runlog import list_runs
from spm_console.scripting.steps import load_script, parse_script
from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT

SHORT = """
[session]
initial_deg = [130.0, 138.0, 133.0]

[[step]]
do = "home"

[[step]]
do = "fk"
rpy = [10.0, 5.0, -15.0]

[[step]]
do = "workspace"

[[step]]
do = "plan"
goal = {theta = [120.0, 125.0, 128.0]}
steps = 30

[[step]]
do = "execute"

[[step]]
do = "assert"
outcome = "completed"
exit_code = 0
theta_near = [120.0, 125.0, 128.0]
tol_deg = 0.5
max_duration_s = 0.6
"""


@pytest.fixture(autouse=True)
def _cache(monkeypatch: pytest.MonkeyPatch, tmp_path_factory: pytest.TempPathFactory) -> None:
    """One workspace cache for this module (built by the first test that needs it)."""
    d = tmp_path_factory.getbasetemp() / "script-ws-cache"
    monkeypatch.setenv("SPM_CONSOLE_CACHE", str(d))


def _run(tmp_path: Path, text: str, capsys: pytest.CaptureFixture[str], *extra: str
         ) -> tuple[int, dict, str]:  # type: ignore[type-arg]
    f = tmp_path / "s.toml"
    f.write_text(text)
    code = main(["script", str(f), "--logs", str(tmp_path / "logs"), *extra])
    out, err = capsys.readouterr()
    return code, json.loads(out), err


def test_short_session_runs_every_step_and_reports_json(tmp_path, capsys, agile) -> None:
    code, summary, err = _run(tmp_path, SHORT, capsys)
    assert code == 0 and summary["ok"], err
    steps = summary["steps"]
    assert [s["do"] for s in steps] == ["home", "fk", "workspace", "plan", "execute", "assert"]
    assert all(s["ok"] for s in steps)
    # progress on stderr, one line per step
    assert all(f"[{i}/6]" in err for i in range(1, 7))
    # fk from an orientation: the IK solution, and its FK gives that orientation back
    from spm_console.config.models import model_of
    from spm_console.core.kinematics.ik import ik_rpy

    fk = steps[1]["result"]
    expect = ik_rpy(model_of(agile), *np.radians([10.0, 5.0, -15.0])).theta_deg
    np.testing.assert_allclose(fk["theta_deg"], expect, atol=1e-5)
    plan = steps[3]["result"]
    assert plan["kind"] == "mvn" and plan["N"] == 30
    np.testing.assert_allclose(plan["start_deg"], [135, 135, 135], atol=0.1)  # "current" = home
    ex = steps[4]["result"]
    assert ex["outcome"] == "completed" and Path(ex["log_dir"]).is_dir()
    assert [r.meta["outcome"] for r in list_runs(tmp_path / "logs")] == ["completed", "completed"]


def test_failed_assertion_exits_11_and_stops_there(tmp_path, capsys) -> None:
    text = SHORT + '\n[[step]]\ndo = "wait"\nseconds = 0\n'
    text = text.replace("theta_near = [120.0, 125.0, 128.0]", "theta_near = [121.0, 125.0, 128.0]")
    code, summary, err = _run(tmp_path, text, capsys)
    assert code == ExitCode.ASSERTION_FAILED
    last = summary["steps"][-1]
    assert last["do"] == "assert" and not last["ok"]
    # θ settles within about 0.1° of 120 (emulator noise, timing): the distance to 121 is about 1°
    m = re.search(r"is (\d+\.\d+)° from \[121\.0, 125\.0, 128\.0\]°", last["error"])
    assert m is not None and 0.8 < float(m.group(1)) < 1.2, last["error"]
    assert last["result"] == {"outcome": True, "exit_code": True, "theta_near": False,
                              "max_duration_s": True}
    assert len(summary["steps"]) == 6  # the wait after it never ran
    assert "FAILED" in err


def test_a_stalled_joint_stops_the_script_with_the_stop_code(tmp_path, capsys) -> None:
    text = SHORT.replace("[session]\n", "[session]\nfaults = [\"stall:2\"]\n")
    code, summary, _ = _run(tmp_path, text, capsys)
    assert code == ExitCode.STOP_TRACKING
    ex = summary["steps"][-1]
    assert ex["do"] == "execute" and not ex["ok"] and "joint 2" in ex["error"]
    assert ex["result"]["outcome"] == "stopped"


def test_allow_stop_turns_a_stop_into_a_result(tmp_path, capsys) -> None:
    text = SHORT.replace("[session]\n", "[session]\nfaults = [\"stall:2\"]\n")
    text = text.replace('do = "execute"', 'do = "execute"\nallow_stop = true')
    a = text.index('[[step]]\ndo = "assert"')
    text = text[:a] + '[[step]]\ndo = "assert"\noutcome = "stopped"\nexit_code = 21\n'
    code, summary, _ = _run(tmp_path, text, capsys)
    assert code == 0, summary
    assert summary["steps"][-1]["result"] == {"outcome": True, "exit_code": True}


@pytest.mark.parametrize(("text", "needle"), [
    ('[[step]]\ndo = "dance"\n', "step 1 (dance): unknown step kind"),
    ('[[step]]\ndo = "home"\n\n[[step]]\ndo = "plan"\nstart = "current"\n', "step 2 (plan) key 'goal': missing key"),
    ('[[step]]\ndo = "wait"\nsecond = 1\n', "step 1 (wait) key 'second': unknown key"),
    ('[[step]]\ndo = "fk"\ntheta = [1, 2]\n', "step 1 (fk) key 'theta'"),
    ('[[step]]\ndo = "wait"\nseconds = nan\n', "step 1 (wait) key 'seconds'"),
    ('[session]\nprofil = "x"\n[[step]]\ndo = "home"\n', "key 'session.profil': unknown key"),
    ('step = [\n', "not valid TOML"),
    ('[session]\n', "key 'step'"),
])
def test_bad_scripts_name_file_step_and_key(text: str, needle: str) -> None:
    with pytest.raises(BadInputError) as exc:
        parse_script(text, "bad.toml")
    assert exc.value.message.startswith("bad.toml: "), exc.value.message
    assert needle in exc.value.message, exc.value.message


@pytest.mark.parametrize(("text", "needle"), [
    ('[[step]]\ndo = "fk"\ntheta = [true, 110, 105]\n', "step 1 (fk) key 'theta': expected three finite numbers"),
    ('[[step]]\ndo = "plan"\ngoal = "home"\nsteps = "150"\n', "step 1 (plan) key 'steps'"),
    ('[[step]]\ndo = "plan"\ngoal = "home"\nsteps = 150.0\n', "step 1 (plan) key 'steps'"),
    ('[[step]]\ndo = "execute"\nallow_stop = 1\n', "step 1 (execute) key 'allow_stop'"),
])
def test_values_are_never_coerced(text: str, needle: str) -> None:
    """A boolean is not a number, a string not an integer, a number not a boolean."""
    with pytest.raises(BadInputError) as exc:
        parse_script(text, "bad.toml")
    assert needle in exc.value.message, exc.value.message


@pytest.mark.parametrize(("text", "needle"), [
    ('[[step]]\ndo = "plan"\ngoal = "home"\nvmax = 200\n',
     "step 1 (plan) key 'vmax' = 200 deg/s is above the profile's planning limit"),
    ('[session]\ninitial_deg = [10, 135, 135]\n[[step]]\ndo = "home"\n',
     "[session] key 'initial_deg': θ1 = 10° is outside joint 1's servo limits"),
    ('[[step]]\ndo = "fk"\ntheta = [1e308, 110, 105]\n',
     "step 1 (fk) key 'theta': θ1 = 1e+308° is outside the range"),
    ('[[step]]\ndo = "plan"\nstart = {theta = [95, 110, 300]}\ngoal = "home"\n',
     "step 1 (plan) key 'start.theta': θ3 = 300° is outside joint 3's servo limits"),
    ('[[step]]\ndo = "follow"\ntargets = [[0, 130, 130, 130], [1e9, 131, 131, 131]]\n',
     "step 1 (follow) key 'targets' row 2: target times must end by t = 600 s"),
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "follow"\nrpy = true\n'
     'targets = [[0, 0, 0, 0], [1, 400, 0, 0]]\n',
     "s.toml: step 2 (follow) key 'targets' row 2: roll must be in [-360, 360] deg, got 400"),
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "follow"\n', "step 2 (follow): give exactly one of"),
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "follow"\nfile = "{typo}"\n',
     "four numbers expected"),  # the file is read before the homing moves anything
    ('[[step]]\ndo = "home"\n[[step]]\ndo = "follow"\nfile = "{fifo}"\n', "a FIFO"),
    ('[[step]]\ndo = "fk"\n', "step 1 (fk): give exactly one of theta or rpy"),
])
def test_a_script_follows_the_command_lines_input_rules(
        tmp_path, capsys, text: str, needle: str) -> None:  # type: ignore[no-untyped-def]
    """The values the CLI refuses with 4 are refused in a script too, before the bus opens."""
    typo, fifo = tmp_path / "typo.csv", tmp_path / "fifo"
    typo.write_text("13x,130,130,130\n1,131,131,131\n")
    os.mkfifo(fifo)
    f = tmp_path / "s.toml"
    f.write_text(text.replace("{typo}", str(typo)).replace("{fifo}", str(fifo)))
    assert main(["script", str(f), "--logs", str(tmp_path / "logs")]) == ExitCode.BAD_INPUT
    err = capsys.readouterr().err
    assert needle in err, err
    assert not (tmp_path / "logs").exists()  # nothing ran


def test_an_orientation_ik_cannot_place_is_refused_before_the_homing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Exit 5 as ``follow --rpy`` gives the same row, naming the script, step, key and row;
    nothing runs (no run log)."""
    f = tmp_path / "s.toml"
    f.write_text('[[step]]\ndo = "home"\n[[step]]\ndo = "follow"\nrpy = true\n'
                 'targets = [[0, 0, 0, 0], [1, 180, 0, 0]]\n')
    assert main(["script", str(f), "--logs", str(tmp_path / "logs")]) == ExitCode.UNREACHABLE
    err = capsys.readouterr().err
    assert f"{f}: step 2 (follow) key 'targets' row 2: roll, pitch, yaw = " in err, err
    assert "orientation out of reach" in err and not (tmp_path / "logs").exists()


def test_a_plan_end_outside_the_workspace_is_refused_before_the_homing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A plan step's goal inside the grid and servo limits but not feasible: exit 6 as
    ``plan --goal`` gives, naming the script, step and key, before anything moves (no run
    log: the homing before it never ran)."""
    f = tmp_path / "s.toml"
    f.write_text('[[step]]\ndo = "home"\n[[step]]\ndo = "plan"\n'
                 'goal = {theta = [70.0, 155.0, 70.0]}\n')
    assert main(["script", str(f), "--logs", str(tmp_path / "logs")]) == ExitCode.INFEASIBLE
    err = capsys.readouterr().err
    assert f"{f}: step 2 (plan) key 'goal.theta': θ = " in err, err
    assert "NOT feasible" in err and not (tmp_path / "logs").exists()


def test_bad_script_exit_code_and_no_traceback(tmp_path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text('[[step]]\ndo = "dance"\n')
    p = subprocess.run([sys.executable, "-m", "spm_console", "script", str(f)], cwd=ROOT,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == ExitCode.BAD_INPUT
    assert "unknown step kind" in p.stderr and "Traceback" not in p.stderr


def test_the_example_parses() -> None:
    s = load_script(ROOT / "examples" / "session.toml")
    assert [st.do for st in s.step][:3] == ["home", "fk", "assert"]


@pytest.mark.slow
def test_the_example_runs(tmp_path) -> None:
    p = subprocess.run([sys.executable, "-m", "spm_console", "script", "examples/session.toml",
                        "--logs", str(tmp_path)], cwd=ROOT, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["ok"]


def _spawn_script(tmp_path: Path, text: str) -> subprocess.Popen[str]:
    typo, fifo = tmp_path / "typo.csv", tmp_path / "fifo"
    typo.write_text("13x,130,130,130\n1,131,131,131\n")
    os.mkfifo(fifo)
    f = tmp_path / "s.toml"
    f.write_text(text.replace("{typo}", str(typo)).replace("{fifo}", str(fifo)))
    env = {**os.environ, "SPM_CONSOLE_CACHE": os.environ["SPM_CONSOLE_CACHE"]}
    return subprocess.Popen([sys.executable, "-m", "spm_console", "script", str(f), "--logs",
                             str(tmp_path / "logs")], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


@pytest.mark.usefixtures("sighup_default", "paced_clock")  # the signal lands mid-motion
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
def test_a_signal_stops_the_motion_and_ends_cleanly(tmp_path, sig) -> None:
    """SIGTERM (kill) and SIGHUP (the terminal closed) mid-motion: E-stop, exit 20."""
    p = _spawn_script(tmp_path, SHORT.replace("steps = 30", "steps = 400"))  # 8 s of motion
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end:  # wait until the execute step has started
        runs = list_runs(tmp_path / "logs")
        if any(r.meta.get("kind") == "execute" for r in runs):
            break
        time.sleep(0.05)
    time.sleep(0.5)
    p.send_signal(sig)
    out, err = p.communicate(timeout=30)
    assert p.returncode == ExitCode.STOP_ESTOP, err
    summary = json.loads(out)
    assert summary["steps"][-1]["do"] == "execute" and not summary["steps"][-1]["ok"]
    run = next(r for r in list_runs(tmp_path / "logs") if r.meta["kind"] == "execute")
    assert run.meta["outcome"] == "stopped" and run.meta["exit_code"] == ExitCode.STOP_ESTOP
    assert run.meta["message"] == f"E-stop: signal {sig.name}"


def test_a_signal_while_nothing_moves_interrupts_at_once(tmp_path) -> None:
    """SIGQUIT during a 60 s wait step: the script ends now with 130, not after the wait."""
    p = _spawn_script(tmp_path, '[[step]]\ndo = "wait"\nseconds = 60\n')
    assert p.stderr is not None
    line = p.stderr.readline()  # "script ...: 1 steps on the emulated bus": the wait begins
    assert "1 steps" in line, line
    time.sleep(0.3)
    t0 = time.monotonic()
    p.send_signal(signal.SIGQUIT)
    out, err = p.communicate(timeout=30)
    assert p.returncode == ExitCode.INTERRUPTED, err
    assert time.monotonic() - t0 < 5
    summary = json.loads(out)
    assert summary["message"] == "step 1 (wait) interrupted"
    assert summary["steps"] == [{"index": 1, "do": "wait", "ok": False, "seconds": summary["steps"][0]["seconds"],
                                 "error": "interrupted"}]


FOLLOW = """
[[step]]
do = "home"

[[step]]
do = "follow"
rpy = true
targets = [[0.0, 0.0, 0.0, 0.0], [0.3, 5.0, 0.0, 0.0], [0.9, 0.0, -4.0, 2.0]]

[[step]]
do = "assert"
outcome = "completed"
"""


def test_a_follow_step_tracks_timed_targets(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            agile) -> None:  # type: ignore[no-untyped-def]
    from spm_console.store.target_file import theta_of_rpy

    code, d, err = _run(tmp_path, FOLLOW, capsys)
    assert code == 0, err
    step = d["steps"][1]
    last = theta_of_rpy(agile, np.array([0.0, -4.0, 2.0]))
    np.testing.assert_allclose(step["result"]["final_deg"], last, atol=0.3)
    assert step["result"]["follow"]["solves"] > 0
    assert sorted(r.meta["kind"] for r in list_runs(tmp_path / "logs")) == ["follow", "home"]
    bad = FOLLOW.replace('targets = [[0.0, 0.0, 0.0, 0.0]', 'file = "t.csv"\ntargets = [[0.0, 0.0, 0.0, 0.0]')
    f = tmp_path / "bad.toml"
    f.write_text(bad)  # refused before the bus opens (nothing moves first)
    assert main(["script", str(f), "--logs", str(tmp_path / "logs2")]) == ExitCode.BAD_INPUT
    assert "exactly one of targets or file" in capsys.readouterr().err
    assert not (tmp_path / "logs2").exists()


def test_the_session_table_chooses_the_emulated_wrist() -> None:
    """``[session] plant`` is ``--plant`` for a script: the physical wrist on the emulated bus;
    refused with a serial port (it is the emulator's), and any other value is named."""
    from spm_console.scripting.runner import session_for

    script = parse_script('[session]\nplant = "physical"\n[[step]]\ndo = "home"\n', "s.toml")
    session = session_for(script)
    assert session.profile.plant.model == "physical"
    assert session.bus_label == "emulated bus (physical wrist)"
    assert session_for(parse_script('[[step]]\ndo = "home"\n', "s.toml")).bus_label == "emulated bus"
    with pytest.raises(BadInputError, match="plant apply to the emulated bus only"):
        session_for(parse_script('[session]\nplant = "ideal"\nport = "/dev/ttyUSB0"\n'
                                 '[[step]]\ndo = "home"\n', "s.toml"))
    with pytest.raises(BadInputError, match=r"session\.plant"):
        parse_script('[session]\nplant = "rubber"\n[[step]]\ndo = "home"\n', "s.toml")
