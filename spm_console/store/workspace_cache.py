"""On-disk cache of built workspaces: one ``.npz`` file per profile name and grid step.

The file stores a key (SHA-256 over everything the result depends on: geometry,
home, links, workspace grid and thresholds, algorithm constants, format version).
A different key means stale: rebuild and overwrite. A corrupt or truncated file
(zip CRC, missing arrays, wrong shapes) gives a clear message and is rebuilt; a file
of an older format is stale by its key (read before anything else). The region cover
(:mod:`spm_console.core.regions.cover`) is stored with the grid, P excluded (it is
``region_A``/``region_b``), under the same content digest: only its regions and graph (the
fine verdicts of its refinement are not stored; the runtime checks fine nodes itself).
Writes are atomic: a temporary file in the same directory, fsync, ``os.replace``; the file has
the umask's permissions (:func:`~spm_console.safe_io.atomic_temp`).

Default directory: ``$SPM_CONSOLE_CACHE`` if set, else ``~/.cache/spm_console``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.config.models import build_workspace, grid_axes_deg, link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.continuation import NEWTON_TOL, PATH_ZETA_FLOOR
from spm_console.core.polytope.cover import RegionCover
from spm_console.core.polytope.region import Region
from spm_console.core.regions import cover as core_cover
from spm_console.core.regions import p_build as region_build
from spm_console.core.regions.cover_grow import SEED_WINDOW
from spm_console.core.workspace import build as core_ws
from spm_console.core.workspace.check import STEP_RAD
from spm_console.core.workspace.data import Progress, Workspace
from spm_console.core.workspace.refine import REFINE, VERDICTS_VERSION
from spm_console.core.workspace_build import FORMAT_VERSION
from spm_console.errors import CacheError
from spm_console.safe_io import atomic_temp, check_path_names

ENV_VAR = "SPM_CONSOLE_CACHE"
_ARRAYS = ("axis0", "axis1", "axis2", "zeta", "min_link_mm", "closest_pair", "R", "klass",
           "region_A", "region_b", "cover_A", "cover_b", "cover_rows", "cover_seeds",
           "cover_edges", "cover_edge_points", "cover_edge_radius", "meta")
_DATA = _ARRAYS[:-1]


def content_digest(arrays: dict[str, Any]) -> str:
    """SHA-256 over every stored array (name, dtype, shape, bytes): an edited file is no hit."""
    h = hashlib.sha256()
    for name in _DATA:
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _consistent(ws: Workspace, profile: Profile) -> str:
    """Why the stored workspace cannot be this profile's (empty when it can): the grid
    axes are the profile's, and every node called feasible meets the stored thresholds."""
    want = grid_axes_deg(profile)
    if any(a.shape != w.shape or not np.allclose(a, w, atol=1e-9) for a, w in
           zip(ws.axes_deg, want, strict=True)):
        return "grid axes differ from the profile's"
    if not (math.isclose(ws.zeta_min, profile.workspace.zeta_min, abs_tol=1e-12)
            and math.isclose(ws.min_distance_mm, 2.0 * profile.links.delta_mm, abs_tol=1e-9)):
        return "thresholds (ζ_min, 2δ) differ from the profile's"
    f = ws.feasible
    with np.errstate(invalid="ignore"):
        if f.any() and not (bool((ws.zeta[f] >= ws.zeta_min).all())
                            and bool((ws.min_link_mm[f] >= ws.min_distance_mm).all())):
            return "nodes marked feasible break the stored thresholds"
    return ""


@dataclass(frozen=True)
class CacheInfo:
    """How a workspace was obtained."""

    path: Path
    """The cache file."""
    key: str
    """Cache key (hex SHA-256)."""
    hit: bool
    """True when loaded from the file without rebuilding."""
    rebuilt_because: str
    """Empty on a hit; otherwise why it was built ("no cache file", "stale key", "forced",
    or the corruption found)."""
    load_seconds: float
    """Time spent reading the file (0 if none was read), s."""
    build_seconds: float
    """Time spent building (0 on a hit), s."""
    write_error: str = ""
    """Why the rebuilt result could not be saved (empty if it was)."""


