"""One design's evaluation, the folder's journal and table, ranking and a design's profile —
in this process (the sweep's own path with ``--workers 0``)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.load import load_profile
from spm_console.design.evaluate import DesignTask, evaluate
from spm_console.design.ranking import pareto
from spm_console.design.spec import load_spec
from spm_console.design.sweep import run_sweep
from spm_console.design.table import JOURNAL, load_table, read_info, read_rows
from spm_console.errors import BadInputError, ExitCode
from tests.support.ws_helpers import agile_profile, cache_folder_holding
from tests.unit.design.conftest import AGILE, GRID

PAIR = "[[pairs]]\nstart_deg = [105.0, 105.0, 105.0]\ngoal_deg = [135.0, 125.0, 115.0]"


def test_a_design_that_cannot_be_built_is_a_row_with_its_reason() -> None:
    text = AGILE.read_text()
    for params, why in (({"beta_deg": 30.0}, "home"), ({"delta_mm": 60.0}, "links collide")):
        row = evaluate(DesignTask(7, params, text, 10.0))
        assert not row.ok and why in row.reason and row.index == 7
        assert row.metrics is None and math.isnan(row.figure("zeta_mean")) and not row.retry
    row = evaluate(DesignTask(0, {"alpha1_deg": 85.0}, text, 10.0,
                                 (((105.0, 105.0, 105.0), (135.0, 125.0, 115.0)),
                                  ((65.0, 65.0, 65.0), (155.0, 155.0, 155.0)))))
    assert row.ok and row.metrics is not None and row.metrics.feasible_nodes > 0
    assert len(row.sign_seed) == 9
    assert row.pairs_planned == 1 and row.pair_times_s[0] > 0 and row.pair_reasons[1]


def test_the_sweep_folder_resumes_and_its_table_holds_one_row_per_design(
        write_spec: Callable[..., Path], tmp_path: Path) -> None:
    spec = load_spec(write_spec(GRID, pairs=PAIR))
    out = tmp_path / "sweep"
    first = run_sweep(spec, out, workers=0)
    assert first.computed == 6 and first.failed == 3  # δ = 60 mm: the legs' capsules collide
    info, cols = load_table(out)
    assert cols["index"] == list(range(6)) and info.names == ("alpha1_deg", "delta_mm")
    assert all(r for r, ok in zip(cols["reason"], cols["ok"], strict=True) if not ok)
    # a journal cut short by a kill: that design runs again, nothing else
    lines = (out / JOURNAL).read_bytes().splitlines(keepends=True)
    (out / JOURNAL).write_bytes(b"".join(lines[:4]) + lines[4][:40])
    assert sorted(read_rows(out, read_info(out))) == [0, 1, 2, 3]
    again = run_sweep(spec, out, workers=0)
    assert (again.resumed, again.computed) == (4, 2)
    _, cols2 = load_table(out)
    same = [c for c in cols if c not in ("seconds", "worker")]
    assert repr({c: cols[c] for c in same}) == repr({c: cols2[c] for c in same})  # NaN too
    # another spec into the same folder is refused
    other = load_spec(write_spec(GRID.replace("count = 3", "count = 2"), name="other.toml"))
    with pytest.raises(BadInputError, match="holds another sweep"):
        run_sweep(other, out, workers=0)


def test_a_design_that_meets_a_bug_is_a_row_the_next_run_computes_again(
        write_spec: Callable[..., Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import spm_console.design.evaluate as ev

    real = ev.workspace_metrics

    def broken(ws):  # type: ignore[no-untyped-def]
        raise ZeroDivisionError("a bug")

    spec = load_spec(write_spec(GRID))
    monkeypatch.setattr(ev, "workspace_metrics", broken)
    first = run_sweep(spec, tmp_path / "s", workers=0)
    assert first.internal_errors == 3 and first.failed == 6  # 3 bugs, 3 colliding homes
    _, cols = load_table(tmp_path / "s")
    assert sum(r.startswith("internal error: ZeroDivisionError") for r in cols["reason"]) == 3
    monkeypatch.setattr(ev, "workspace_metrics", real)
    again = run_sweep(spec, tmp_path / "s", workers=0)
    assert (again.resumed, again.computed, again.internal_errors) == (3, 3, 0)


def test_a_region_too_thin_for_qhull_keeps_its_rows_and_has_no_volume() -> None:
    from spm_console.core.polytope.region import Region

    box = Region.box(100.0, 140.0)
    thin = Region(np.vstack([box.A, [[1.0, 1.0, 0.0], [-1.0, -1.0, 0.0]]]),
                  np.r_[box.b, 280.0 + 2e-13, -280.0 + 2e-13])  # θ1 + θ2 = 280 within 1e-13
    assert thin.facet_rows() == list(range(8)) and thin.volume() == 0.0
    assert box.volume() == pytest.approx(40.0 ** 3)


def test_a_design_whose_region_qhull_cannot_cut_is_a_row_with_a_reason() -> None:
    """Found by probing: IRIS met a region thinner than qhull's precision (QH6023 "feasible
    point is not clearly inside halfspace") and the design stopped its sweep."""
    params = {"alpha1_deg": 68.73475376588952, "alpha2_deg": 31.91030678123554,
              "beta_deg": 62.81832542200899, "gamma_deg": 32.17921267203597,
              "oa_mm": 203.00629448980445, "od_mm": 484.17746653874383,
              "delta_mm": 1.3054761817674743}
    row = evaluate(DesignTask(8, params, AGILE.read_text(), 15.0))
    assert not row.retry and (row.ok or "QH6023" not in row.reason), row.reason


