"""A sweep's folder: what it is (``sweep.json``), its results as they finish (``rows.jsonl``,
one line per design, flushed to disk before the next) and its table (``results.parquet``,
one row per design, written from the journal whenever the sweep stops).

The journal is what makes a sweep resumable: a design is done when its line is there. A
line cut short by a kill is ignored (that design runs again). A folder holds one sweep: the
spec's digest in ``sweep.json`` must match, or the folder is refused.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from spm_console.design.evaluate import INT_FIGURES, METRICS, DesignRow
from spm_console.design.spec import HARD_MAX_DESIGNS, MAX_PAIRS, PARAMETERS, SweepSpec
from spm_console.errors import BadInputError
from spm_console.safe_io import MB, FileRefusedError, read_capped, write_text_atomic

SWEEP_FILE = "sweep.json"
BASE_PROFILE = "base_profile.toml"
JOURNAL = "rows.jsonl"
TABLE = "results.parquet"
#: Largest journal line read back (a row is under 2 kB).
MAX_LINE_BYTES = 64 * 1024
#: Largest sweep.json read back.
MAX_SWEEP_FILE_BYTES = MB


@dataclass(frozen=True)
class SweepInfo:
    """What ``sweep.json`` records."""

    digest: str
    spec: str
    names: tuple[str, ...]
    count: int
    sampling: str
    pairs: int

    @classmethod
    def of(cls, spec: SweepSpec) -> SweepInfo:
        return cls(spec.digest, spec.source, spec.names, spec.count, spec.sampling, len(spec.pairs))


def read_info(folder: Path) -> SweepInfo:
    """The sweep a folder holds (BadInputError when it holds none)."""
    path = folder / SWEEP_FILE
    try:
        d = json.loads(read_capped(path, MAX_SWEEP_FILE_BYTES))
        info = SweepInfo(d["digest"], d["spec"], tuple(d["names"]), d["count"], d["sampling"],
                         d.get("pairs", 0))
    except FileRefusedError as exc:
        raise BadInputError(f"{folder}: not a sweep folder ({SWEEP_FILE}: {exc.reason})") from None
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        raise BadInputError(f"{path}: not a sweep record ({exc})") from None
    problem = _info_problem(info)
    if problem:
        raise BadInputError(f"{path}: not a sweep record ({problem})")
    return info


def _whole(v: object, lo: int, hi: int) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi


def _info_problem(info: SweepInfo) -> str:
    """What is wrong with a read ``sweep.json`` ("" when nothing)."""
    if not (isinstance(info.digest, str) and re.fullmatch(r"[0-9a-f]{64}", info.digest)):
        return "digest: not a SHA-256"
    if not isinstance(info.spec, str):
        return "spec: not a path"
    if not (info.names and len(set(info.names)) == len(info.names)
            and all(isinstance(n, str) and n in PARAMETERS for n in info.names)):
        return f"names: not distinct sweep parameters ({', '.join(PARAMETERS)})"
    if not _whole(info.count, 1, HARD_MAX_DESIGNS):
        return f"count: not a whole number within 1..{HARD_MAX_DESIGNS}"
    if info.sampling not in ("grid", "lhs"):
        return "sampling: neither grid nor lhs"
    if not _whole(info.pairs, 0, MAX_PAIRS):
        return f"pairs: not a whole number within 0..{MAX_PAIRS}"
    return ""


def read_base_text(folder: Path) -> str:
    """The base profile's TOML kept in a sweep folder (as the sweep read it)."""
    path = folder / BASE_PROFILE
    try:
        return read_capped(path, MAX_SWEEP_FILE_BYTES).decode("utf-8")
    except FileRefusedError as exc:
        raise BadInputError(f"{path}: {exc.reason}") from None
    except UnicodeDecodeError:
        raise BadInputError(f"{path}: not UTF-8 text") from None


def read_done(folder: Path, spec: SweepSpec) -> dict[int, DesignRow]:
    """The designs of ``spec`` already done in ``folder`` (none when it does not exist yet).
    BadInputError when the folder holds another sweep, or its table's path is not a file."""
    if not (folder / SWEEP_FILE).exists():
        return {}
    held = read_info(folder)
    if held.digest != spec.digest:
        raise BadInputError(
            f"{folder} holds another sweep (spec {held.spec}, digest {held.digest[:12]}…; "
            f"this spec's is {spec.digest[:12]}…): give another --out")
    table = folder / TABLE
    if table.exists() and not table.is_file():
        raise BadInputError(f"{table}: not a file (the sweep writes its table there)")
    rows = read_rows(folder, held)
    # a row is this spec's design only with this spec's values, and done unless it met a bug
    # or a killed worker (else it is computed again)
    return {k: r for k, r in rows.items() if r.params == spec.params(k) and not r.retry}


def create_folder(folder: Path, spec: SweepSpec) -> None:
    """Make ``folder`` hold ``spec``'s sweep (kept as it is when it does; the base profile's
    copy is written again if it was removed)."""
    info = SweepInfo.of(spec)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"--out {folder}: {exc.strerror or exc}") from None
    if not (folder / BASE_PROFILE).is_file():
        write_text_atomic(folder / BASE_PROFILE, spec.base_text, BadInputError)
    if not (folder / SWEEP_FILE).exists():
        write_text_atomic(folder / SWEEP_FILE, json.dumps(
            {"digest": info.digest, "spec": info.spec, "names": list(info.names),
             "count": info.count, "sampling": info.sampling, "pairs": info.pairs},
            indent=1) + "\n", BadInputError)


