"""Run logs: one folder per run under ``logs/`` (or ``$SPM_CONSOLE_LOGS``).

A run folder holds

* ``meta.json`` — profile name, hash and wrist (:mod:`spm_console.motion.logs.profile_record`),
  plan summary, package versions, start
  time, the writing process (:mod:`spm_console.motion.logs.procid`), outcome; written at
  the start (outcome ``"running"``) and rewritten atomically at the end;
* ``samples.csv`` — one row per executor cycle, appended as the run goes and
  flushed to the OS every :data:`FLUSH_EVERY` rows, so a killed process (even by
  SIGKILL) leaves every row up to the last flush;
* ``events.jsonl`` — faults, retries, stops: one JSON object per line, flushed
  at once;
* ``run.mcap`` — the same as ROS 2 messages (:mod:`spm_console.motion.logs.mcap_log`),
  written from the files above once the run has finished (``on_finish``), and then
  ``metadata.yaml``, which makes the folder a rosbag2 bag (:mod:`spm_console.motion.logs.bag`).

Readers (:func:`load_run`, :func:`list_runs`) tolerate a truncated last line, and
report a run still marked ``running`` whose process is gone as ``killed``.
Angles in degrees, velocities in deg/s, times in seconds.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as dt
import errno
import json
import math
import os
import platform
import shutil
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from spm_console.errors import BadInputError, RunLogError
from spm_console.jsonutil import to_jsonable
from spm_console.motion.logs.procid import current_process, writer_alive
from spm_console.motion.logs.run_info import RunInfo, run_info
from spm_console.motion.sample import Sample
from spm_console.safe_io import MB, FileRefusedError, check_path_names, read_capped

F = NDArray[np.float64]

LOGS_ENV = "SPM_CONSOLE_LOGS"
"""Environment variable overriding the log root."""

FLUSH_EVERY = 3
"""Rows between two flushes of samples.csv to the OS: a SIGKILL loses at most the
FLUSH_EVERY − 1 rows written since the last flush (a flush costs a few µs, one
``write`` system call; no fsync — the OS keeps what it was given when the process dies)."""

PACKAGES = ("spm_console", "numpy", "scipy", "filterpy", "control", "pyserial", "osqp", "daqp")

_VEC = ("ref", "meas", "pred", "pred_vel", "filt", "vel", "fd_vel")
COLUMNS: tuple[str, ...] = (
    "t", "k", "phase",
    *(f"{name}{i}" for name in _VEC for i in (1, 2, 3)),
    "track_err", "bus_ms", "late_ms", "retries", "read_ms",
    "target1", "target2", "target3",
)
"""samples.csv header: ref = θ*, meas = θ, pred = model at k·Ts, filt / vel = Kalman θ̂ / θ̇̂
at the read instant, fd_vel = finite differences, track_err = max |θ − model at the read
instant|, read_ms = read instant after k·Ts, target = live following's target (empty for
planned motions)."""


#: Largest run-log files read, bytes (a 10-minute run at 50 Hz writes about 20 MB of samples).
MAX_META_BYTES = 64 * MB
MAX_SAMPLES_BYTES = 512 * MB
MAX_EVENTS_BYTES = 256 * MB

def logs_root(root: str | Path | None = None) -> Path:
    """The log root: ``root`` if given, else ``$SPM_CONSOLE_LOGS``, else ``logs/``."""
    if root is not None:
        return Path(root)
    return Path(os.environ.get(LOGS_ENV) or "logs")


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "absent"
    return out


#: Bytes a run's first ``meta.json`` takes on disk (its JSON, then spaces): room for the
#: outcome written over it in place when the disk is full by then.
META_ROOM = 16384


def _write_json_atomic(path: Path, data: dict[str, Any], room: int = 0) -> None:
    """Replace ``path`` with ``data`` as JSON (padded with spaces to ``room`` bytes); on a
    full disk, write it over the old file in place when it fits in the old file's size."""
    text = (json.dumps(to_jsonable(data), indent=2) + "\n").encode()
    text = text.ljust(room, b" ")
    tmp = path.with_suffix(".json.tmp")
    try:
        with tmp.open("wb") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if exc.errno != errno.ENOSPC or not _overwrite(path, text):
            raise


