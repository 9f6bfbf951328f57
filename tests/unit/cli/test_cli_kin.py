"""The fk / ik commands as an API: JSON keys, exit codes, stderr diagnostics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err

def test_fk_json_keys(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "fk", "--theta", "95", "110", "105", "--json")
    assert code == 0
    d = json.loads(out)
    for key in ("theta_deg", "v", "n", "zeta", "residual", "min_link_distance_mm", "feasible"):
        assert key in d
    np.testing.assert_allclose(d["n"], [0.2320, 0.0613, 0.9708], atol=6e-5)
    assert d["feasible"] is True

def test_fk_all_modes(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "fk", "--theta", "108", "60", "105", "--all-modes", "--json")
    assert code == 0
    modes = json.loads(out)["modes"]
    assert 2 <= len(modes) <= 8 and sum(m["home_connected"] for m in modes) == 1

def test_the_session_fk_is_the_cli_record(capsys: pytest.CaptureFixture[str]) -> None:
    """The console's and scripts' FK (the session's ``WristService.fk``) and ``fk --json`` are
    one record: same keys in the same order, same numbers, modes included."""
    from spm_console.cli.common import to_jsonable
    from spm_console.services.wrist_service import WristService
    from tests.support.ws_helpers import agile_profile

    rec = WristService(agile_profile()).fk([108.0, 60.0, 105.0], all_modes=True)
    code, out, _ = run(capsys, "fk", "--theta", "108", "60", "105", "--all-modes", "--json")
    assert code == 0
    assert out == json.dumps(to_jsonable(rec.as_json())) + "\n"
    assert rec.modes is not None and len(json.loads(out)["modes"]) == len(rec.modes)

def test_fk_theta_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "t.csv"
    f.write_text("t1,t2,t3\n95,110,105\n108,60,105\n135,135,135\n")
    code, out, _ = run(capsys, "fk", "--theta-file", str(f), "--json")
    assert code == 0
    res = json.loads(out)
    assert isinstance(res, list)
    assert len(res) == 3 and all(r["ok"] for r in res)
    np.testing.assert_allclose(res[2]["n"], [0, 0, 1], atol=1e-12)
    assert [r["row"] for r in res] == [1, 2, 3]


def test_fk_theta_file_names_the_row_it_could_not_solve(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """A refused row's record had only ok, reason and the path's ζ: which row, and which θ,
    was left to the reader to count."""
    f = tmp_path / "t.csv"
    f.write_text("95,110,105\n10,170,20\n")
    code, out, _ = run(capsys, "fk", "--theta-file", str(f), "--json")
    assert code == 5
    bad = json.loads(out)[1]
    assert bad["ok"] is False and bad["row"] == 2 and bad["theta_deg"] == [10, 170, 20]

@pytest.mark.parametrize(
    ("argv", "code", "needle"),
    [
        (["fk", "--theta", "95", "110", "nan"], 4, "finite"),
        (["fk", "--theta", "10", "170", "20"], 5, "singularity"),
        (["fk", "--profile", "nope.toml", "--theta", "1", "2", "3"], 3, "nope.toml"),
        (["fk", "--theta", "1", "2"], 2, ""),
        (["ik", "--v", "1", "0", "0", "0", "1", "0", "0", "0", "2"], 4, "unit vectors"),
    ],
)
def test_errors_exit_codes(capsys: pytest.CaptureFixture[str], argv: list[str], code: int, needle: str) -> None:
    got, out, err = run(capsys, *argv)
    assert got == code
    assert out == ""
    assert needle in err
    assert "Traceback" not in err

def test_ik_rpy_roundtrip(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "ik", "--rpy", "10", "5", "-20", "--json")
    assert code == 0
    th = json.loads(out)["theta_deg"]
    code, out, _ = run(capsys, "fk", "--theta", *map(str, th), "--json")
    v = np.array(json.loads(out)["v"])
    from spm_console.config.load import load_profile
    from spm_console.config.models import model_of
    from spm_console.core.kinematics.rotations import rpy_matrix

    m = model_of(load_profile())
    R = rpy_matrix(*np.radians([10.0, 5.0, -20.0]))
    np.testing.assert_allclose(v, m.v_home @ R.T, atol=1e-9)

def test_command_table_matches_registered_parsers() -> None:
    """Each module registers exactly the commands the lazy table maps to it."""
    import argparse
    import importlib

    from spm_console.cli.main import COMMAND_MODULES, COMMANDS

    for mod in COMMAND_MODULES:
        parser = argparse.ArgumentParser()
        sub = parser.add_subparsers(dest="command")
        importlib.import_module(mod).register(sub)
        assert set(sub.choices) == {c for c, m in COMMANDS.items() if m == mod}, mod


def test_ik_takes_the_axes_fk_prints(capsys: pytest.CaptureFixture[str]) -> None:
    """fk prints v to four decimals, and ik refused them (norms 1 ± 1e-4 against a tolerance
    of 1e-6): axes within ROUNDED_AXES_TOL of an orientation are taken as the nearest one,
    with a note; axes farther off are still refused."""
    code, out, _ = run(capsys, "fk", "--theta", "120", "100", "110")
    assert code == 0
    rows = [line.split("=", 1)[1] for line in out.splitlines() if line.startswith(("v1", "v2", "v3"))]
    printed = [x.strip(" []") for row in rows for x in row.split(",")]
    assert len(printed) == 9 and all(len(x.split(".")[1]) == 4 for x in printed)
    code, out, err = run(capsys, "ik", "--v", *printed, "--json")
    assert code == 0, err
    assert "nearest orientation" in err
    np.testing.assert_allclose(json.loads(out)["theta_deg"], [120, 100, 110], atol=0.01)
    two = [f"{float(x):.2f}" for x in printed]
    code, _, err = run(capsys, "ik", "--v", *two)
    assert code == 4 and "unit vectors" in err
