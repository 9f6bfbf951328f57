"""Every numeric argument and input file of the headless CLI is bounded: a bad value gets
its exit code and a message naming what was wrong, before any long work — never a
traceback, never an unbounded run. Each case runs with and without ``--json``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.core.polytope.region import Region
from spm_console.core.servo.identify import response
from spm_console.errors import ExitCode
from tests.support.paths import ROOT as PROJECT_ROOT
from tests.support.planning_cases import polytope

B, INF, UNR = ExitCode.BAD_INPUT, ExitCode.INFEASIBLE, ExitCode.UNREACHABLE
SOL = ExitCode.SOLVER_FAILED
TICK_DEG = 360.0 / 4096


def _step_record(p: float = 30.0, n: int = 60) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 3-joint step response of (27) sampled every 20 ms, quantized to encoder ticks."""
    t = np.arange(n) * 0.02
    ref = np.tile([100.0, 120.0, 90.0], (n, 1))
    ref[5:] = [130.0, 100.0, 95.0]
    return t, ref, np.round(response(p, 0.0, t, ref, ref[0]) / TICK_DEG) * TICK_DEG


def _write_identify_csv(path: Path, t: np.ndarray, ref: np.ndarray, meas: np.ndarray) -> None:
    rows = ["t,ref1,ref2,ref3,meas1,meas2,meas3"]  # line 1; sample k is on line k + 2
    rows += [",".join(repr(float(v)) for v in (t[k], *ref[k], *meas[k])) for k in range(len(t))]
    path.write_text("\n".join(rows) + "\n")


def _identify_files(d: Path) -> dict[str, Path]:
    """Hostile identify CSVs (named id_*): each edits a good step record."""
    t, ref, meas = _step_record()
    k = np.arange(len(t))[:, None]
    edits = {
        "id_huge": (t, np.where(k == 10, 1e308, ref), meas),
        "id_nan": (t, ref, np.where(k == 7, np.nan, meas)),
        "id_inf": (t, ref, np.where(k == 8, np.inf, meas)),
        "id_still": (t, np.full_like(ref, 100.0), np.full_like(meas, 100.0)),
        "id_ref_still": (t, np.full_like(ref, 100.0), meas),
        "id_ref_tick": (t, ref[0] + 0.05 * (k >= 5), meas),
        "id_meas_still": (t, ref, np.full_like(meas, 100.0)),
        "id_t_huge": (t * 1e300, ref, meas),
        "id_t_tiny": (t * 1e-300, ref, meas),
        "id_t_day": (t * 1e5, ref, meas),
        "id_t_repeat": (np.where(k[:, 0] == 20, t[19], t), ref, meas),
        "id_t_back": (t[::-1], ref, meas),
        "id_fast": (t, ref, np.round(response(5000.0, 0.0, t, ref, ref[0]) / TICK_DEG) * TICK_DEG),
    }
    out = {}
    for name, (tt, rr, mm) in edits.items():
        out[name] = d / f"{name}.csv"
        _write_identify_csv(out[name], tt, rr, mm)
    return out
S = ["--start", "127.53", "83.23", "85.25"]
G = ["--goal", "66.80", "155.00", "131.48"]


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("hostile")
    paths = {
        "bin": d / "binary.dat", "deep": d / "deep.json", "region": d / "region.json",
        "zero_row": d / "zero_row.json", "many_rows": d / "many_rows.json",
        "dir": d / "folder", "deep_toml": d / "deep.toml", "far_csv": d / "far.csv",
        "box": d / "box.json",
    }
    paths |= _identify_files(d)
    paths["bin"].write_bytes(bytes(range(256)) * 8)
    paths["deep"].write_text("[" * 100_000 + "]" * 100_000)
    paths["region"].write_text(json.dumps({"region": polytope().to_dict()}))
    paths["box"].write_text(json.dumps(Region.box(65.0, 155.0).to_dict()))
    paths["zero_row"].write_text(json.dumps({"A": [[1, 0, 0], [0, 0, 0]], "b": [1, 2]}))
    paths["many_rows"].write_text(json.dumps({"A": [[1, 0, 0]] * 1001, "b": [150] * 1001}))
    paths["dir"].mkdir()
    paths["deep_toml"].write_text("a = " + "[" * 50_000 + "]" * 50_000 + "\n")
    paths["far_csv"].write_text("t1,t2,t3\n100,100,100\n100,720,100\n")
    out = {k: str(v) for k, v in paths.items()}
    out["nodir"] = str(d / "missing" / "x.png")
    out["nodir_json"] = str(d / "missing" / "x.json")
    out["xyz"] = str(d / "figure.xyz")
    return out


