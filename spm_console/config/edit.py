"""Set keys of a profile's TOML text, everything else kept (sections, order, comments).

Each ``key = value`` line named is replaced by the new value with a comment saying where it
came from (a key missing from its section is added under the section's header, a section
missing from the text is added at its end). The result
is parsed and validated as a profile, and the values it holds are compared with the values
asked for, before anyone writes it.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence

from spm_console.config.load import parse_profile_text
from spm_console.config.schema import Profile
from spm_console.errors import ProfileError

#: A table header, ``[name]`` or ``[[name]]`` (an array of tables).
HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\-\s\"']+?)\s*\]\]?\s*(#.*)?$")

Value = bool | int | float | str | list[int] | list[float]


def toml_value(v: Value) -> str:
    """A TOML literal of a bool, int, finite float, str or a list of them."""
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"not a finite number: {v}")
        return repr(v)
    return json.dumps(str(v), ensure_ascii=False)


def _key_of(line: str) -> str | None:
    m = re.match(r"^\s*([A-Za-z0-9_\-]+)\s*=", line)
    return m.group(1) if m else None


def _value_end(lines: list[str], k: int) -> int:
    """Index after the last line of the value that starts on line ``k`` (arrays may span
    lines: brackets outside strings and comments are counted)."""
    depth = 0
    j = k
    while j < len(lines):
        text = re.sub(r'"(?:\\.|[^"\\])*"', '""', lines[j]).split("#", 1)[0]
        if j == k:
            text = text.split("=", 1)[1]
        depth += text.count("[") - text.count("]")
        j += 1
        if depth <= 0:
            break
    return j


def with_values(text: str, values: Mapping[tuple[str, str], Value | None], note: str,
                source: str) -> tuple[str, Profile]:
    """``text`` with each ``(section, key)`` set to its value (commented ``note``), or, for
    None, its line commented out (the key takes its default, with the note saying why); the
    new text and the profile it parses to. ProfileError naming ``source`` when it does not
    parse, or when a value read back differs from the one asked for."""
    lines = text.splitlines()
    todo: dict[tuple[str, str], Value | None] = dict(values)
    out: list[str] = []
    section = ""
    k = 0
    while k < len(lines):
        line = lines[k]
        m = HEADER.match(line)
        if m:
            _flush(out, section, todo, note)  # keys the previous section lacked
            section = re.sub(r"\s+", "", m.group(1))
            out.append(line)
            k += 1
            continue
        key = _key_of(line)
        if key is not None and (section, key) in todo:
            value = todo.pop((section, key))
            end = _value_end(lines, k)
            if value is None:  # the key back to its default: its lines kept, commented
                out += [f"# {ln}" for ln in lines[k:end]]
                out.append(f"# ({key} removed: {note})")
            else:
                out.append(key_line(key, value, note))
            k = end
            continue
        out.append(line)
        k += 1
    _flush(out, section, todo, note)
    headers = {re.sub(r"\s+", "", m.group(1)) for ln in lines if (m := HEADER.match(ln))}
    for sec in dict.fromkeys(s for s, _key in todo):
        if sec in Profile.model_fields and sec not in headers:  # an optional section, absent
            out += ["", f"[{sec}]"]
            _flush(out, sec, todo, note)
    if todo:
        missing = ", ".join(f"[{s}] {key}" for s, key in todo)
        raise ProfileError(f"{source}: the base profile has no section for {missing}")
    new = "\n".join(out).rstrip("\n") + "\n"
    prof = parse_profile_text(new, source)
    dumped = prof.model_dump()
    for (sec, key), v in values.items():
        got = dumped.get(sec, {}).get(key)
        got = list(got) if isinstance(got, tuple) else got
        if got != v:
            raise ProfileError(f"{source}: [{sec}] {key} reads back as {got!r}, not {v!r}")
    return new, prof


def key_line(key: str, value: Value, note: str) -> str:
    """One ``key = value  # note`` line, the comments lined up as in the shipped profiles."""
    return f"{key} = {toml_value(value)}".ljust(38) + f" # {note}"


def _flush(out: list[str], section: str, todo: dict[tuple[str, str], Value | None],
           note: str) -> None:
    """Add the keys of ``section`` still to set at the end of its lines (before blank lines);
    one to remove that the section lacks is done."""
    for gone in [(s, key) for (s, key), v in todo.items() if s == section and v is None]:
        del todo[gone]
    mine = [(s, key) for s, key in todo if s == section]
    if not mine:
        return
    at = len(out)
    while at > 0 and not out[at - 1].strip():
        at -= 1
    out[at:at] = [key_line(key, v, note) for s, key in mine
                  if (v := todo.pop((s, key))) is not None]


def with_joints(text: str, joints: Sequence[dict[str, Value]], note: str,
                source: str) -> tuple[str, Profile]:
    """``text`` with keys of its ``[[bus.joints]]`` tables set, the k-th table from
    ``joints[k]`` (commented ``note``); the new text and the profile it parses to. ProfileError
    when the text has another number of joint tables or a value reads back otherwise."""
    lines = text.splitlines()
    out: list[str] = []
    table = -1
    in_joints = False
    todo: dict[str, Value] = {}
    k = 0
    while k < len(lines):
        line = lines[k]
        m = HEADER.match(line)
        if m:
            _flush_keys(out, todo, note)
            in_joints = line.lstrip().startswith("[[") and re.sub(r"\s+", "", m.group(1)) == "bus.joints"
            if in_joints:
                table += 1
                todo = dict(joints[table]) if table < len(joints) else {}
            out.append(line)
            k += 1
            continue
        key = _key_of(line)
        if in_joints and key is not None and key in todo:
            out.append(key_line(key, todo.pop(key), note))
            k = _value_end(lines, k)
            continue
        out.append(line)
        k += 1
    _flush_keys(out, todo, note)
    if table + 1 != len(joints):
        raise ProfileError(f"{source}: {table + 1} [[bus.joints]] tables, expected {len(joints)}")
    new = "\n".join(out).rstrip("\n") + "\n"
    prof = parse_profile_text(new, source)
    for j, want in zip(prof.bus.joints, joints, strict=True):
        for key, v in want.items():
            if getattr(j, key) != v:
                raise ProfileError(f"{source}: [[bus.joints]] {key} reads back as "
                                   f"{getattr(j, key)!r}, not {v!r}")
    return new, prof


def _flush_keys(out: list[str], todo: dict[str, Value], note: str) -> None:
    """Add the keys still to set at the end of the current table (before blank lines)."""
    if not todo:
        return
    at = len(out)
    while at > 0 and not out[at - 1].strip():
        at -= 1
    out[at:at] = [key_line(key, v, note) for key, v in todo.items()]
    todo.clear()
