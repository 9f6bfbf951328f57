"""The console's form values, remembered per profile between sessions.

What the operator typed (start, goal, steps, v_max, …) is kept as typed text — never
reformatted — under the profile's name, in ``$SPM_CONSOLE_CONFIG/console.json`` (default
``~/.config/spm_console/console.json``). A missing, unreadable or oversized file is ignored
(the console starts with its defaults); a write that fails is reported once, never raised
into the UI. Bounded: 64 KB per file, 200 characters per value, 50 profiles.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

from spm_console.safe_io import atomic_temp

#: Largest file read, bytes; longest value kept, characters; most profiles kept.
MAX_BYTES = 64 * 1024
MAX_VALUE = 200
MAX_PROFILES = 50


def config_dir() -> Path:
    env = os.environ.get("SPM_CONSOLE_CONFIG")
    return Path(env) if env else Path.home() / ".config" / "spm_console"


class FormMemory:
    """``get``/``put`` typed text per (profile, field); ``save`` writes it atomically."""

    def __init__(self, path: Path | None = None) -> None:
        self.path = path if path is not None else config_dir() / "console.json"
        self.data: dict[str, dict[str, str]] = self._read()
        self.error = ""
        """Why the last save failed ("" when it did not)."""

    def _read(self) -> dict[str, dict[str, str]]:
        try:
            if not self.path.is_file() or self.path.stat().st_size > MAX_BYTES:
                return {}
            raw = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError):
            return {}
        if not isinstance(raw, dict):
            return {}
        out: dict[str, dict[str, str]] = {}
        for prof, fields in list(raw.items())[:MAX_PROFILES]:
            if isinstance(prof, str) and isinstance(fields, dict):
                out[prof] = {k: v[:MAX_VALUE] for k, v in fields.items()
                             if isinstance(k, str) and isinstance(v, str)}
        return out

    def get(self, profile: str, field: str) -> str | None:
        return self.data.get(profile, {}).get(field)

    def put(self, profile: str, field: str, text: str) -> None:
        fields = self.data.setdefault(profile, {})
        fields[field] = text[:MAX_VALUE]
        while len(self.data) > MAX_PROFILES:
            self.data.pop(next(iter(self.data)))

    def save(self) -> bool:
        """Write the file (temporary file + rename); False (and ``error``) when it failed."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            text = json.dumps(self.data, indent=1, ensure_ascii=False)
            fd, tmp = atomic_temp(self.path)
            try:
                with os.fdopen(fd, "w", encoding="utf-8") as fh:
                    fh.write(text + "\n")
                os.replace(tmp, self.path)
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise
        except OSError as exc:
            self.error = f"{self.path}: {exc.strerror or exc}"
            return False
        self.error = ""
        return True