def test_the_pareto_front_is_what_no_design_beats_on_both() -> None:
    rng = np.random.default_rng(2)
    x, y = rng.uniform(0, 1, 60), rng.uniform(0, 1, 60)
    cols = {"index": list(range(60)), "ok": [True] * 60, "tilt_cone_deg": x.tolist(),
            "seconds": y.tolist()}  # more tilt is better, fewer seconds are better
    front = set(pareto(cols, "tilt_cone_deg", "seconds").tolist())
    brute = {i for i in range(60)
             if not any(x[j] >= x[i] and y[j] <= y[i] and (x[j] > x[i] or y[j] < y[i])
                        for j in range(60))}
    assert front == brute and front


def test_show_and_profile_of_a_sweep(write_spec: Callable[..., Path], tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sweep"
    assert main(["design", "sweep", str(write_spec(GRID)), "--out", str(out), "--workers", "0",
                 "--json"]) == 0
    done = json.loads(capsys.readouterr().out)
    assert done["designs"] == 6 and done["failed"] == 3
    plot = tmp_path / "pareto.png"
    assert main(["design", "show", str(out), "--top", "2", "--pareto", "zeta_mean",
                 "feasible_fraction", "--plot", str(plot), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert plot.stat().st_size > 10_000 and shown["built"] == 3
    best = shown["best"]["feasible_fraction"]
    assert len(best) == 2 and best[0]["value"] >= best[1]["value"]
    k = best[0]["index"]
    new = tmp_path / "design.toml"
    assert main(["design", "profile", str(out), str(k), "--out", str(new), "--json"]) == 0
    capsys.readouterr()
    prof = load_profile(new)  # complete and valid
    assert prof.geometry.alpha1_deg == best[0]["params"]["alpha1_deg"]
    assert prof.links.delta_mm == best[0]["params"]["delta_mm"]
    assert prof.workspace == load_profile(AGILE).workspace  # the base's own grid
    assert f"design {k} of" in new.read_text()
    failed = next(i for i in range(6) if i not in [d["index"] for d in best] and i % 2 == 1)
    for args, code in ((["profile", str(out), str(failed), "--out", str(new), "--force"],
                        ExitCode.BAD_INPUT),
                       (["profile", str(out), "99", "--out", str(new), "--force"], ExitCode.BAD_INPUT),
                       (["show", str(out), "--metric", "beauty"], ExitCode.BAD_INPUT),
                       (["show", str(tmp_path)], ExitCode.BAD_INPUT),
                       (["show", str(out), "--top", "0"], ExitCode.BAD_INPUT)):
        assert main(["design", *args, "--json"]) == code, args
        assert json.loads(capsys.readouterr().out)["ok"] is False


def test_the_agile_wrist_design_has_the_figures_workspace_build_reports(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The base design itself (α1 = 90° on the profile's 2° grid), swept, against ``workspace
    build`` of the default profile."""
    spec = tmp_path / "one.toml"
    spec.write_text(f'[sweep]\nbase_profile = "{AGILE}"\n'
                    "[parameters.alpha1_deg]\nmin = 90.0\nmax = 90.0\n")
    assert main(["design", "sweep", str(spec), "--out", str(tmp_path / "s"), "--workers", "0"]) == 0
    capsys.readouterr()
    # the build's figures as the command reports them, from the session's cache of that build
    cache = cache_folder_holding(agile_profile(), tmp_path / "cache")
    assert main(["workspace", "build", "--profile", str(AGILE), "--cache-dir", str(cache),
                 "--json"]) == 0
    ws = json.loads(capsys.readouterr().out)
    _, cols = load_table(tmp_path / "s")
    assert cols["ok"] == [True]
    assert cols["nodes"][0] == ws["nodes"] and cols["feasible_nodes"][0] == ws["feasible"]
    assert cols["feasible_fraction"][0] == pytest.approx(ws["feasible"] / ws["nodes"])
    assert cols["p_halfspaces"][0] == ws["halfspaces"]
    assert cols["p_coverage"][0] == pytest.approx(ws["coverage"])
    assert cols["feasible_volume_deg3"][0] == ws["feasible"] * ws["grid"]["step_deg"] ** 3
    from spm_console.core.polytope.region import Region

    assert cols["p_volume_deg3"][0] == pytest.approx(Region.from_dict(ws["region"]).volume())
    assert cols["zeta_min"][0] >= ws["grid"]["zeta_min"] and cols["clearance_min_mm"][0] >= 0.0
