"""The runtime (the motion process and the services) names no console step or key: the
front ends add their own words (the console by the error's Issue)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT
#: A console step ("step 1", "(step 3)") or key ("press SPACE") in a string.
CONSOLE = re.compile(r"\bstep \d|\(step\b|\bpress(es)?\b", re.IGNORECASE)


def _strings(path: Path) -> list[tuple[int, str]]:
    """The string constants of a module that are not docstrings (line, text)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and n.body and isinstance(n.body[0], ast.Expr)
            and isinstance(n.body[0].value, ast.Constant)}
    return [(n.lineno, n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def test_no_runtime_message_names_a_console_step_or_key() -> None:
    found = [f"{p.relative_to(ROOT)}:{line}: {text!r}"
             for pkg in ("motion", "services") for p in sorted((ROOT / "spm_console" / pkg).rglob("*.py"))
             for line, text in _strings(p) if CONSOLE.search(text)]
    assert found == []


def test_the_check_finds_a_console_step() -> None:
    assert CONSOLE.search("connect first (step 1)") and CONSOLE.search("press SPACE to stop it")
    assert not CONSOLE.search("N = 150 steps") and not CONSOLE.search("compressed")