def _overwrite(path: Path, text: bytes) -> bool:
    """Write ``text`` over ``path``'s bytes, padded with spaces to its size (no new block
    needed), when it fits; whether it was written."""
    try:
        size = path.stat().st_size
        if len(text) > size:
            return False
        with path.open("r+b") as fh:
            fh.write(text.ljust(size, b" "))
            fh.flush()
            os.fsync(fh.fileno())
    except OSError:
        return False
    return True


def _fmt(x: float) -> str:
    return "" if not math.isfinite(x) else f"{x:.6g}"


class RunLog:
    """Writer of one run folder. Create with :meth:`create`; call :meth:`finish` at the end."""

    def __init__(self, path: Path, meta: dict[str, object], flush_every: int) -> None:
        self.path = path
        self.meta = meta
        self.flush_every = max(1, flush_every)
        self._samples: IO[str] = (path / "samples.csv").open("w", newline="")
        self._events: IO[str] = (path / "events.jsonl").open("w")
        self._csv = csv.writer(self._samples)
        self._csv.writerow(COLUMNS)
        self._samples.flush()
        self._pending = 0
        self.finished = False
        self.sample_count = 0
        self.event_count = 0
        self.write_error: str | None = None
        """Why a write failed (the rows and events after it are not in the files)."""
        self.on_finish: Callable[[Path], object] | None = None
        """Called with the run folder once :meth:`finish` has written everything (the MCAP
        beside the CSV); its failure is reported on stderr and changes nothing else."""

    @classmethod
    def create(
        cls,
        kind: str,
        profile_name: str,
        profile_hash: str,
        plans: Sequence[Mapping[str, object]],
        root: str | Path | None = None,
        flush_every: int = FLUSH_EVERY,
        extra: Mapping[str, object] | None = None,
        wrist: dict[str, str] | None = None,
    ) -> RunLog:
        """Make ``<root>/<YYYYmmdd-HHMMSS>-<kind>[-n]/`` and write the initial meta.json;
        ``wrist``: the digests of the profile's wrist sections
        (:func:`~spm_console.motion.logs.profile_record.wrist_digests`), recorded with its
        name and hash."""
        base = logs_root(root)
        try:
            base.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BadInputError(f"run log folder {base}: cannot create it ({exc.strerror or exc})") from None
        now = dt.datetime.now(dt.UTC)
        stem = f"{now.astimezone():%Y%m%d-%H%M%S}-{kind}"
        for n in range(1000):
            path = base / (stem if n == 0 else f"{stem}-{n}")
            try:
                path.mkdir()
                break
            except FileExistsError:
                continue
            except OSError as exc:  # an existing folder this process cannot write, a full disk
                raise BadInputError(f"run log folder {base}: cannot create a run folder in it "
                                    f"({exc.strerror or exc})") from None
        else:  # pragma: no cover - a thousand runs in one second
            raise BadInputError(f"{base}: cannot create a new run folder for {stem}")
        meta: dict[str, Any] = {
            "run": path.name,
            "kind": kind,
            "profile": {"name": profile_name, "hash": profile_hash,
                        **({"wrist": wrist} if wrist is not None else {})},
            "plans": plans,
            "versions": package_versions(),
            "argv": sys.argv,
            "pid": os.getpid(),
            "process": current_process(),
            "start_time": now.isoformat(),
            "end_time": None,
            "outcome": "running",
            "exit_code": None,
            "message": "",
            "stats": {},
            **(extra or {}),
        }
        try:
            log = cls(path, meta, flush_every)
            _write_json_atomic(path / "meta.json", meta, META_ROOM)
        except OSError as exc:  # (a full disk): no run folder is left half made
            shutil.rmtree(path, ignore_errors=True)
            raise BadInputError(f"run log folder {base}: cannot write a run's files in it "
                                f"({exc.strerror or exc})") from None
        return log

    def _failed(self, exc: OSError) -> RunLogError:
        """The first write that failed: later rows and events are dropped (they cannot be
        written), and the caller stops the run."""
        self.write_error = f"{exc.strerror or exc}"
        return RunLogError(f"the run log {self.path} cannot be written ({self.write_error}): "
                           "the run stopped, the wrist holds")

    def sample(self, s: Sample) -> None:
        """Append one row; flushed to the OS every ``flush_every`` rows. A row that cannot be
        written raises :class:`RunLogError` (once: later rows are dropped)."""
        if self.write_error is not None:
            return
        row: list[str] = [f"{s.t:.6f}", str(s.k), s.phase]
        for vec in (s.reference_deg, s.measured_deg, s.predicted_deg, s.predicted_velocity_degps,
                    s.filtered_deg, s.velocity_degps, s.fd_velocity_degps):
            row.extend(_fmt(float(x)) for x in vec)
        row += [_fmt(s.tracking_error_deg), _fmt(s.bus_s * 1e3), _fmt(s.late_s * 1e3),
                str(s.retries), _fmt(s.read_offset_s * 1e3)]
        row += (["", "", ""] if s.target_deg is None else [_fmt(float(x)) for x in s.target_deg])
        try:
            self._csv.writerow(row)
        except OSError as exc:
            raise self._failed(exc) from None
        self.sample_count += 1
        self._pending += 1
        if self._pending >= self.flush_every:
            self.flush()

    def event(self, name: str, t: float, /, **data: object) -> None:
        """Append one event line ``{"t", "event": name, **data}`` and flush it at once
        (:class:`RunLogError` as :meth:`sample`)."""
        if self.write_error is not None:
            return
        rec = {"t": round(t, 6), "event": name, **data}
        try:
            self._events.write(json.dumps(to_jsonable(rec)) + "\n")
            self._events.flush()
        except OSError as exc:
            raise self._failed(exc) from None
        self.event_count += 1

    def flush(self) -> None:
        if self.write_error is not None:
            return
        try:
            self._samples.flush()
        except OSError as exc:
            raise self._failed(exc) from None
        self._pending = 0

    def finish(self, outcome: str, exit_code: int, message: str, stats: Mapping[str, object]) -> None:
        """Flush everything and rewrite meta.json with the outcome (and ``log_write_error``
        when rows or events could not be written: they are missing from the files)."""
        with contextlib.suppress(RunLogError):
            self.flush()
        if self.write_error is not None:
            self.meta["log_write_error"] = self.write_error
        self.meta.update(
            end_time=dt.datetime.now(dt.UTC).isoformat(),
            outcome=outcome,
            exit_code=int(exit_code),
            message=message,
            stats=stats,
            samples=self.sample_count,
            events=self.event_count,
        )
        _write_json_atomic(self.path / "meta.json", self.meta)
        self.finished = True
        self.close()
        if self.on_finish is not None:
            try:
                self.on_finish(self.path)
            except Exception as exc:  # the run and its CSV stand; the companion file is extra
                sys.stderr.write(f"spm-console: {self.path}: {exc!r}\n")

    def close(self) -> None:
        for fh in (self._samples, self._events):
            with contextlib.suppress(OSError, ValueError):
                fh.flush()
                fh.close()


