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

import pytest

from spm_console.cli.main import main
from spm_console.core.region import Region
from spm_console.errors import ExitCode
from tests.planning_cases import polytope

B, INF, UNR = ExitCode.BAD_INPUT, ExitCode.INFEASIBLE, ExitCode.UNREACHABLE
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
    if as_json:  # SPEC §5: one JSON object on stdout, also on failure
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
    import spm_console.cli.kin as kin
    import spm_console.cli.plan as cli_plan

    monkeypatch.setattr(kin, "MAX_THETA_ROWS", 3)
    monkeypatch.setattr(cli_plan, "MAX_IDENTIFY_SAMPLES", 3)
    thetas = tmp_path / "thetas.csv"
    thetas.write_text("t1,t2,t3\n" + "100,100,100\n" * 4)
    assert main(["fk", "--theta-file", str(thetas)]) == B
    assert "more than 3 θ rows" in capsys.readouterr().err
    steps = tmp_path / "steps.csv"
    steps.write_text("t,ref,meas\n" + "".join(f"{0.02 * k},1,1\n" for k in range(4)))
    assert main(["identify", "--csv", str(steps), "--json"]) == B
    assert "4 samples, more than the 3" in capsys.readouterr().err


def test_output_folders_under_a_file_are_refused(files: dict[str, str], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    under = files["bin"] + "/x"
    for argv in (["reproduce", "--out", under, "--quick", "--no-execute"],
                 ["home", "--sim", "--logs", under], ["home", "--sim", "--logs", files["bin"]]):
        assert main(argv) == B
        err = capsys.readouterr().err
        assert "binary.dat is a file, not a folder" in err and "Traceback" not in err
