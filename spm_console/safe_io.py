"""Bounded reading of operator-supplied files (profile, plan, region, CSV, script).

Every file an operator names must be a regular file, opened without blocking (a FIFO,
a device such as ``/dev/zero``, a socket or a directory is refused at once, never waited
on), and is read with a size cap (a larger file is refused after ``max_bytes`` + 1 bytes,
never read whole), decoded
as UTF-8 (a binary file is refused as such) and, for JSON, parsed with a nesting cap.
Failures raise the caller's :class:`~spm_console.errors.SpmError` subclass with a
message naming the file and what was wrong — never a traceback. Files the commands write
are replaced atomically (:func:`write_text_atomic`, :func:`atomic_temp`), with the permissions
the umask gives any new file (``tempfile.mkstemp``'s are 0600 whatever the umask).
"""

from __future__ import annotations

import json
import os
import secrets
import stat
import sys
import tomllib
from pathlib import Path
from typing import Any

from spm_console.errors import SpmError

MB = 1024 * 1024
#: Deepest nesting accepted in a JSON file (a valid plan needs 5 levels).
MAX_JSON_DEPTH = 32
#: Longest name of one folder or file, bytes, where the file system does not say (Linux's
#: NAME_MAX), and longest path (PATH_MAX, with its terminating NUL).
NAME_MAX = 255
PATH_MAX = 4096
#: Bytes of a file's name its temporary (``.NAME.xxxxxxxx`` beside it) keeps: a name up to
#: NAME_MAX long still leaves room for the temporary's.
TEMP_NAME_BYTES = 64


def _mb(n: int) -> str:
    if n >= MB:
        return f"{n / MB:g} MB"
    return f"{n / 1024:g} kB" if n >= 1024 else f"{n} bytes"


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


class FileRefusedError(Exception):
    """A file that cannot be read as asked: ``reason`` says why (no path in it)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _read_fd(fd: int, n: int) -> bytes:
    """Up to ``n`` bytes of ``fd`` (fewer only at its end)."""
    parts: list[bytes] = []
    while n > 0 and (chunk := os.read(fd, min(n, MB))):
        parts.append(chunk)
        n -= len(chunk)
    return b"".join(parts)


def read_capped(path: str | Path, max_bytes: int) -> bytes:
    """At most ``max_bytes`` of the regular file ``path``; anything else (FIFO, device,
    directory, socket) is refused without waiting on it, a larger file without reading it
    whole (:class:`FileRefusedError`)."""
    try:  # O_NONBLOCK: opening a FIFO with no writer would otherwise wait for one for ever
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except OSError as exc:
        raise FileRefusedError(f"cannot read: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise FileRefusedError(f"{_kind(st.st_mode)}, not a regular file: refused")
        data = b"" if st.st_size > max_bytes else _read_fd(fd, max_bytes + 1)
    except OSError as exc:
        raise FileRefusedError(f"cannot read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if st.st_size > max_bytes or len(data) > max_bytes:
        raise FileRefusedError(f"larger than the {_mb(max_bytes)} limit for this kind of file")
    return data


def read_bytes(path: str | Path, what: str, max_bytes: int, error: type[SpmError]) -> bytes:
    """:func:`read_capped`, its refusal raised as ``error`` naming ``what`` and the file."""
    try:
        return read_capped(path, max_bytes)
    except FileRefusedError as exc:
        raise error(f"{what} {path}: {exc.reason}") from None


def read_text(path: str | Path, what: str, max_bytes: int, error: type[SpmError]) -> str:
    """The UTF-8 text of ``path`` (size-capped); a binary file is refused as such."""
    data = read_bytes(path, what, max_bytes, error)
    try:
        return data.decode("utf-8-sig")  # a byte-order mark is not part of the text
    except UnicodeDecodeError as exc:
        raise error(f"{what} {path}: not UTF-8 text (a binary file?): byte {exc.start} "
                    f"cannot be decoded") from None


def json_depth(obj: Any) -> int:
    """Nesting depth of a decoded JSON value (a scalar is 0), without recursion."""
    depth = 0
    stack: list[tuple[Any, int]] = [(obj, 0)]
    while stack:
        node, d = stack.pop()
        if isinstance(node, dict):
            node = list(node.values())
        if isinstance(node, list):
            depth = max(depth, d + 1)
            stack.extend((v, d + 1) for v in node if isinstance(v, dict | list))
    return depth


def parse_json(text: str, what: str, error: type[SpmError], max_depth: int = MAX_JSON_DEPTH) -> Any:
    """Decode JSON text; refuses malformed text, numbers Python cannot hold and deep nesting."""
    try:
        obj = json.loads(text)
    except RecursionError:
        raise error(f"{what}: JSON nested too deeply (more than {max_depth} levels)") from None
    except json.JSONDecodeError as exc:
        raise error(f"{what}: not valid JSON: {exc}") from None
    except ValueError as exc:  # an integer with more digits than Python converts
        if "integer string conversion" in str(exc):
            raise error(f"{what}: not valid JSON here: a number with more than "
                        f"{sys.get_int_max_str_digits()} digits") from None
        raise error(f"{what}: not valid JSON: {exc}") from None
    if json_depth(obj) > max_depth:
        raise error(f"{what}: JSON nested too deeply (more than {max_depth} levels)")
    return obj


def parse_toml(text: str, what: str, error: type[SpmError], too_deep: str) -> dict[str, Any]:
    """Decode TOML text; malformed text is ``"{what}: not valid TOML: …"`` and nesting deeper
    than the decoder recurses ``"{what}: {too_deep}"``, both ``error``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what}: not valid TOML: {exc}") from None
    except RecursionError:
        raise error(f"{what}: {too_deep}") from None


