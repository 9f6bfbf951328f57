"""Workspaces built once per test process (the 46³ build takes ~2 s)."""

from __future__ import annotations

import fcntl
import functools
import shutil
from pathlib import Path

from spm_console.config.load import load_profile
from spm_console.config.models import build_workspace
from spm_console.config.schema import Profile
from spm_console.core.workspace.data import Workspace
from spm_console.store.workspace_cache import cache_path, default_cache_dir, load_or_build
from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT

#: The paper's configurations (deg).
MVN_START = (127.53, 83.23, 85.25)
MVN_GOAL = (66.80, 155.00, 131.48)
MINTIME_START = (70.0, 90.0, 80.0)


def agile_profile() -> Profile:
    return load_profile(ROOT / "profiles" / "agile_wrist.toml")


def with_step(profile: Profile, step_deg: float) -> Profile:
    """The profile with another grid spacing (a coarse grid keeps tests fast)."""
    ws = profile.workspace.model_copy(update={"step_deg": step_deg})
    return profile.model_copy(update={"workspace": ws})


def _built_once(profile: Profile, refined_cover: bool) -> Workspace:
    """The profile's workspace, built by whichever test process asks first and saved in the
    session's workspace cache (``SPM_CONSOLE_CACHE``, shared by the workers); the others wait
    for it and load that file (15 ms against 1–3 s for a build)."""
    folder = default_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / f".tests-{profile.name}-{refined_cover}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        ws, _ = load_or_build(profile, refined_cover=refined_cover)
    return ws


def cache_folder_holding(profile: Profile, folder: Path) -> Path:
    """``folder``, made, holding the profile's workspace cache file (default cover): a copy of
    the session's, built once by whichever process asks first (:func:`_built_once`), for tests
    whose commands need a cache folder of their own."""
    _built_once(profile, False)
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(cache_path(profile), cache_path(profile, folder))
    return folder


@functools.lru_cache(maxsize=1)
def agile_workspace() -> Workspace:
    """The Agile Wrist workspace on the profile's own 2° grid."""
    return _built_once(agile_profile(), False)


@functools.lru_cache(maxsize=1)
def coarse_workspace() -> Workspace:
    """The Agile Wrist on a 5° grid (19³ nodes), for cache and CLI tests."""
    return build_workspace(with_step(agile_profile(), 5.0))


@functools.lru_cache(maxsize=1)
def agile_workspace_refined() -> Workspace:
    """The Agile Wrist workspace on the 2° grid with the refined region cover (~2× the default build)."""
    return _built_once(agile_profile(), True)
