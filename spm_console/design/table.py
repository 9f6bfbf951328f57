"""A sweep's folder: what it is (``sweep.json``), its results as they finish (``rows.jsonl``,
one line per design, flushed to disk before the next) and its table (``results.parquet``,
one row per design, written from the journal whenever the sweep stops).

The journal is what makes a sweep resumable: a design is done when its line is there. A
line cut short by a kill is ignored (that design runs again). A folder holds one sweep: the
spec's digest in ``sweep.json`` must match, or the folder is refused.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from spm_console.design.evaluate import METRICS, DesignRow
from spm_console.design.spec import SweepSpec
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
        return SweepInfo(str(d["digest"]), str(d["spec"]), tuple(str(n) for n in d["names"]),
                         int(d["count"]), str(d["sampling"]), int(d.get("pairs", 0)))
    except FileRefusedError as exc:
        raise BadInputError(f"{folder}: not a sweep folder ({SWEEP_FILE}: {exc.reason})") from None
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        raise BadInputError(f"{path}: not a sweep record ({exc})") from None


def read_base_text(folder: Path) -> str:
    """The base profile's TOML kept in a sweep folder (as the sweep read it)."""
    path = folder / BASE_PROFILE
    try:
        return read_capped(path, MAX_SWEEP_FILE_BYTES).decode("utf-8")
    except FileRefusedError as exc:
        raise BadInputError(f"{path}: {exc.reason}") from None
    except UnicodeDecodeError:
        raise BadInputError(f"{path}: not UTF-8 text") from None


def open_folder(folder: Path, spec: SweepSpec) -> dict[int, DesignRow]:
    """Create ``folder`` for ``spec``, or reopen it: the designs already done (by index).
    BadInputError when it holds another sweep."""
    info = SweepInfo.of(spec)
    if (folder / SWEEP_FILE).exists():
        held = read_info(folder)
        if held.digest != info.digest:
            raise BadInputError(
                f"{folder} holds another sweep (spec {held.spec}, digest {held.digest[:12]}…; "
                f"this spec's is {info.digest[:12]}…): give another --out")
        return read_rows(folder, info.count)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"--out {folder}: {exc.strerror or exc}") from None
    write_text_atomic(folder / BASE_PROFILE, spec.base_text, BadInputError)
    write_text_atomic(folder / SWEEP_FILE, json.dumps(
        {"digest": info.digest, "spec": info.spec, "names": list(info.names),
         "count": info.count, "sampling": info.sampling, "pairs": info.pairs}, indent=1) + "\n",
        BadInputError)
    return {}


def read_rows(folder: Path, count: int) -> dict[int, DesignRow]:
    """The journal's rows by index (the last line of an index wins; a broken line is skipped)."""
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
        if 0 <= row.index < count:
            rows[row.index] = row
    return rows


class Journal:
    """Appends each finished design to ``rows.jsonl``, on disk before the next is taken."""

    def __init__(self, folder: Path) -> None:
        path = folder / JOURNAL
        try:
            self._f = open(path, "ab")  # noqa: SIM115 (closed by close())
        except OSError as exc:
            raise BadInputError(f"{path}: {exc.strerror or exc}") from None
        if self._f.tell() and not _ends_with_newline(path):
            self._f.write(b"\n")  # a line cut short by a kill stays apart from the next

    def append(self, row: DesignRow) -> None:
        self._f.write(json.dumps(row.to_json(), allow_nan=False).encode() + b"\n")
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
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
        cols[m] = [r.metrics.get(m, math.nan) for r in rows]
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
    table = pa.table(columns(info, ordered))
    table = table.replace_schema_metadata({"spm_console.sweep": json.dumps(
        {"digest": info.digest, "names": list(info.names), "count": info.count})})
    out = folder / TABLE
    tmp = folder / f".{TABLE}.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, out)
    return out


def load_table(folder: Path) -> tuple[SweepInfo, dict[str, list[Any]]]:
    """A sweep folder's table as columns (from ``results.parquet``, or from the journal when
    the table was not written yet)."""
    info = read_info(folder)
    path = folder / TABLE
    if path.exists():
        import pyarrow.lib
        import pyarrow.parquet as pq

        try:
            return info, pq.read_table(path).to_pydict()
        except (OSError, pyarrow.lib.ArrowException) as exc:
            raise BadInputError(f"{path}: not a readable Parquet table ({exc})") from None
    rows = read_rows(folder, info.count)
    return info, columns(info, [rows[k] for k in sorted(rows)])