def default_cache_dir() -> Path:
    env = os.environ.get(ENV_VAR)
    return Path(env) if env else Path.home() / ".cache" / "spm_console"


def cache_key(profile: Profile, refined_cover: bool = False) -> str:
    """SHA-256 over the profile sections and constants the workspace depends on, and the build
    option ``refined_cover`` (a refined and a default cover never share a key)."""
    blob = json.dumps({
        "format": FORMAT_VERSION,
        "sections": profile.section_digest("geometry", "home", "links", "workspace"),
        "constants": {
            "path_zeta_floor": PATH_ZETA_FLOOR, "newton_tol": NEWTON_TOL,
            "connectivity": core_ws.CONNECTIVITY, "volume_tol": region_build.VOLUME_TOL,
            "max_iters": region_build.MAX_ITERS,
            "cover": [core_cover.COVER_TARGET, core_cover.COVER_MAX_REGIONS,
                      core_cover.COVER_HALFSPACES, core_cover.COVER_ITERS,
                      core_cover.MIN_OVERLAP_STEPS],
        },
        # the refined cover's own constants only in its key (the default key is unchanged)
        **({"refined_cover": [core_cover.REFINED_MAX_REGIONS, SEED_WINDOW, REFINE,
                              STEP_RAD, VERDICTS_VERSION]} if refined_cover else {}),
    }, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()


def cache_path(profile: Profile, cache_dir: Path | None = None,
               refined_cover: bool = False) -> Path:
    """One file per profile name, grid step and cover kind (a 1° workspace built for the
    paper's minimum-time pair does not evict the profile's own 2° one, nor a refined cover the
    default one); any other change rebuilds it."""
    d = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in profile.name)
    step = f"{float(profile.workspace.step_deg):g}".replace(".", "p")
    kind = "-refined" if refined_cover else ""
    return d / f"workspace-{safe}-{step}deg{kind}.npz"


