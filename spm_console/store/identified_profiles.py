"""Identified profiles, kept beside the profile they were identified from.

Layout: the identification of ``profiles/agile_wrist.toml`` is written as
``profiles/agile_wrist.identified-2026-11-28T072800Z.toml`` — the same folder, the base
profile's name, then the UTC time of the fit (the ``date`` of its ``[servo.identified]``
section, colons dropped: the name sorts by time and is a valid file name everywhere). An
identification of an identified profile is named after the base profile again, so one
profile's identifications stay one family. The file holds the whole profile, its ``[servo]``
replaced and ``[servo.identified]`` naming the experiment's run folder (the provenance).

Nothing is ever overwritten: a name taken (two fits within a second) gets ``-2``, ``-3``, …
before ``.toml``, and the file appears whole or not at all (written beside, then hard-linked
into place, which fails rather than replace a file). Applying an identified model to the
profile itself (``identify --experiment --apply``) keeps the profile as it was in
``agile_wrist.toml.bak-2026-11-28T072800Z`` (not a ``.toml``: never listed as a profile).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import glob
import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from spm_console.errors import BadInputError

TAG = ".identified-"
"""Between the base profile's name and the time in an identified profile's file name."""
BACKUP_TAG = ".bak-"
"""Between a profile's file name and the time in its backup's."""
_NAME = re.compile(r"^(?P<base>.+?)\.identified-(?P<stamp>\d{4}-\d{2}-\d{2}T\d{6}Z)"
                   r"(?:-(?P<n>\d+))?\.toml$")
MAX_SAME_STAMP = 99
"""Most files one fit time may name (-2 … -99) before writing is refused."""


def stamp_of(date: str | dt.datetime) -> str:
    """The time in a file name: ``2026-11-28T072800Z`` for an ISO 8601 UTC date
    (``[servo.identified] date``) or a datetime (taken as UTC when it has no zone)."""
    when = date if isinstance(date, dt.datetime) else dt.datetime.fromisoformat(date)
    if when.tzinfo is not None:
        when = when.astimezone(dt.UTC)
    return when.strftime("%Y-%m-%dT%H%M%SZ")


def is_identified(path: Path) -> bool:
    """True for a file named as an identified profile."""
    return _NAME.match(path.name) is not None


def base_name(path: Path) -> str:
    """The base profile's name of a profile file: ``agile_wrist`` for ``agile_wrist.toml``
    and for ``agile_wrist.identified-….toml``."""
    m = _NAME.match(path.name)
    return m["base"] if m else path.stem


def newest_first_key(path: Path) -> tuple[str, int]:
    """Sort key (with ``reverse=True``: newest first) of an identified profile's file."""
    m = _NAME.match(path.name)
    return ("", 0) if m is None else (m["stamp"], int(m["n"] or 1))


def identified_path(profile_path: Path, date: str | dt.datetime) -> Path:
    """Where the identification of ``profile_path`` fitted at ``date`` goes (before a
    taken name's ``-2`` …)."""
    return profile_path.parent / f"{base_name(profile_path)}{TAG}{stamp_of(date)}.toml"


def family(profile_path: Path) -> list[Path]:
    """The base profile beside ``profile_path`` (when it exists) and every identified profile
    of it there, newest first."""
    folder, base = profile_path.parent, base_name(profile_path)
    plain = folder / f"{base}.toml"
    found = sorted((p for p in folder.glob(f"{glob.escape(base)}{TAG}*.toml")
                    if base_name(p) == base and is_identified(p)),
                   key=newest_first_key, reverse=True)
    return ([plain] if plain.is_file() else []) + found


def arrange(paths: Iterable[Path]) -> list[Path]:
    """Profile files as listed: in the order given, each base profile followed by its
    identified profiles of the same folder, newest first; identified profiles whose base is
    not among them at the end, newest first. A file given twice is listed once."""
    seen: set[Path] = set()
    plain: list[Path] = []
    found: list[Path] = []
    for p in paths:
        r = p.resolve()
        if r in seen:
            continue
        seen.add(r)
        (found if is_identified(p) else plain).append(p)
    found.sort(key=newest_first_key, reverse=True)
    out: list[Path] = []
    for p in plain:
        out.append(p)
        mine = [q for q in found if base_name(q) == p.stem
                and q.parent.resolve() == p.parent.resolve()]
        out += mine
        found = [q for q in found if q not in mine]
    return out + found


