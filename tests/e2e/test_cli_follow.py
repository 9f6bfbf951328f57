"""``spm-console follow``: timed CSV targets (θ or roll/pitch/yaw), live UDP targets with the
example client, and bounded, refused inputs."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import load_run
from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT
HOME = [135.0, 135.0, 135.0]


def _json(capsys: pytest.CaptureFixture[str]) -> dict:  # type: ignore[type-arg]
    out = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("{")]
    assert len(out) == 1
    return json.loads(out[0])  # type: ignore[no-any-return]


#: How close each emulated wrist settles on the last target, deg: the ideal servos are the
#: model; the physical wrist's P-only drives stop short by friction and the links' weight,
#: unless the profile holds the load identified on it (then the runtime adds its offset).
SETTLED_DEG = {"ideal": 0.3, "physical": 0.6, "physical+load": 0.1}
#: The load ``python -m benchmarks physical`` identified on the physical wrist (deg per N·m of
#: the weight's holding torque, Coulomb friction in deg).
IDENTIFIED_LOAD = {"load_deg_per_nm": 1.39, "coulomb_deg": 0.085}


def _loaded_profile(tmp_path: Path) -> Path:
    from spm_console.config.load import load_profile
    from spm_console.config.servo_section import with_servo

    src = ROOT / "profiles" / "agile_wrist.toml"
    servo = load_profile(src).servo.model_copy(update=IDENTIFIED_LOAD)
    text, _ = with_servo(src.read_text(encoding="utf-8"), servo, "test")
    out = tmp_path / "loaded.toml"
    out.write_text(text, encoding="utf-8")
    return out


@pytest.mark.parametrize("plant", [
    "ideal",
    pytest.param("physical", marks=pytest.mark.slow),  # CI runs the slow set as its own stage
    pytest.param("physical+load", marks=pytest.mark.slow),
])
def test_follow_timed_rpy_targets_settles_on_the_last(tmp_path: Path, plant: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / "t.csv"
    csv.write_text("t, roll, pitch, yaw\n0, 0, 0, 0\n0.3, 6, 0, 0  # a step\n1.0, 0, -4, 3\n")
    loaded = plant.endswith("+load")
    extra = ["--profile", str(_loaded_profile(tmp_path))] if loaded else []
    code = main(["follow", "--sim", "--plant", plant.removesuffix("+load"), "--targets",
                 str(csv), "--rpy", "--json", "--logs", str(tmp_path / "logs"), *extra,
                 "--skip-homing", "test"])
    d = _json(capsys)
    assert code == 0 and d["outcome"] == "completed"
    from spm_console.config.load import load_profile
    from spm_console.store.target_file import theta_of_rpy

    last = theta_of_rpy(load_profile(ROOT / "profiles" / "agile_wrist.toml"), np.array([0, -4, 3.0]))
    np.testing.assert_allclose(d["final_deg"], last, atol=SETTLED_DEG[plant])
    assert d["follow"]["solves"] > 0 and d["follow"]["refused"] == 0
    run = load_run(d["log_dir"])
    assert run.meta["kind"] == "follow" and run.meta["homing"].startswith("skipped")
    np.testing.assert_allclose(run.vec("target")[-1], last, atol=1e-3)  # the log keeps 3 decimals


@pytest.mark.parametrize("text, why", [
    ("t,a,b,c\n", "no targets"),
    ("0,1,2\n", "four"),
    ("0,135,135,135\n0,136,135,135\n", "increase strictly"),
    ("0,135,135,nan\n", "finite"),
    ("x,y,z,w\nq,r,s,t\n", "four numbers"),
])
def test_bad_target_files_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      text: str, why: str) -> None:
    csv = tmp_path / "bad.csv"
    csv.write_text(text)
    code = main(["follow", "--sim", "--targets", str(csv), "--logs", str(tmp_path)])
    assert code == int(ExitCode.BAD_INPUT)
    assert why in capsys.readouterr().err


@pytest.mark.slow  # a whole real-time run (the slow set runs in CI as its own stage)
def test_live_udp_targets_from_the_example_client(tmp_path: Path) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen([sys.executable, "-m", "spm_console", "follow", "--sim", "--udp",
                             str(port), "--json", "--logs", str(tmp_path), "--deadman", "2",
                             "--skip-homing", "test"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        for _ in range(200):  # the following runs once the run folder has rows
            runs = list(tmp_path.glob("*/samples.csv"))
            if runs and runs[0].read_text().count("\n") > 3:
                break
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            subprocess.run(["sleep", "0.05"], check=True)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as c:  # junk is dropped, counted
            c.sendto(b"not json", ("127.0.0.1", port))
            c.sendto(b'{"theta_deg": [1, 2]}', ("127.0.0.1", port))
        subprocess.run([sys.executable, str(ROOT / "examples" / "follow_udp_client.py"), "--port",
                        str(port), "--seconds", "2"], check=True, timeout=30)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    d = json.loads(out)
    assert d["outcome"] == "completed" and d["udp"]["dropped"] == 2 and d["udp"]["received"] > 50
    np.testing.assert_allclose(d["final_deg"], HOME, atol=0.3)  # the client ends at roll 0
    assert d["follow"]["solve_ms_p99"] < 20.0 and d["follow"]["refused"] == 0


def test_a_stopped_following_keeps_its_exit_code_when_stdout_is_a_closed_pipe(
        tmp_path: Path) -> None:
    """`follow … | true`: the summary lines meet a closed pipe; the command still exits with
    the run's stop code (it used to exit 0 for a run stopped by a stalled joint)."""
    csv = tmp_path / "t.csv"
    csv.write_text("t,a,b,c\n0,127.53,83.23,85.25\n3,100,120,110\n")
    proc = subprocess.Popen(
        [sys.executable, "-m", "spm_console", "follow", "--sim", "--sim-start", "127.53",
         "83.23", "85.25", "--targets", str(csv), "--skip-homing", "test", "--fault",
         "stall:2@1.0", "--logs", str(tmp_path / "logs")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader is gone before anything is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == ExitCode.STOP_TRACKING, err
    assert "Traceback" not in err