@dataclass(frozen=True)
class RunData:
    """A run read back from disk."""

    path: Path
    meta: dict[str, object]
    columns: dict[str, F]
    """Numeric columns by name (NaN for empty cells)."""
    phase: list[str]
    events: list[dict[str, object]]
    truncated: bool
    """True when a partial last line was dropped (the writer was killed mid-row)."""

    def vec(self, name: str) -> F:
        """(M, 3) array of a per-joint column family, e.g. ``vec('meas')``."""
        return np.stack([self.columns[f"{name}{i}"] for i in (1, 2, 3)], axis=1)

    @property
    def rows(self) -> int:
        return len(self.phase)

    @property
    def info(self) -> RunInfo:
        """Outcome, exit code, stop kind (also from the stop event), duration, plan."""
        return run_info(self.path.name, self.meta, self.events)


def resolve_run(run: str | Path, root: str | Path | None = None) -> Path:
    """A run folder from a path, a folder name under the log root, or 'last'."""
    base = logs_root(root)
    p = Path(run)
    check_path_names(base, "run log folder", BadInputError)
    check_path_names(p, "run", BadInputError)
    if str(run) == "last":
        runs = list_runs(root)
        if not runs:
            raise BadInputError(f"{base}: no runs logged yet")
        return runs[-1].path
    for cand in (p, base / p):
        if (cand / "meta.json").is_file() or (cand / "samples.csv").is_file():
            return cand
    raise BadInputError(f"no run '{run}' (looked for {p} and {base / p}); see `spm-console logs`")


def _read(path: Path, max_bytes: int) -> str:
    """A run-log file: a regular file (a FIFO or device is refused, never waited on) of at most
    ``max_bytes``, as text (FileRefusedError, UnicodeDecodeError)."""
    return read_capped(path, max_bytes).decode("utf-8")


