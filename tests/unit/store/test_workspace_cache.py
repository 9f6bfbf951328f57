"""Workspace cache: hit, stale key, corrupt/truncated files, atomic writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from spm_console.config.models import link_model_of, model_of
from spm_console.errors import CacheError
from spm_console.store import workspace_cache as wc
from spm_console.store.workspace_cache import cache_key, cache_path, load_or_build
from tests.support.ws_helpers import agile_profile, coarse_workspace, with_step


@pytest.fixture()
def coarse(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """Builds return the prebuilt 5° workspace (counted), so tests stay fast."""
    prof = with_step(agile_profile(), 5.0)
    calls = []

    def fake_build(profile, progress=None, refined_cover=None):  # type: ignore[no-untyped-def]
        calls.append(profile)
        return coarse_workspace()

    monkeypatch.setattr(wc, "build_workspace", fake_build)
    return prof, calls

def _same(a, b) -> None:  # type: ignore[no-untyped-def]
    for name in ("zeta", "min_link_mm", "closest_pair", "R", "klass"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=name != "klass"
                              and name != "closest_pair")
    assert np.array_equal(a.region.A, b.region.A) and np.array_equal(a.region.b, b.region.b)
    assert a.home_index == b.home_index and a.counts() == b.counts()

def test_miss_then_hit(tmp_path: Path, coarse) -> None:  # type: ignore[no-untyped-def]
    prof, calls = coarse
    ws1, i1 = load_or_build(prof, tmp_path)
    assert not i1.hit and i1.rebuilt_because == "no cache file" and i1.path.is_file()
    ws2, i2 = load_or_build(prof, tmp_path)
    assert i2.hit and i2.rebuilt_because == "" and len(calls) == 1
    _same(ws1, ws2)
    assert ws2.model is model_of(prof) and ws2.links == link_model_of(prof)  # attached on load
    _, i3 = load_or_build(prof, tmp_path, force=True)
    assert not i3.hit and i3.rebuilt_because == "forced" and len(calls) == 2

def test_env_var_sets_the_directory(tmp_path: Path, coarse, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    prof, _ = coarse
    monkeypatch.setenv("SPM_CONSOLE_CACHE", str(tmp_path / "env"))
    _, info = load_or_build(prof)
    assert info.path.parent == tmp_path / "env" and info.path.is_file()

def test_key_depends_on_what_matters() -> None:
    base = agile_profile()
    k = cache_key(base)
    assert cache_key(with_step(base, 5.0)) != k
    ws = base.workspace.model_copy(update={"zeta_min": 0.3})
    assert cache_key(base.model_copy(update={"workspace": ws})) != k
    links = base.links.model_copy(update={"delta_mm": 12.0})
    assert cache_key(base.model_copy(update={"links": links})) != k
    servo = base.servo.model_copy(update={"p": 30.0})
    assert cache_key(base.model_copy(update={"servo": servo})) == k  # not a workspace input

def test_stale_key_rebuilds(tmp_path: Path, coarse) -> None:  # type: ignore[no-untyped-def]
    prof, calls = coarse
    load_or_build(prof, tmp_path)
    ws = prof.workspace.model_copy(update={"zeta_min": 0.3})
    changed = prof.model_copy(update={"workspace": ws})
    assert cache_path(changed, tmp_path) == cache_path(prof, tmp_path)  # same file name
    _, info = load_or_build(changed, tmp_path)
    assert not info.hit and info.rebuilt_because.startswith("stale key")
    assert wc.read_key(info.path) == cache_key(changed)
    assert len(calls) == 2

@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty", "flip"])
def test_corrupt_file_rebuilds_with_message(tmp_path: Path, coarse, damage: str) -> None:  # type: ignore[no-untyped-def]
    prof, calls = coarse
    _, info = load_or_build(prof, tmp_path)
    raw = info.path.read_bytes()
    if damage == "truncate":
        info.path.write_bytes(raw[: len(raw) // 2])
    elif damage == "garbage":
        info.path.write_bytes(b"not a zip file at all" * 10)
    elif damage == "empty":
        info.path.write_bytes(b"")
    else:  # flip bytes inside the R array: only the zip CRC can notice
        pos = raw.find(b"R.npy")
        assert pos > 0
        mid = bytearray(raw)
        for i in range(pos + 2000, pos + 2010):
            mid[i] ^= 0xFF
        info.path.write_bytes(bytes(mid))
    with pytest.raises(CacheError, match="corrupt"):
        wc.load(info.path, prof, cache_key(prof))
    _, info2 = load_or_build(prof, tmp_path)
    assert not info2.hit and "corrupt" in info2.rebuilt_because
    assert str(info.path) in info2.rebuilt_because
    assert len(calls) == 2
    _, info3 = load_or_build(prof, tmp_path)  # repaired
    assert info3.hit

def test_unwritable_directory_still_returns_a_workspace(tmp_path: Path, coarse) -> None:  # type: ignore[no-untyped-def]
    prof, _ = coarse
    blocker = tmp_path / "file"
    blocker.write_text("x")
    ws, info = load_or_build(prof, blocker / "sub")
    assert ws.counts()["nodes"] == 19**3
    assert "cannot write workspace cache" in info.write_error

_WRITER = """
import sys
from pathlib import Path
sys.path.insert(0, {root!r})
from tests.support.ws_helpers import coarse_workspace
from spm_console.store.workspace_cache import save
ws = coarse_workspace()
print("ready", flush=True)
while True:
    save(ws, Path({path!r}), "key")
