"""Bounded reading of operator-supplied files (plan, region, CSV, script).

Every file an operator names is read with a size cap (a device such as ``/dev/zero``
or a huge file is refused after ``max_bytes`` + 1 bytes, never read whole), decoded
as UTF-8 (a binary file is refused as such) and, for JSON, parsed with a nesting cap.
Failures raise the caller's :class:`~spm_console.errors.SpmError` subclass with a
message naming the file and what was wrong — never a traceback.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from spm_console.errors import SpmError

MB = 1024 * 1024
#: Deepest nesting accepted in a JSON file (a valid plan needs 5 levels).
MAX_JSON_DEPTH = 32


def _mb(n: int) -> str:
    return f"{n / MB:g} MB" if n >= MB else f"{n} bytes"


def read_bytes(path: str | Path, what: str, max_bytes: int, error: type[SpmError]) -> bytes:
    """At most ``max_bytes`` of ``path``; larger files are refused without reading them whole."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise error(f"{what} {p}: cannot read: {exc.strerror or exc}") from None
    if len(data) > max_bytes:
        raise error(f"{what} {p}: larger than the {_mb(max_bytes)} limit for this kind of file")
    return data


def read_text(path: str | Path, what: str, max_bytes: int, error: type[SpmError]) -> str:
    """The UTF-8 text of ``path`` (size-capped); a binary file is refused as such."""
    data = read_bytes(path, what, max_bytes, error)
    try:
        return data.decode("utf-8")
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
    except ValueError as exc:  # e.g. an integer with more digits than Python converts
        raise error(f"{what}: not valid JSON: {exc}") from None
    if json_depth(obj) > max_depth:
        raise error(f"{what}: JSON nested too deeply (more than {max_depth} levels)")
    return obj


def load_json(path: str | Path, what: str, max_bytes: int, error: type[SpmError],
              max_depth: int = MAX_JSON_DEPTH) -> Any:
    """Read and decode a JSON file with the size and depth caps."""
    text = read_text(path, what, max_bytes, error)
    return parse_json(text, f"{what} {path}", error, max_depth)