# (argv with {placeholders} for `files`, exit code, words the message must contain)
CASES: list[tuple[list[str], int, tuple[str, ...]]] = [
    # plan: steps, intersample, speeds, angles, files
    (["plan", "mvn", *S, *G, "--steps", "10000000"], B, ("--steps", "2..5,000")),
    (["plan", "mvn", *S, *G, "--steps", "1"], B, ("--steps",)),
    (["plan", "mvn", *S, *G, "--intersample", "0"], B, ("--intersample", "1..100")),
    (["plan", "mvn", *S, *G, "--intersample", "1000000000"], B, ("--intersample",)),
    (["plan", "mvn", *S, *G, "--steps", "5000", "--intersample", "100"], B,
     ("--intersample", "100,000")),
    (["plan", "mvn", *S, *G, "--vmax", "nan"], B, ("--vmax", "must be a finite number")),
    (["plan", "mvn", *S, *G, "--vmax=-inf"], B, ("--vmax", "must be a finite number")),
    (["plan", "mvn", *S, *G, "--vmax", "0"], B, ("--vmax", "> 0")),
    (["plan", "mvn", *S, *G, "--vmax", "60"], B, ("--vmax 60", "limits.vmax_degps = 50")),
    (["plan", "mintime", *S, *G, "--vmax", "1e9"], B, ("--vmax 1e+09", "MX-106", "270")),
    (["plan", "mintime", *S, *G, "--vmax", "inf"], B, ("--vmax", "must be a finite number")),
    (["plan", "mintime", *S, *G, "--vmax", "200"], B, ("limits.vmax_degps = 50",)),
    (["plan", "mvn", "--start", "nan", "83", "85", *G], B, ("--start", "must be a finite number")),
    (["plan", "mvn", "--start", "1e308", "83", "85", *G, "--no-ref-limits"], B,
     ("--start", "θ1", "outside the grid", "65..155°")),
    (["plan", "mvn", *S, "--goal", "100", "100", "100000", "--no-ref-limits"], B,
     ("--goal", "θ3", "outside the grid", "65..155°")),
    (["plan", "mvn", *S, "--goal", "100", "100", "158", "--region", "{region}"], B,
     ("--goal", "outside the grid 65..155°")),
    (["plan", "mvn", "--start", "100", "170", "100", *G], B, ("--start", "joint 2", "servo limits")),
    (["plan", "mvn", *S, *G, "--out", "{nodir_json}"], B, ("--out", "does not exist")),
    (["plan", "mvn", *S, *G, "--plot", "{xyz}"], B, ("--plot", ".png")),
    (["plan", "mvn", *S, *G, "--plot", "{nodir}"], B, ("--plot", "does not exist")),
    (["plan", "mvn", *S, *G, "--region", "{bin}"], B, ("--region", "not UTF-8")),
    (["plan", "mvn", *S, *G, "--region", "{deep}"], B, ("--region", "nested too deeply")),
    (["plan", "mvn", *S, *G, "--region", "{dir}"], B, ("--region", "a directory, not a regular file")),
    (["plan", "mvn", *S, *G, "--region", "/dev/zero"], B, ("--region", "a device, not a regular file")),
    (["plan", "mvn", *S, *G, "--region", "{zero_row}"], B, ("--region", "row 1 is zero")),
    (["plan", "mvn", *S, *G, "--region", "{many_rows}"], B, ("--region", "1..1000 rows")),
    (["plan", "mintime", "--start", "70", "90", "80", *G, "--vmax", "0.01", "--region", "{box}"],
     INF, ("0.01 deg/s", "N ≤ 5000", "at least")),
    (["plan", "show", "{bin}"], ExitCode.PLAN_MISMATCH, ("not UTF-8",)),
    (["plan", "show", "{region}", "--plot", "{xyz}"], B, ("--plot", ".png")),
    (["identify", "--csv", "{bin}"], B, ("--csv", "not UTF-8")),
    (["identify", "--csv", "/dev/zero"], B, ("--csv", "a device, not a regular file")),
    # identify: what cannot be fitted is refused with its reason, never a made-up p
    (["identify", "--csv", "{id_huge}"], B, ("id_huge.csv, line 12", "ref1 = 1e+308", "±3600°")),
    (["identify", "--csv", "{id_nan}"], B, ("id_nan.csv, line 9", "meas1 = nan is not finite")),
    (["identify", "--csv", "{id_inf}"], B, ("id_inf.csv, line 10", "meas1 = inf is not finite")),
    (["identify", "--csv", "{id_still}"], B, ("id_still.csv", "reference never moves")),
    (["identify", "--csv", "{id_ref_still}"], B, ("id_ref_still.csv", "reference never moves")),
    (["identify", "--csv", "{id_ref_tick}"], B, ("reference moves by 0.05°", "0.5° needed")),
    (["identify", "--csv", "{id_meas_still}"], B,
     ("id_meas_still.csv", "measured position never moves", "did not follow")),
    (["identify", "--csv", "{id_t_huge}"], B, ("id_t_huge.csv, line 3", "t = 2e+298", "±1e+10 s")),
    (["identify", "--csv", "{id_t_tiny}"], B, ("id_t_tiny.csv", "sample interval", "below 0.0001 s")),
    (["identify", "--csv", "{id_t_day}"], B, ("id_t_day.csv", "span", "more than 86400 s")),
    (["identify", "--csv", "{id_t_repeat}"], B, ("id_t_repeat.csv", "strictly increasing", "line 22")),
    (["identify", "--csv", "{id_t_back}"], B, ("id_t_back.csv", "strictly increasing", "line 3")),
    (["identify", "--csv", "{id_fast}"], SOL, ("id_fast.csv", "cannot tell p", "from 2p")),
    # fk / ik
    (["fk", "--theta", "1e308", "100", "100"], B, ("--theta", "θ1", "one turn", "-360..360°")),
    (["fk", "--theta", "100", "inf", "100"], B, ("--theta", "must be a finite number")),
    (["fk", "--theta", "100", "100", "100", "--from", "nan", "1", "1"], B, ("--from", "finite")),
    (["fk", "--theta-file", "{bin}"], B, ("--theta-file", "not UTF-8")),
    (["fk", "--theta-file", "{dir}"], B, ("--theta-file", "a directory, not a regular file")),
    (["fk", "--theta-file", "/dev/zero"], B, ("--theta-file", "a device, not a regular file")),
    (["fk", "--theta-file", "{far_csv}"], B, (":3:", "-360..360°")),
    (["ik", "--rpy", "0", "89", "0"], INF, ("joint 1 θ1 = 55.475°", "joint 2 θ2 = 211.163°", "servo limits 60..160°")),
    (["ik", "--rpy", "nan", "0", "0"], B, ("--rpy roll", "must be a finite number")),
    (["ik", "--rpy", "0", "1e308", "0"], B, ("--rpy pitch", "[-360, 360]")),
    (["ik", "--v", "nan", "0", "0", "0", "1", "0", "0", "0", "1"], B, ("--v", "finite number")),
    # workspace: θ outside the grid is refused before the workspace is even loaded
    (["workspace", "check", "--theta", "100000", "100", "100"], B,
     ("--theta", "θ1 = 100000°", "outside the grid", "65..155°")),
    (["workspace", "check", "--theta", "100", "inf", "100"], B, ("--theta", "finite number")),
    (["workspace", "region", "--contain", "100", "100", "100", "1e6", "100", "100"], B,
     ("--contain θb", "outside the grid 65..155°")),
    (["workspace", "region", "--out", "{nodir_json}"], B, ("--out", "does not exist")),
    (["workspace", "verify", "--samples", "1000000000"], B, ("--samples", "1..10,000,000")),
    (["workspace", "verify", "--seed", "-1"], B, ("--seed",)),
    (["workspace", "show", "--plot", "{nodir}"], B, ("--plot", "missing", "does not exist")),
    (["workspace", "show", "--plot", "{xyz}"], B, ("--plot", ".png, .svg, .pdf")),
    # bus, emulator, runs
    (["emulate", "--initial", "1e30", "1", "2"], B, ("--initial", "θ1", "servo limits 60..160°")),
    (["emulate", "--initial", "nan", "100", "100"], B, ("--initial", "finite number")),
    (["emulate", "--duration", "nan"], B, ("--duration", "must be a finite number")),
    (["emulate", "--duration", "0"], B, ("--duration", "(0, 86400]")),
    (["emulate", "--duration", "1e300"], B, ("--duration", "(0, 86400]")),
    (["home", "--sim", "--sim-start", "1e30", "1", "2"], B, ("--sim-start", "servo limits")),
    (["execute", "--sim", "--plan", "{region}", "--sim-start", "nan", "1", "1"], B,
     ("--sim-start", "finite")),
    (["execute", "--sim", "--plan", "{deep}"], ExitCode.PLAN_MISMATCH, ("nested too deeply",)),
    (["servo", "ping", "--port", "/nonexistent", "--ids", "1", "1"], B, ("--ids", "at most once")),
    (["servo", "ping", "--port", "/nonexistent", "--ids", "99999"], B, ("--ids", "0..252")),
    # scripts
    (["script", "{bin}"], B, ("script", "not UTF-8")),
    (["script", "/dev/zero"], B, ("script", "a device, not a regular file")),
    (["script", "{deep_toml}"], B, ("nested too deeply",)),
]


