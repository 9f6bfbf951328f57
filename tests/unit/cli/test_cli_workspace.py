"""``spm-console workspace …``: JSON keys, exit codes, messages."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.core.polytope.region import Region
from spm_console.errors import ExitCode
from spm_console.store.workspace_cache import cache_key, cache_path, save
from tests.support.ws_helpers import MINTIME_START, MVN_GOAL, MVN_START, agile_profile, agile_workspace


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A cache directory holding the Agile Wrist workspace (built once per run)."""
    d = tmp_path_factory.mktemp("cache")
    prof = agile_profile()
    save(agile_workspace(), cache_path(prof, d), cache_key(prof))
    return d


@pytest.fixture(autouse=True)
def _env(cache_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SPM_CONSOLE_CACHE", str(cache_dir))


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict, str]:  # type: ignore[type-arg]
    code = main(list(argv))
    out, err = capsys.readouterr()
    data = json.loads(out) if "--json" in argv and out.strip() else {}
    return code, data, err


def test_show_json_keys(capsys: pytest.CaptureFixture[str]) -> None:
    code, d, _ = run(capsys, "workspace", "show", "--json")
    assert code == ExitCode.OK
    for key in ("nodes", "feasible", "singular", "colliding", "seconds", "cache", "region",
                "halfspaces"):
        assert key in d, key
    assert d["nodes"] == 46**3 and d["cache"]["hit"] is True
    R = Region.from_dict(d["region"])
    assert R.halfspaces == d["halfspaces"] <= 64
    assert R.contains(np.array(MVN_START))


def test_check(capsys: pytest.CaptureFixture[str]) -> None:
    code, d, _ = run(capsys, "workspace", "check", "--theta", *map(str, MVN_GOAL), "--json")
    assert code == ExitCode.OK
    assert d["feasible"] is True and d["in_region"] is False and d["plannable"] is True
    assert d["verdict"].startswith("feasible, outside P by ") and "grown around" in d["verdict"]
    assert "outside the region P" in d["reason"] and d["zeta"] == pytest.approx(0.29, abs=0.01)
    code, d, _ = run(capsys, "workspace", "check", "--theta", "150", "70", "70", "--json")
    assert code == ExitCode.INFEASIBLE and d["feasible"] is False and d["reason"]
    code, _, err = run(capsys, "workspace", "check", "--theta", "nan", "90", "90")
    assert code == ExitCode.BAD_INPUT and "finite" in err


def test_region_contain(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "region.json"
    code, d, _ = run(capsys, "workspace", "region", "--contain", *map(str, MVN_START),
                     *map(str, MVN_GOAL), "--out", str(out), "--json")
    assert code == ExitCode.OK and d["cached_region"] is False
    assert d["kind"] in ("grown", "refined")
    assert (d["resolution_deg"] is None) == (d["kind"] == "grown")
    R = Region.from_dict(json.loads(out.read_text()))
    assert R.contains(np.array([MVN_START, MVN_GOAL]), tol=1e-7).all()
    code, d, _ = run(capsys, "workspace", "region", "--contain", *map(str, MVN_START),
                     *map(str, MINTIME_START), "--json")
    assert code == ExitCode.OK and d["cached_region"] is True and d["kind"] == "P"
    code, _, err = run(capsys, "workspace", "region", "--contain", *map(str, MVN_START),
                       "150", "70", "70")
    assert code == ExitCode.INFEASIBLE and "leaves the feasible set" in err
    assert "Traceback" not in err


def test_verify_small(capsys: pytest.CaptureFixture[str]) -> None:
    code, d, _ = run(capsys, "workspace", "verify", "--samples", "3000", "--json")
    assert code == ExitCode.OK
    assert d["samples"] == 3000 and d["infeasible"] == 0 and d["fraction_infeasible"] == 0.0
    assert d["min_zeta"] >= 0.25 and d["min_link_distance_mm"] >= 28.0
    code, _, err = run(capsys, "workspace", "verify", "--samples", "0")
    assert code == ExitCode.BAD_INPUT and "--samples" in err


@pytest.mark.filterwarnings("error::RuntimeWarning")  # matplotlib's autoscale overflowed once
def test_show_plot(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    png = tmp_path / "ws.png"
    code, _, _ = run(capsys, "workspace", "show", "--plot", str(png))
    assert code == ExitCode.OK
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_build_after_corrupt_cache(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    (tmp_path / "workspace-agile_wrist-2deg.npz").write_bytes(b"junk")
    code, d, err = run(capsys, "workspace", "build", "--json", "--cache-dir", str(tmp_path))
    assert code == ExitCode.OK and d["cache"]["hit"] is False
    assert "corrupt or truncated" in d["cache"]["rebuilt_because"] and "workspace built in" in err
    assert d["feasible"] == agile_workspace().counts()["feasible"]
    assert d["halfspaces"] == agile_workspace().region.halfspaces
    code, d, _ = run(capsys, "workspace", "build", "--json", "--cache-dir", str(tmp_path))
    assert code == ExitCode.OK and d["cache"]["hit"] is True


def test_a_refined_region_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    """The paper's minimum-time pair passes 1.84° from a singular node: the region is grown
    on the grid refined 4× there, and the command says it, as the reference promises."""
    code = main(["workspace", "region", "--contain", "70", "90", "80", *map(str, MVN_GOAL)])
    out = capsys.readouterr().out
    assert code == ExitCode.OK
    assert "certified at the refined resolution h = 0.5°" in out