def valid_row(row: DesignRow, info: SweepInfo) -> bool:
    """A journal row of this sweep: its index, parameters, figures and pairs as written."""
    finite = all(isinstance(v, float) and math.isfinite(v) for v in row.params.values())
    return (0 <= row.index < info.count and set(row.params) == set(info.names) and finite
            and row.ok == (row.metrics is not None) and (row.ok or bool(row.reason))
            and len(row.pair_times_s) == len(row.pair_reasons) == (info.pairs if row.ok else 0))


def read_rows(folder: Path, info: SweepInfo) -> dict[int, DesignRow]:
    """The journal's valid rows by index (the last line of an index wins; a line cut short
    by a kill, or one that is not a row of this sweep, is skipped: that design runs again)."""
    count = info.count
    path = folder / JOURNAL
    rows: dict[int, DesignRow] = {}
    if not path.exists():
        return rows
    try:
        data = read_capped(path, max(count, 1) * 4 * MAX_LINE_BYTES)
    except FileRefusedError as exc:
        raise BadInputError(f"{path}: {exc.reason}") from None
    for line in data.splitlines():
        if len(line) > MAX_LINE_BYTES:
            continue
        try:
            row = DesignRow.from_json(json.loads(line))
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError):
            continue  # cut short by a kill: that design runs again
        if valid_row(row, info):
            rows[row.index] = row
    return rows


class Journal:
    """Appends each finished design to ``rows.jsonl``, on disk before the next is taken.
    A write that fails (a full disk) is a BadInputError naming the file."""

    def __init__(self, folder: Path) -> None:
        self.path = folder / JOURNAL
        try:
            self._f = open(self.path, "ab")  # noqa: SIM115 (closed by close())
            if self._f.tell() and not _ends_with_newline(self.path):
                self._f.write(b"\n")  # a line cut short by a kill stays apart from the next
        except OSError as exc:
            raise BadInputError(f"{self.path}: {exc.strerror or exc}") from None

    def append(self, row: DesignRow) -> None:
        try:
            self._f.write(json.dumps(row.to_json(), allow_nan=False).encode() + b"\n")
            self._f.flush()
            os.fsync(self._f.fileno())
        except OSError as exc:
            raise BadInputError(f"{self.path}: cannot write design {row.index}'s row "
                                f"({exc.strerror or exc})") from None

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._f.close()


def _ends_with_newline(path: Path) -> bool:
    with open(path, "rb") as f:
        f.seek(-1, os.SEEK_END)
        return f.read(1) == b"\n"


def columns(info: SweepInfo, rows: list[DesignRow]) -> dict[str, list[Any]]:
    """The table's columns: index, the parameters, ok/reason, the figures of merit, the
    pairs planned and their times, and the cost (seconds, worker)."""
    cols: dict[str, list[Any]] = {"index": [r.index for r in rows]}
    for n in info.names:
        cols[n] = [r.params.get(n, math.nan) for r in rows]
    cols["ok"] = [r.ok for r in rows]
    cols["reason"] = [r.reason for r in rows]
    for m in METRICS:
        cols[m] = [None if r.metrics is None else
                   (getattr(r.metrics, m) if m in INT_FIGURES else r.figure(m)) for r in rows]
    cols["pairs_planned"] = [r.pairs_planned for r in rows]
    cols["pair_times_s"] = [list(r.pair_times_s) for r in rows]
    cols["seconds"] = [r.seconds for r in rows]
    cols["worker"] = [r.worker for r in rows]
    return cols


def write_table(folder: Path, info: SweepInfo, rows: dict[int, DesignRow]) -> Path:
    """``results.parquet`` from the rows (sorted by index), replaced atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    ordered = [rows[k] for k in sorted(rows)]
    cols = columns(info, ordered)
    types = {"index": pa.int64(), "ok": pa.bool_(), "reason": pa.string(),
             "pairs_planned": pa.int64(), "pair_times_s": pa.list_(pa.float64()),
             "seconds": pa.float64(), "worker": pa.string(),
             **{m: pa.int64() if m in INT_FIGURES else pa.float64() for m in METRICS}}
    schema = pa.schema([(c, types.get(c, pa.float64())) for c in cols])
    table = pa.table(cols, schema=schema)
    table = table.replace_schema_metadata({"spm_console.sweep": json.dumps(
        {"digest": info.digest, "names": list(info.names), "count": info.count})})
    out = folder / TABLE
    tmp = folder / f".{TABLE}.tmp"
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, out)
    except OSError as exc:
        raise BadInputError(f"{out}: cannot write the table ({exc.strerror or exc}); the "
                            f"designs are kept in {folder / JOURNAL}") from None
    return out


def load_table(folder: Path) -> tuple[SweepInfo, dict[str, list[Any]]]:
    """A sweep folder's table as columns, from its journal (what is done, even when the sweep
    was killed before it wrote ``results.parquet``)."""
    info = read_info(folder)
    rows = read_rows(folder, info)
    return info, columns(info, [rows[k] for k in sorted(rows)])