"""

@pytest.mark.parametrize("edit", ["region", "klass", "klass_and_digest"])
def test_an_edited_cache_is_no_hit(tmp_path: Path, coarse, edit: str) -> None:  # type: ignore[no-untyped-def]
    """Arrays replaced in a cache file (the region widened to the servo box, colliding nodes
    marked feasible) are never used: the file is rebuilt with the reason."""
    import json

    import numpy as np

    from spm_console.core.workspace.data import NodeClass

    prof, _calls = coarse
    _, info = load_or_build(prof, tmp_path)
    with np.load(info.path) as z:
        d = {k: z[k] for k in z.files}
    meta = json.loads(str(d["meta"]))
    if edit == "region":
        d["region_A"] = np.vstack([np.eye(3), -np.eye(3)])
        d["region_b"] = np.array([160.0, 160.0, 160.0, -60.0, -60.0, -60.0])
    else:
        d["klass"] = np.where(d["klass"] == NodeClass.COLLIDING, NodeClass.FEASIBLE, d["klass"])
        if edit == "klass_and_digest":  # a forger who also recomputes the digest
            meta["content"] = wc.content_digest(d)
    d["meta"] = np.array(json.dumps(meta))
    with open(info.path, "wb") as f:
        np.savez(f, **d)
    why = "does not fit the profile" if edit == "klass_and_digest" else "modified after it was written"
    with pytest.raises(CacheError, match=why):
        wc.load(info.path, prof, cache_key(prof))
    _, info2 = load_or_build(prof, tmp_path)
    assert not info2.hit and why in info2.rebuilt_because

def test_another_grid_step_has_its_own_file(tmp_path: Path, coarse) -> None:  # type: ignore[no-untyped-def]
    from spm_console.config.load import with_grid_step
    from spm_console.errors import ProfileError

    prof, _calls = coarse
    finer = with_grid_step(prof, prof.workspace.step_deg / 2)
    assert finer.workspace.step_deg == prof.workspace.step_deg / 2
    assert cache_path(finer, tmp_path) != cache_path(prof, tmp_path)
    assert cache_key(finer) != cache_key(prof)
    with pytest.raises(ProfileError, match="step"):  # the range is no whole number of steps
        with_grid_step(prof, 0.7 * prof.workspace.step_deg)

def test_a_refined_cover_has_its_own_key_and_file(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    prof = with_step(agile_profile(), 5.0)
    assert cache_key(prof, refined_cover=True) != cache_key(prof)
    assert cache_path(prof, tmp_path, refined_cover=True) != cache_path(prof, tmp_path)
    asked: list[bool] = []

    def fake_build(profile, progress=None, refined_cover=None):  # type: ignore[no-untyped-def]
        asked.append(profile.workspace.refined_cover if refined_cover is None else refined_cover)
        return coarse_workspace()

    monkeypatch.setattr(wc, "build_workspace", fake_build)
    _, i1 = load_or_build(prof, tmp_path, refined_cover=True)
    assert not i1.hit and asked == [True] and i1.key == cache_key(prof, refined_cover=True)
    # the default workspace is not the refined file: built (and stored) on its own
    _, i2 = load_or_build(prof, tmp_path)
    assert not i2.hit and i2.rebuilt_because == "no cache file" and asked == [True, False]
    _, i3 = load_or_build(prof, tmp_path, refined_cover=True)
    assert i3.hit and len(asked) == 2
    # a refined file under the default name (copied by hand) is stale, never a hit
    cache_path(prof, tmp_path).write_bytes(i1.path.read_bytes())
    _, i4 = load_or_build(prof, tmp_path)
    assert not i4.hit and i4.rebuilt_because.startswith("stale key")

def test_the_profile_chooses_the_refined_cover_for_every_loader(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``workspace.refined_cover = true`` in a profile: every caller of load_or_build (the
    runtime, plan, the console) gets the refined workspace without passing the option;
    plan hashes do not depend on it (the runtime verifies against its own certified set)."""
    from spm_console.config.load import parse_profile
    from spm_console.store.plan_file import plan_hash

    prof = with_step(agile_profile(), 5.0)
    data = prof.model_dump(mode="json")
    data["workspace"] = {**data["workspace"], "refined_cover": True}
    refined = parse_profile(data, "test")
    asked: list[bool] = []

    def fake_build(profile, progress=None, refined_cover=None):  # type: ignore[no-untyped-def]
        # as models.build_workspace: by default what the profile asks for
        asked.append(profile.workspace.refined_cover if refined_cover is None else refined_cover)
        return coarse_workspace()

    monkeypatch.setattr(wc, "build_workspace", fake_build)
    _, info = load_or_build(refined, tmp_path)
    assert asked == [True] and info.path == cache_path(prof, tmp_path, refined_cover=True)
    _, info = load_or_build(refined, tmp_path, refined_cover=False)  # an explicit choice wins
    assert asked == [True, False] and info.path == cache_path(prof, tmp_path)
    assert plan_hash(refined) == plan_hash(prof)

def test_a_cover_of_p_alone_is_read_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A workspace whose cover is P alone (the coaxial profile's: P already covers 99 %)
    stores no cover rows; loading it was refused as corrupt and rebuilt every time."""
    from dataclasses import replace

    from spm_console.core.polytope.cover import RegionCover

    ws = coarse_workspace()
    alone = RegionCover(regions=(ws.region,), seeds_deg=np.zeros((1, 3)),
                        edges=np.zeros((0, 2), np.int64), edge_points_deg=np.zeros((0, 3)),
                        edge_radius_deg=np.zeros(0), min_overlap_deg=0.5, covered=0.995,
                        seconds=0.1)
    monkeypatch.setattr(wc, "build_workspace",
                        lambda profile, progress=None, refined_cover=None: replace(ws, cover=alone))
    prof = with_step(agile_profile(), 5.0)
    load_or_build(prof, tmp_path)
    ws2, info = load_or_build(prof, tmp_path)
    assert info.hit, info.rebuilt_because
    assert ws2.cover is not None and ws2.cover.size == 1 and len(ws2.cover.edges) == 0