def _link_new(data: bytes, target: Path) -> bool:
    """Write ``data`` as ``target`` unless a file has that name (False then)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        try:
            os.link(tmp, target)  # fails when the name is taken: never replaces a file
        except FileExistsError:
            return False
        except OSError:  # a file system without hard links: create it exclusively
            try:
                with open(target, "xb") as fh:
                    fh.write(data)
            except FileExistsError:
                return False
        return True
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def write_new(path: Path, text: str | bytes) -> Path:
    """Write ``text`` (UTF-8) to ``path``, or, when that name is taken, to it with ``-2``,
    ``-3`` … (before ``.toml``, else at the end); never over a file. The path written, or BadInputError saying why
    nothing was."""
    data = text.encode("utf-8") if isinstance(text, str) else text
    for n in range(1, MAX_SAME_STAMP + 1):
        target = path if n == 1 else path.with_name(
            f"{path.stem}-{n}.toml" if path.suffix == ".toml" else f"{path.name}-{n}")
        try:
            if _link_new(data, target):
                return target
        except OSError as exc:
            raise BadInputError(f"cannot write {target}: {exc.strerror or exc}") from None
    raise BadInputError(f"{path}: {MAX_SAME_STAMP} files of that name and time exist already")


def write_beside(profile_path: Path, text: str, date: str | dt.datetime) -> Path:
    """The identified profile ``text`` written beside ``profile_path`` (the layout above)."""
    return write_new(identified_path(profile_path, date), text)


def apply_in_place(profile_path: Path, text: str, date: str | dt.datetime) -> Path:
    """Replace the profile with ``text``, its old content kept first as
    ``<name>.bak-<time>`` beside it (never over a file); the backup's path. The profile is
    replaced atomically (a file beside it, then a rename), so it is whole at every instant."""
    try:
        old = profile_path.read_bytes()
    except OSError as exc:
        raise BadInputError(f"cannot read {profile_path}: {exc.strerror or exc}") from None
    backup = write_new(profile_path.with_name(
        f"{profile_path.name}{BACKUP_TAG}{stamp_of(date)}"), old)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{profile_path.name}.", suffix=".tmp",
                                   dir=profile_path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)
                fh.flush()
                os.fsync(fh.fileno())
            with contextlib.suppress(OSError):
                os.chmod(tmp, profile_path.stat().st_mode & 0o7777)
            os.replace(tmp, profile_path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
    except OSError as exc:
        raise BadInputError(f"cannot replace {profile_path}: {exc.strerror or exc} (it is "
                            f"unchanged; its copy is {backup})") from None
    return backup


@dataclass(frozen=True)
class FitFigures:
    """What a profile's ``[servo]`` and ``[servo.identified]`` say of its fit."""

    date: str
    """When it was fitted (ISO 8601, UTC, as written)."""
    wn_radps: float
    zeta: float
    held_out_rms_deg: float | None
    delay_s: float | None = None

    def words(self) -> str:
        """e.g. ``identified 2026-11-28 07:28:00 UTC: ωn 43.10 rad/s, ζ 0.790, held-out
        RMS 0.041°``."""
        when = self.date.replace("T", " ").replace("Z", " UTC")
        parts = [f"ωn {self.wn_radps:.2f} rad/s", f"ζ {self.zeta:.3f}"]
        if self.delay_s is not None:
            parts.append(f"delay {1e3 * self.delay_s:.1f} ms")
        if self.held_out_rms_deg is not None:
            parts.append(f"held-out RMS {self.held_out_rms_deg:.3f}°")
        return f"identified {when}: " + ", ".join(parts)


def _finite(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def fit_figures(data: Mapping[str, Any]) -> FitFigures | None:
    """The fit figures of a profile's parsed TOML, None when its ``[servo]`` has no
    ``[servo.identified]`` section (or a malformed one: Apply's check says what is wrong)."""
    servo = data.get("servo")
    ident = servo.get("identified") if isinstance(servo, Mapping) else None
    if not isinstance(servo, Mapping) or not isinstance(ident, Mapping):
        return None
    date, wn = ident.get("date"), _finite(servo.get("p"))
    zeta = _finite(servo.get("zeta", 1.0))
    if not isinstance(date, str) or wn is None or zeta is None:
        return None
    return FitFigures(date[:64], wn, zeta, _finite(ident.get("held_out_rms_deg")),
                      _finite(servo.get("delay_s")))
