"""The pure core never imports UI, viewer or serial packages (SPEC §2, STYLE §1)."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import spm_console.core as core

FORBIDDEN = ("textual", "rich", "meshcat", "serial")


def test_core_imports_no_ui_or_io_packages() -> None:
    mods = [f"spm_console.core.{m.name}" for m in pkgutil.walk_packages(core.__path__)]
    assert mods
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        f"bad = sorted(k for k in sys.modules if k.split('.')[0] in {FORBIDDEN!r})\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core pulled in: {out.stdout.strip()}"
