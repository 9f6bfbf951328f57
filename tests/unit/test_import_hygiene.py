"""The pure core never imports UI, viewer or serial packages."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import spm_console.core as core
from tests.support.import_graph import circles, own_import_graph
from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT

FORBIDDEN = ("textual", "rich", "meshcat", "serial", "pydantic", "matplotlib", "control",
             "plotext")
#: Modules of the package above the core that the core must not pull in.
ABOVE = ("spm_console.config", "spm_console.motion", "spm_console.services", "spm_console.system",
         "spm_console.devices",
         "spm_console.cli", "spm_console.tui", "spm_console.viewer", "spm_console.report",
         "spm_console.store.workspace_cache", "spm_console.store.plan_file")


def _core_modules() -> list[str]:
    return [m.name for m in pkgutil.walk_packages(core.__path__, prefix="spm_console.core.")]


def test_every_core_module_is_checked() -> None:
    mods = _core_modules()
    assert "spm_console.core.planning.mvn" in mods and "spm_console.core.workspace.certify" in mods


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
    assert _loaded("import spm_console.motion.server", HEAVY) == []


def test_the_console_shows_its_first_screen_before_loading_scipy_or_meshcat() -> None:
    """What the console does before its first screen (its imports and loading the profile,
    which finds the home pose's assembly mode) loads neither scipy's sparse, spatial or
    optimize packages nor meshcat: together about 0.8 s of a 2 s budget."""
    code = ("from pathlib import Path\n"
            "import spm_console.cli.tui, spm_console.tui.app\n"
            "from spm_console.config.load import load_profile\n"
            "load_profile(Path('profiles/agile_wrist.toml'))")
    assert _loaded(code, (*HEAVY, "scipy.sparse", "scipy.spatial", "meshcat")) == []


def test_a_command_that_only_executes_or_homes_never_loads_the_follower() -> None:
    """The motion process's client (every command and console) names the following's outcome
    for its types only: the follower's solvers (scipy.optimize, osqp: about 1.2 s) load in
    the motion process, never in a front end that does not follow."""
    code = "import spm_console.cli.run, spm_console.services.client, spm_console.services.oneshot"
    assert _loaded(code, ("scipy.optimize", "osqp", "spm_console.motion.follow.run")) == []


def test_no_import_circle_anywhere_in_the_package() -> None:
    """Function-level and type-only imports count: each module depends on modules below it."""
    graph = own_import_graph()
    assert len(graph) > 150 and graph["spm_console.motion.executor"]  # the walk sees the package
    assert circles(graph) == []


def test_the_circle_check_finds_a_circle() -> None:
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_no_folder_of_the_package_holds_more_than_15_modules() -> None:
    """A flat heap hides the architecture: each folder is one part of it."""
    crowded = {str(d.relative_to(ROOT)): n for d in (ROOT / "spm_console").rglob("*")
               if d.is_dir() and d.name != "__pycache__"
               and (n := sum(1 for f in d.glob("*.py") if f.name != "__init__.py")) > 15}
    assert crowded == {}
