"""Sweep specs: designs from a grid or a Latin hypercube, and every refusal names its key
before anything is computed."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.design.spec import PARAMETERS, load_spec
from spm_console.errors import BadInputError, ExitCode
from tests.unit.design.conftest import GRID


def test_a_grid_spec_gives_every_combination_in_order(write_spec: Callable[..., Path]) -> None:
    spec = load_spec(write_spec(GRID))
    assert spec.names == ("alpha1_deg", "delta_mm") and spec.count == 6
    assert spec.params(0) == {"alpha1_deg": 80.0, "delta_mm": 12.0}
    assert spec.params(5) == {"alpha1_deg": 100.0, "delta_mm": 60.0}
    assert spec.base.workspace.step_deg == 10.0


def test_a_latin_hypercube_fills_each_range_once_per_stratum(write_spec: Callable[..., Path]) -> None:
    lhs = 'sampling = "lhs"\nsamples = 8\nseed = 3'
    ranges = "\n".join(line for line in GRID.splitlines() if not line.startswith("count"))
    spec = load_spec(write_spec(ranges, lhs))
    again = load_spec(write_spec(ranges, lhs, name="again.toml"))
    assert spec.count == 8 and np.array_equal(spec.values, again.values)  # the seed decides
    for j, (lo, hi) in enumerate(((80.0, 100.0), (12.0, 60.0))):
        strata = np.floor((spec.values[:, j] - lo) / (hi - lo) * 8).astype(int)
        assert sorted(strata.tolist()) == list(range(8))
    other = load_spec(write_spec(ranges, 'sampling = "lhs"\nsamples = 8\nseed = 4', name="o.toml"))
    with pytest.raises(BadInputError, match=r"parameters\.alpha1_deg\.count"):
        load_spec(write_spec(GRID, lhs, name="counted.toml"))  # counts are for a grid
    assert not np.array_equal(spec.values, other.values)
    assert spec.digest != other.digest


@pytest.mark.parametrize(("parameters", "sweep", "pairs", "names"), [
    ("[parameters.alpha1_deg]\nmin = 0.0\nmax = 90.0", "", "", "parameters.alpha1_deg.min"),
    ("[parameters.alpha1_deg]\nmin = 90.0\nmax = 180.0", "", "", "parameters.alpha1_deg.max"),
    ("[parameters.beta_deg]\nmin = 30.0\nmax = 90.0", "", "", "parameters.beta_deg.max"),
    ("[parameters.delta_mm]\nmin = -1.0\nmax = 9.0", "", "", "parameters.delta_mm.min"),
    ("[parameters.delta_mm]\nmin = 12.0\nmax = 9.0", "", "", "min 12 is above max 9"),
    ("[parameters.radius_mm]\nmin = 1.0\nmax = 2.0", "", "", "parameters.radius_mm"),
    ("[parameters.alpha1_deg]\nmin = 80.0\nmax = 90.0\ncount = 0", "", "", "count"),
    ("[parameters.alpha1_deg]\nmin = 80.0\nmax = nan", "", "", "max"),
    ("[parameters.alpha1_deg]\nmin = 80.0\nmax = true", "", "", "max"),
    (GRID, "max_nodes = 500", "", "sweep.max_nodes"),
    (GRID, 'sampling = "lhs"', "", "parameters.alpha1_deg.count"),
    ("[parameters.alpha1_deg]\nmin = 80.0\nmax = 90.0", 'sampling = "lhs"', "", "sweep.samples"),
    (GRID, "samples = 4", "", "sweep.samples"),
    ("[parameters.alpha1_deg]\nmin = 80.0\nmax = 90.0\ncount = true", "", "", "count"),
    (GRID, "step_deg = 7.0", "", "sweep.step_deg"),
    (GRID, "colour = 3", "", "colour"),
    (GRID, "", "[[pairs]]\nstart_deg = [100.0, 100.0, 100.0]\ngoal_deg = [160.0, 100.0, 100.0]",
     "pairs[0].goal_deg"),
    (GRID, "", "[[pairs]]\nstart_deg = [100.0, 100.0]\ngoal_deg = [100.0, 100.0, 100.0]", "start_deg"),
])
def test_a_bad_spec_is_refused_naming_the_key(write_spec: Callable[..., Path], parameters: str,
                                               sweep: str, pairs: str, names: str) -> None:
    with pytest.raises(BadInputError, match=names.replace("[", r"\[").replace(".", r"\.")):
        load_spec(write_spec(parameters, sweep, pairs))


def test_bounds_follow_the_profile_schema() -> None:
    from spm_console.design.spec import _bounds

    assert _bounds("alpha1_deg") == (0.0, False, 180.0, False)
    assert _bounds("gamma_deg") == (0.0, True, 90.0, False)
    assert _bounds("delta_mm")[:2] == (0.0, False)
    assert set(PARAMETERS) >= {"alpha2_deg", "beta_deg", "oa_mm", "of_mm"}


def test_too_many_designs_and_too_fine_a_grid_are_refused_before_any_work(
        write_spec: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    big = "[parameters.alpha1_deg]\nmin = 60.0\nmax = 120.0\ncount = 1000\n" \
          "[parameters.alpha2_deg]\nmin = 60.0\nmax = 120.0\ncount = 1000"
    out = tmp_path / "never"
    rc = main(["design", "sweep", str(write_spec(big)), "--out", str(out), "--json"])
    assert rc == ExitCode.BAD_INPUT and "1000000 designs" in capsys.readouterr().err
    rc = main(["design", "sweep", str(write_spec(GRID)), "--out", str(out), "--max-designs", "5"])
    assert rc == ExitCode.BAD_INPUT and "--max-designs" in capsys.readouterr().err
    fine = write_spec(GRID, "step_deg = 1.0")
    rc = main(["design", "sweep", str(fine), "--out", str(out)])
    assert rc == ExitCode.BAD_INPUT and "sweep.max_nodes" in capsys.readouterr().err
    odd = write_spec(GRID)
    odd.write_text(odd.read_text().replace("step_deg = 10.0", "step_deg = 7.0"))
    rc = main(["design", "sweep", str(odd), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == ExitCode.BAD_INPUT and "sweep.step_deg" in err, err
    assert not out.exists()  # refused before the folder was made


def test_a_spec_that_is_not_a_file_or_not_toml_is_refused(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "bad.toml").write_text("[sweep\n")
    for spec in (tmp_path, Path("/dev/zero"), tmp_path / "bad.toml", tmp_path / "missing.toml"):
        rc = main(["design", "sweep", str(spec), "--out", str(tmp_path / "o"), "--json"])
        assert rc == ExitCode.BAD_INPUT, spec
    capsys.readouterr()