def load_json(path: str | Path, what: str, max_bytes: int, error: type[SpmError],
              max_depth: int = MAX_JSON_DEPTH) -> Any:
    """Read and decode a JSON file with the size and depth caps."""
    text = read_text(path, what, max_bytes, error)
    return parse_json(text, f"{what} {path}", error, max_depth)


def _name_max(path: Path) -> int:
    """NAME_MAX of the file system ``path`` (or its nearest existing folder) lies on."""
    for folder in (path, *path.parents):
        try:
            return int(os.pathconf(folder, "PC_NAME_MAX"))
        except (OSError, ValueError):
            continue
    return NAME_MAX


def _abbrev(name: str, keep: int = 24) -> str:
    return name if len(name) <= keep else f"{name[:keep]}…"


def check_path_names(path: str | Path, what: str, error: type[SpmError]) -> None:
    """Refuse a path the system cannot name, before anything opens it (which would fail with
    ENAMETOOLONG): a folder or file name above NAME_MAX bytes, or the whole above PATH_MAX."""
    p = Path(path)
    whole = len(os.fsencode(str(p)))
    if whole >= PATH_MAX:
        raise error(f"{what} {_abbrev(str(p), 40)}: the path is {whole:,} bytes long; a path "
                    f"holds fewer than {PATH_MAX:,} (PATH_MAX)")
    limit = _name_max(p.parent)
    for part in p.parts:
        n = len(os.fsencode(part))
        if n > limit:
            raise error(f"{what}: the name '{_abbrev(part)}' in the path is {n} bytes long; a "
                        f"file or folder name holds at most {limit} bytes here (NAME_MAX)")


def temp_prefix(name: str) -> str:
    """The prefix of a temporary file written beside the file ``name``, then renamed to it:
    ``.NAME.`` with the name cut to :data:`TEMP_NAME_BYTES` bytes."""
    return "." + os.fsdecode(os.fsencode(name)[:TEMP_NAME_BYTES]) + "."


#: Permissions asked for a new file; the kernel takes the process's umask off (0644 under the
#: usual 022), as for any file ``open()`` creates.
NEW_FILE_MODE = 0o666


def atomic_temp(path: str | Path) -> tuple[int, Path]:
    """A new, empty temporary file beside ``path`` to be renamed onto it: (its descriptor,
    opened for writing, and its path ``.<name>.<random>.tmp``, the name cut as
    :func:`temp_prefix` cuts it). Created with
    :data:`NEW_FILE_MODE`, so the file that replaces ``path`` has the umask's permissions (and
    a folder's default ACL applies), as ``samples.csv`` and every other file written with
    ``open()``; the umask is never read (reading it means setting it, for every thread)."""
    p = Path(path)
    folder = p.parent
    for _ in range(100):
        tmp = folder / f"{temp_prefix(p.name)}{secrets.token_hex(4)}.tmp"
        try:  # O_EXCL: never an existing file, nor through a symbolic link
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, NEW_FILE_MODE)
        except FileExistsError:
            continue
        return fd, tmp
    raise FileExistsError(f"{folder}: no free temporary name beside {p.name}")


def write_text_atomic(path: str | Path, text: str, error: type[SpmError]) -> None:
    """Write ``text`` to ``path`` atomically (a temporary file beside it, then a rename), with
    the umask's permissions. Only a regular file (or nothing) may be replaced: a device, pipe or
    folder there raises ``error``, and so does a file that cannot be written (its folder
    missing or not writable, a full disk)."""
    p = Path(path)
    if p.exists() and not p.is_file():
        raise error(f"{p}: exists and is not a regular file; not replaced")
    try:
        fd, tmp = atomic_temp(p)
    except OSError as exc:  # a folder this process cannot write, or none
        raise error(f"{p}: cannot write: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, p)
    except OSError as exc:  # (a full disk)
        tmp.unlink(missing_ok=True)
        raise error(f"{p}: cannot write: {exc.strerror or exc}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
