"""The package's import statements read from its source (``ast``), for the tests of its
import graph: circles, and which imports inside functions put off loading something."""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from tests.support.paths import ROOT

PACKAGE = "spm_console"


@dataclass(frozen=True)
class ImportStatement:
    module: str  #: the importing module
    line: int
    where: str  #: "top" (runs when the module loads), "function" or "type_checking"
    own: frozenset[str]  #: modules of the package it runs (each package ``__init__`` too)
    other: frozenset[str]  #: other modules it names (``scipy.optimize``, ``json``)


@cache
def modules() -> dict[str, Path]:
    """Dotted name -> source file, for every module and package of the package."""
    out: dict[str, Path] = {}
    for p in (ROOT / PACKAGE).rglob("*.py"):
        parts = p.relative_to(ROOT).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return out


def _owner(name: str) -> str | None:
    mods = modules()
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name or None


def _names(module: str, path: Path, node: ast.Import | ast.ImportFrom) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    base = node.module or ""
    if node.level:
        here = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        here = here[: len(here) - node.level + 1]
        base = ".".join([*here, base] if base else here)
    return [f"{base}.{a.name}" if f"{base}.{a.name}" in modules() else base for a in node.names]


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _walk(node: ast.AST, where: str) -> Iterator[tuple[str, ast.Import | ast.ImportFrom]]:
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.Import, ast.ImportFrom)):
            yield where, child
        elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            yield from _walk(child, "function")
        elif isinstance(child, ast.If) and where == "top" and _is_type_checking(child):
            yield from _walk(ast.Module(body=child.body, type_ignores=[]), "type_checking")
            yield from _walk(ast.Module(body=child.orelse, type_ignores=[]), "top")
        else:  # class bodies, if/try/with blocks: they run where their parent runs
            yield from _walk(child, where)


@cache
def statements() -> tuple[ImportStatement, ...]:
    """Every import statement of the package."""
    out: list[ImportStatement] = []
    for m, path in modules().items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for where, node in _walk(tree, "top"):
            own: set[str] = set()
            other: set[str] = set()
            for n in _names(m, path, node):
                t = _owner(n) if n.split(".")[0] == PACKAGE else None
                if t is None:
                    if n.split(".")[0] != PACKAGE:
                        other.add(n)
                    continue
                # importing a.b.c runs the packages a and a.b first (unless m is inside them)
                parts = t.split(".")
                for k in range(2, len(parts) + 1):
                    dep = ".".join(parts[:k])
                    if dep in modules() and dep != m and not m.startswith(dep + "."):
                        own.add(dep)
            out.append(ImportStatement(m, node.lineno, where, frozenset(own), frozenset(other)))
    return tuple(out)


def own_import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports anywhere: at the top, inside functions and
    under ``TYPE_CHECKING`` alike (a circle hidden in a function or a type hint is a circle)."""
    graph: dict[str, set[str]] = {m: set() for m in modules()}
    for s in statements():
        graph[s.module] |= s.own
    return graph


@cache
def loaded_by(module: str) -> frozenset[str]:
    """What importing ``module`` loads, by its top-level imports and theirs: the package's
    modules by name, other modules as the names imported (``scipy.optimize``)."""
    top: dict[str, list[ImportStatement]] = {}
    for s in statements():
        if s.where == "top":
            top.setdefault(s.module, []).append(s)
    seen: set[str] = set()
    stack = [module]
    while stack:
        m = stack.pop()
        if m in seen:
            continue
        seen.add(m)
        for s in top.get(m, ()):
            seen |= s.other
            stack.extend(s.own)
    return frozenset(seen)


def outside_stdlib(name: str) -> bool:
    return name.split(".")[0] not in sys.stdlib_module_names and name.split(".")[0] != PACKAGE


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out