def _id(case: tuple[list[str], int, tuple[str, ...]]) -> str:
    return " ".join(case[0])[:70]


@pytest.mark.parametrize("as_json", [False, True], ids=["text", "json"])
@pytest.mark.parametrize("case", CASES, ids=[_id(c) for c in CASES])
def test_bad_argument_is_refused_with_its_code_and_reason(
        case: tuple[list[str], int, tuple[str, ...]], as_json: bool, files: dict[str, str],
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SPM_CONSOLE_CACHE", str(tmp_path / "cache"))  # empty: no workspace yet
    monkeypatch.setenv("SPM_CONSOLE_LOGS", str(tmp_path / "logs"))
    argv, code, words = case
    argv = [a.format(**files) for a in argv] + (["--json"] if as_json else [])
    t0 = time.perf_counter()
    got = main(argv)
    out, err = capsys.readouterr()
    assert got == code, err
    assert "Traceback" not in err
    if as_json or argv[0] == "script":  # one JSON object on stdout, also on failure (a
        # script's summary always)
        assert json.loads(out) == {"ok": False, "exit_code": code, "error": json.loads(out)["error"]}
    else:
        assert out == ""
    for w in words:
        assert w in err, f"{w!r} not in {err!r}"
    assert time.perf_counter() - t0 < 20  # refused before any long work
    # nothing was built: a refusal never pays for the workspace
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").iterdir())


FIFO_CASES = [
    (["fk", "--profile", "{fifo}", "--theta", "95", "110", "105"], ExitCode.PROFILE_ERROR,
     "profile"),
    (["execute", "--sim", "--plan", "{fifo}"], ExitCode.PLAN_MISMATCH, "plan"),
    (["follow", "--sim", "--targets", "{fifo}"], B, "targets file"),
    (["script", "{fifo}"], B, "script"),
    (["identify", "--csv", "{fifo}"], B, "--csv"),
    (["fk", "--theta-file", "{fifo}"], B, "--theta-file"),
]


@pytest.mark.parametrize("case", FIFO_CASES, ids=[c[0][0] + " " + c[0][1] for c in FIFO_CASES])
def test_a_fifo_is_refused_at_once_never_waited_on(
        case: tuple[list[str], int, str], tmp_path: Path) -> None:
    """Opening a FIFO with no writer blocks for ever: every named file is opened without
    blocking and refused unless it is a regular file (a subprocess: a hang fails, never stalls
    the suite)."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    argv, code, what = case
    argv = [a.format(fifo=fifo) for a in argv]
    env = {**os.environ, "SPM_CONSOLE_LOGS": str(tmp_path / "logs")}
    r = subprocess.run([sys.executable, "-m", "spm_console", *argv], capture_output=True,
                       text=True, timeout=60, env=env)
    assert r.returncode == int(code), r.stderr
    assert f"{fifo}" in r.stderr and "a FIFO (named pipe), not a regular file" in r.stderr
    assert what in r.stderr and "Traceback" not in r.stderr


def test_a_huge_profile_is_refused_without_reading_it(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    big = tmp_path / "big.toml"
    with big.open("wb") as fh:  # 20 MB, sparse
        fh.truncate(20 * 1024 * 1024)
    assert main(["fk", "--profile", str(big), "--theta", "95", "110", "105"]) == \
        ExitCode.PROFILE_ERROR
    assert "larger than the 256 kB limit" in capsys.readouterr().err


def test_row_counts_are_capped(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                               monkeypatch: pytest.MonkeyPatch) -> None:
    """fk --theta-file and identify --csv refuse more rows than their documented caps."""
    import spm_console.cli.identify as cli_identify
    import spm_console.cli.kin as kin

    monkeypatch.setattr(kin, "MAX_THETA_ROWS", 3)
    monkeypatch.setattr(cli_identify, "MAX_IDENTIFY_SAMPLES", 3)
    thetas = tmp_path / "thetas.csv"
    thetas.write_text("t1,t2,t3\n" + "100,100,100\n" * 4)
    assert main(["fk", "--theta-file", str(thetas)]) == B
    assert "more than 3 θ rows" in capsys.readouterr().err
    steps = tmp_path / "steps.csv"
    steps.write_text("t,ref,meas\n" + "".join(f"{0.02 * k},1,1\n" for k in range(4)))
    assert main(["identify", "--csv", str(steps), "--json"]) == B
    assert "4 samples, more than the 3" in capsys.readouterr().err



def test_identify_refuses_a_p_the_profile_cannot_hold(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """A fit of p = 300 rad/s is refused (exit 7) for a profile sampled at 0.2 s: p·Ts = 60
    is outside the [0.001, 10] a profile accepts; the default profile (Ts = 20 ms) takes it."""
    agile = (PROJECT_ROOT / "profiles" / "agile_wrist.toml").read_text()
    slow = tmp_path / "slow.toml"
    slow.write_text(agile.replace("ts_s = 0.02 ", "ts_s = 0.2 ")
                    .replace("watchdog_ms = 100 ", "watchdog_ms = 500 "))
    csv_file = tmp_path / "fast.csv"
    _write_identify_csv(csv_file, *_step_record(p=300.0))
    assert main(["identify", "--csv", str(csv_file), "--json"]) == ExitCode.OK
    assert abs(json.loads(capsys.readouterr().out)["p"] / 300 - 1) < 0.02
    assert main(["identify", "--csv", str(csv_file), "--profile", str(slow)]) == SOL
    err = capsys.readouterr().err
    assert "fast.csv" in err and "p·Ts = 59" in err and "[0.001, 10]" in err, err


def test_identify_of_a_run_skips_lost_replies_and_refuses_corrupt_rows(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """In a run log an empty measurement is a lost reply: the row is skipped and the fit
    goes on. Any other non-finite value (an edited log) is refused naming the data row."""
    t, ref, meas = _step_record(p=32.22)
    lost = {3, 17, 40}

    def write_run(name: str, cell: tuple[int, int, str] | None = None) -> None:
        run = tmp_path / "logs" / name
        run.mkdir(parents=True)
        rows = ["t,k,phase,ref1,ref2,ref3,meas1,meas2,meas3"]
        for k in range(len(t)):
            cells = [f"{t[k]:.6f}", str(k), "plan", *(f"{v:.6g}" for v in ref[k]),
                     *("" if k in lost else f"{v:.6g}" for v in meas[k])]
            if cell is not None and cell[0] == k:
                cells[cell[1]] = cell[2]
            rows.append(",".join(cells))
        (run / "samples.csv").write_text("\n".join(rows) + "\n")

    write_run("good")
    write_run("edited", (25, 4, "inf"))
    logs = ["--logs", str(tmp_path / "logs")]
    assert main(["identify", "--run", "good", *logs, "--json"]) == ExitCode.OK
    d = json.loads(capsys.readouterr().out)
    assert d["samples"] == len(t) - len(lost) and abs(d["p"] / 32.22 - 1) < 0.02
    assert main(["identify", "--run", "edited", *logs]) == B
    err = capsys.readouterr().err
    assert "samples.csv, data row 26: ref2 = inf is not finite" in err and "Traceback" not in err

def test_output_folders_under_a_file_are_refused(files: dict[str, str], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    under = files["bin"] + "/x"
    for argv in (["reproduce", "--out", under, "--quick", "--no-execute"],
                 ["home", "--sim", "--logs", under], ["home", "--sim", "--logs", files["bin"]]):
        assert main(argv) == B
        err = capsys.readouterr().err
        assert "binary.dat is a file, not a folder" in err and "Traceback" not in err


@pytest.mark.parametrize("which", ["samples.csv", "events.jsonl", "meta.json"])
def test_a_run_log_file_that_is_a_fifo_is_refused_never_waited_on(tmp_path: Path, which: str) -> None:
    """`logs show` and `identify --run` read run folders an operator names: a FIFO in one
    (no writer) used to block them for ever."""
    from tests.support.runlog_helpers import write_run

    run = write_run(tmp_path / "logs", "completed", rows=40).path
    (run / which).unlink()
    os.mkfifo(run / which)
    env = {**os.environ, "SPM_CONSOLE_LOGS": str(tmp_path / "logs")}
    for argv in (["logs", "show", str(run)], ["identify", "--run", str(run)]):
        r = subprocess.run([sys.executable, "-m", "spm_console", *argv], capture_output=True,
                           text=True, timeout=60, env=env)
        assert "Traceback" not in r.stderr, r.stderr
        if which == "samples.csv":  # the data: refused, exit 4
            assert r.returncode == ExitCode.BAD_INPUT and "a FIFO" in r.stderr, r.stderr
        elif argv[0] == "logs":  # meta or events unreadable: the run is shown without them
            assert r.returncode == ExitCode.OK, r.stderr
        else:  # the samples are read: the fit answers for itself (never a bug, never a hang)
            assert r.returncode != ExitCode.INTERNAL, r.stderr