def save(ws: Workspace, path: Path, key: str) -> None:
    """Write atomically (temp file + fsync + rename); raises CacheError on failure."""
    meta = {
        "key": key, "format": FORMAT_VERSION, "step_deg": ws.step_deg,
        "zeta_min": ws.zeta_min, "min_distance_mm": ws.min_distance_mm,
        "home_index": list(ws.home_index), "seconds": ws.seconds,
        "region_seconds": ws.region_seconds, "region_info": ws.region_info,
    }
    data: dict[str, np.ndarray] = {"axis0": ws.axes_deg[0], "axis1": ws.axes_deg[1], "axis2": ws.axes_deg[2],
            "zeta": ws.zeta, "min_link_mm": ws.min_link_mm, "closest_pair": ws.closest_pair,
            "R": ws.R, "klass": ws.klass, "region_A": ws.region.A, "region_b": ws.region.b}
    data.update(_cover_arrays(ws.cover))
    meta["cover"] = None if ws.cover is None else {
        "covered": ws.cover.covered, "min_overlap_deg": ws.cover.min_overlap_deg,
        "seconds": ws.cover.seconds, "resolution_deg": ws.cover.resolution_deg,
        "refined_cells": ws.cover.refined_cells, "fine_nodes": ws.cover.fine_nodes,
        "refine_seconds": ws.cover.refine_seconds}
    meta["content"] = content_digest(data)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = atomic_temp(path)
    except OSError as exc:
        raise CacheError(f"cannot write workspace cache {path}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, meta=np.array(json.dumps(meta)), **data)  # type: ignore[arg-type]
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        with contextlib.suppress(OSError):
            dfd = os.open(path.parent, os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise CacheError(f"cannot write workspace cache {path}: {exc.strerror or exc}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _cover_arrays(cover: RegionCover | None) -> dict[str, np.ndarray]:
    """The cover's arrays without P (regions[1:] stacked, with their row counts)."""
    rest = () if cover is None else cover.regions[1:]
    return {
        "cover_A": np.concatenate([np.zeros((0, 3)), *(r.A for r in rest)]),
        "cover_b": np.concatenate([np.zeros(0), *(r.b for r in rest)]),
        "cover_rows": np.array([r.halfspaces for r in rest], np.int64),
        "cover_seeds": np.zeros((0, 3)) if cover is None else cover.seeds_deg,
        "cover_edges": np.zeros((0, 2), np.int64) if cover is None else cover.edges,
        "cover_edge_points": np.zeros((0, 3)) if cover is None else cover.edge_points_deg,
        "cover_edge_radius": np.zeros(0) if cover is None else cover.edge_radius_deg,
    }


def _cover_of(d: dict[str, Any], p: Region, info: object) -> RegionCover | None:
    """The stored cover (None when none was stored); ValueError when inconsistent."""
    if info is None:
        return None
    if not isinstance(info, dict):
        raise ValueError("cover metadata is not an object")
    rows = np.asarray(d["cover_rows"], np.int64)
    A = np.asarray(d["cover_A"], float)
    b = np.asarray(d["cover_b"], float)
    if rows.ndim != 1 or (rows < 1).any() or int(rows.sum()) != len(A) or len(A) != len(b):
        raise ValueError("cover rows do not add up")
    cuts = np.cumsum(rows)[:-1]
    # (np.split of nothing gives one empty piece: a cover of P alone stores no rows)
    pieces = zip(np.split(A, cuts), np.split(b, cuts), strict=True) if len(rows) else ()
    regions = (p, *(Region.from_dict({"A": a, "b": c}) for a, c in pieces))
    k = len(regions)
    seeds = np.asarray(d["cover_seeds"], float)
    edges = np.asarray(d["cover_edges"], np.int64)
    pts = np.asarray(d["cover_edge_points"], float)
    rad = np.asarray(d["cover_edge_radius"], float)
    m = len(edges)
    if seeds.shape != (k, 3) or edges.shape != (m, 2) or pts.shape != (m, 3) or rad.shape != (m,):
        raise ValueError("cover arrays have inconsistent shapes")
    if m and not ((edges[:, 0] >= 0).all() and (edges[:, 0] < edges[:, 1]).all()
                  and (edges[:, 1] < k).all()):
        raise ValueError("cover edges name regions that do not exist")
    return RegionCover(
        regions=regions, seeds_deg=seeds, edges=edges, edge_points_deg=pts,
        edge_radius_deg=rad, min_overlap_deg=float(info["min_overlap_deg"]),
        covered=float(info["covered"]), seconds=float(info["seconds"]),
        resolution_deg=None if info.get("resolution_deg") is None
        else float(info["resolution_deg"]),
        refined_cells=int(info.get("refined_cells", 0)), fine_nodes=int(info.get("fine_nodes", 0)),
        refine_seconds=float(info.get("refine_seconds", 0.0)),
    )


def read_key(path: Path) -> str:
    """The key stored in a cache file (CacheError if unreadable)."""
    return str(_read(path, arrays=("meta",))["meta"]["key"])


def _read(path: Path, arrays: tuple[str, ...] = _ARRAYS) -> dict[str, Any]:
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [a for a in arrays if a not in z.files]
            if missing:
                raise CacheError(f"workspace cache {path} is corrupt: missing {', '.join(missing)}")
            out: dict[str, Any] = {a: z[a] for a in arrays}
        out["meta"] = json.loads(str(out["meta"]))
        return out
    except CacheError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, json.JSONDecodeError,
            UnicodeDecodeError) as exc:
        raise CacheError(f"workspace cache {path} is corrupt or truncated: "
                         f"{type(exc).__name__}: {exc}") from None


def load(path: Path, profile: Profile, key: str) -> Workspace:
    """Read a cache file; CacheError if corrupt, ``KeyError`` if its key differs,
    FileNotFoundError if there is none."""
    if not path.is_file():
        raise FileNotFoundError(str(path))
    head = _read(path, arrays=("meta",))["meta"]
    if not isinstance(head, dict) or head.get("key") != key:
        raise KeyError("stale key")  # an older format is stale, not corrupt
    d = _read(path)
    meta = d["meta"]
    if meta.get("key") != key:
        raise KeyError("stale key")
    if meta.get("content") != content_digest(d):
        raise CacheError(f"workspace cache {path} was modified after it was written "
                         "(content digest mismatch)")
    axes = (np.asarray(d["axis0"], float), np.asarray(d["axis1"], float),
            np.asarray(d["axis2"], float))
    shape = tuple(len(a) for a in axes)
    checks = {"zeta": shape, "min_link_mm": shape, "closest_pair": shape, "klass": shape,
              "R": (*shape, 3, 3)}
    for name, want in checks.items():
        if d[name].shape != want:
            raise CacheError(f"workspace cache {path} is corrupt: {name} has shape "
                             f"{d[name].shape}, expected {want}")
    try:
        region = Region.from_dict({"A": d["region_A"], "b": d["region_b"]})
        home = tuple(int(i) for i in meta["home_index"])
        ws = Workspace(
            axes_deg=axes, step_deg=float(meta["step_deg"]), zeta=d["zeta"],
            min_link_mm=d["min_link_mm"], closest_pair=d["closest_pair"], R=d["R"],
            klass=d["klass"], region=region, zeta_min=float(meta["zeta_min"]),
            min_distance_mm=float(meta["min_distance_mm"]),
            home_index=(home[0], home[1], home[2]), seconds=float(meta["seconds"]),
            region_seconds=float(meta["region_seconds"]),
            region_info={k: float(v) for k, v in meta["region_info"].items()},
            cover=_cover_of(d, region, meta["cover"]),
            model=model_of(profile), links=link_model_of(profile),
        )
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        raise CacheError(f"workspace cache {path} is corrupt: bad metadata ({exc})") from None
    why = _consistent(ws, profile)
    if why:
        raise CacheError(f"workspace cache {path} does not fit the profile: {why}")
    return ws


def load_or_build(
    profile: Profile, cache_dir: Path | str | None = None, force: bool = False,
    progress: Progress | None = None, refined_cover: bool | None = None,
) -> tuple[Workspace, CacheInfo]:
    """The profile's workspace from the cache, or built (and cached) when missing,
    stale, corrupt or ``force``. ``progress(stage, fraction)`` reports a build.
    ``refined_cover``: the workspace whose region cover is refined near the boundary
    (≥ 99 % of the feasible nodes, a slower build; its own cache file and key); by
    default the profile's ``workspace.refined_cover``."""
    if refined_cover is None:
        refined_cover = profile.workspace.refined_cover
    path = cache_path(profile, Path(cache_dir) if cache_dir is not None else None,
                      refined_cover)
    check_path_names(path, "workspace cache", CacheError)
    if path.parent.exists() and not path.parent.is_dir():
        raise CacheError(f"workspace cache folder {path.parent} is not a folder")
    key = cache_key(profile, refined_cover)
    why = "forced"
    load_s = 0.0
    if not force:
        t0 = time.perf_counter()
        try:
            ws = load(path, profile, key)
            load_s = time.perf_counter() - t0
            return ws, CacheInfo(path, key, True, "", load_s, 0.0)
        except FileNotFoundError:
            why = "no cache file"
        except KeyError:
            why = "stale key (profile or algorithm changed)"
        except CacheError as exc:
            why = exc.message
        load_s = time.perf_counter() - t0
    t1 = time.perf_counter()
    # the plain (profile, progress) call builds what the profile asks for
    ws = (build_workspace(profile, progress) if refined_cover == profile.workspace.refined_cover
          else build_workspace(profile, progress, refined_cover=refined_cover))
    build_s = time.perf_counter() - t1
    write_error = ""
    try:
        save(ws, path, key)
    except CacheError as exc:
        write_error = exc.message
    return ws, CacheInfo(path, key, False, why, load_s, build_s, write_error)
