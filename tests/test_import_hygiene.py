"""The pure core never imports UI, viewer or serial packages (SPEC §2, STYLE §1)."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import spm_console.core as core

FORBIDDEN = ("textual", "rich", "meshcat", "serial", "pydantic", "matplotlib", "control",
             "plotext")
#: Modules of the package above the core that the core must not pull in.
ABOVE = ("spm_console.profile", "spm_console.models", "spm_console.run", "spm_console.devices",
         "spm_console.cli", "spm_console.tui", "spm_console.viewer", "spm_console.report",
         "spm_console.store.workspace_cache", "spm_console.store.plan_file")


def _core_modules() -> list[str]:
    return [m.name for m in pkgutil.walk_packages(core.__path__, prefix="spm_console.core.")]


def test_every_core_module_is_checked() -> None:
    mods = _core_modules()
    assert "spm_console.core.planning.mvn" in mods and "spm_console.core.certify" in mods


def test_core_imports_no_ui_or_io_packages() -> None:
    mods = _core_modules()
    assert mods
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        f"bad = sorted(k for k in sys.modules if k.split('.')[0] in {FORBIDDEN!r}\n"
        f"             or any(k == a or k.startswith(a + '.') for a in {ABOVE!r}))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core pulled in: {out.stdout.strip()}"


#: Packages that take about a second to import together and that only a motion (the Kalman
#: filters load scipy.stats) or a workspace build (linprog, fsolve) needs.
HEAVY = ("filterpy", "scipy.stats", "scipy.optimize")


def _loaded(code: str, packages: tuple[str, ...]) -> list[str]:
    """The modules of ``packages`` in ``sys.modules`` after ``code`` ran in a fresh
    interpreter."""
    probe = (f"{code}\nimport sys\nprint(','.join(sorted(k for k in sys.modules if any(\n"
             f"    k == h or k.startswith(h + '.') for h in {packages!r}))))\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return [m for m in out.stdout.strip().split(",") if m]


def test_the_motion_process_answers_before_it_loads_what_only_a_motion_needs() -> None:
    """Each console and CLI run starts a motion process and waits for its first answer: its
    imports were 2.4 s, now about 0.6 s; the rest loads after that answer, before the first
    request is read (``motion_process._warm_up``)."""
    assert _loaded("import spm_console.run.motion_process", HEAVY) == []


def test_the_console_shows_its_first_screen_before_loading_scipy_or_meshcat() -> None:
    """What the console does before its first screen (its imports and loading the profile,
    which finds the home pose's assembly mode) loads neither scipy's sparse, spatial or
    optimize packages nor meshcat: together about 0.8 s of a 2 s budget."""
    code = ("from pathlib import Path\n"
            "import spm_console.cli.tui, spm_console.tui.app\n"
            "from spm_console.profile_load import load_profile\n"
            "load_profile(Path('profiles/agile_wrist.toml'))")
    assert _loaded(code, (*HEAVY, "scipy.sparse", "scipy.spatial", "meshcat")) == []