def _read_meta(path: Path) -> dict[str, Any]:
    try:
        meta = json.loads(_read(path / "meta.json", MAX_META_BYTES))
    except (FileRefusedError, ValueError):
        return {"run": path.name, "outcome": "unreadable meta.json"}
    return with_liveness(meta) if isinstance(meta, dict) else {}


def with_liveness(meta: dict[str, object]) -> dict[str, object]:
    """``meta`` with outcome ``killed`` when it says ``running`` but its writer is gone
    (SIGKILL, power loss, crash); the file itself is left as it is."""
    if meta.get("outcome") != "running" or writer_alive(meta.get("process")) is not False:
        return meta
    proc = meta["process"]
    pid = proc.get("pid") if isinstance(proc, dict) else "?"  # a dict: writer_alive told
    msg = f"process {pid} ended without closing its log (rows up to its last flush kept)"
    return {**meta, "outcome": "killed", "message": meta.get("message") or msg}


def append_events(run_dir: Path, events: Sequence[Mapping[str, object]]) -> None:
    """Add events seen outside the servo loop to a finished run's ``events.jsonl`` (one line
    each, ``{"t", "event", …}``): the emulated wrist's leg contacts, told by its own process
    after the run."""
    if not events:
        return
    with (Path(run_dir) / "events.jsonl").open("a") as fh:
        for rec in events:
            fh.write(json.dumps(to_jsonable(rec)) + "\n")


def load_run(run: str | Path, root: str | Path | None = None) -> RunData:
    """Read meta, samples and events of a run; a partial last CSV/JSONL line is dropped."""
    path = resolve_run(run, root)
    meta = _read_meta(path)
    truncated = False
    try:
        text = _read(path / "samples.csv", MAX_SAMPLES_BYTES)
    except FileRefusedError as exc:
        raise BadInputError(f"{path}: samples.csv: {exc.reason}") from None
    except UnicodeDecodeError:
        raise BadInputError(f"{path}: samples.csv is not UTF-8 text") from None
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
        truncated = True
    rows = list(csv.reader(text.splitlines()))
    header = rows[0] if rows else list(COLUMNS)
    body = [r for r in rows[1:] if len(r) == len(header)]
    if rows and len(body) != len(rows) - 1:
        truncated = True
    cols: dict[str, F] = {}
    phase: list[str] = []
    for j, name in enumerate(header):
        if name == "phase":
            phase = [r[j] for r in body]
            continue
        try:
            cols[name] = np.array([float(r[j]) if r[j] else math.nan for r in body], float)
        except ValueError:
            raise BadInputError(f"{path}: samples.csv: column '{name}' holds a value that is not "
                                "a number") from None
    if not phase:
        phase = [""] * len(body)
    events: list[dict[str, Any]] = []
    with contextlib.suppress(FileRefusedError, UnicodeDecodeError):
        for line in _read(path / "events.jsonl", MAX_EVENTS_BYTES).splitlines():
            try:
                events.append(json.loads(line))
            except ValueError:
                truncated = True
    return RunData(path=path, meta=meta, columns=cols, phase=phase, events=events,
                   truncated=truncated)


@dataclass(frozen=True)
class RunSummary:
    path: Path
    meta: dict[str, object]

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def info(self) -> RunInfo:
        """Outcome, exit code, stop kind, duration, plan (from meta.json alone)."""
        return run_info(self.path.name, self.meta)


def list_runs(root: str | Path | None = None) -> list[RunSummary]:
    """Every run folder under the log root, oldest first: by folder name (the start time to
    the second), then by the start time in meta.json (runs started within one second, such as
    the homing and the execution of one ``execute``)."""
    base = logs_root(root)
    check_path_names(base, "run log folder", BadInputError)
    if base.exists() and not base.is_dir():
        raise BadInputError(f"run log folder {base} is not a folder")
    if not base.is_dir():
        return []
    out = []
    for p in sorted(base.iterdir()):
        if p.is_dir() and ((p / "meta.json").is_file() or (p / "samples.csv").is_file()):
            out.append(RunSummary(p, _read_meta(p)))
    out.sort(key=lambda r: (r.path.name[:15], str(r.meta.get("start_time") or ""), r.path.name))
    return out
