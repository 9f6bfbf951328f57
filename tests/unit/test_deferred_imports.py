"""An import of the package's own modules inside a function only where it puts off
something slow: the rest are at the top of their modules, where a reader looks for them.

"Slow", read from the source: the import, made at the top instead, would load a package
from outside the standard library (numpy, scipy, textual, meshcat, serial, …) or at least
:data:`MIN_OWN_MODULES` of the package's own modules that the importing module does not
load anyway. An import inside a function that puts off less than that only hides where a
module's dependencies are."""

from __future__ import annotations

from tests.support.import_graph import ImportStatement, loaded_by, outside_stdlib, statements

#: ``python -X importtime`` here, after ``import spm_console.services.session``: 4 modules
#: (``spm_console.store.plan_file`` and what it loads) take about 1.4 ms, 8
#: (``spm_console.motion.plan_check``) about 11 ms; the console imports in about 1 s.
MIN_OWN_MODULES = 5


def put_off(s: ImportStatement) -> frozenset[str]:
    """What the statement, run inside a function, loads that its module does not load."""
    later: set[str] = set()
    for target in s.own:
        later |= loaded_by(target)
    return frozenset(later - loaded_by(s.module))


def slow(later: frozenset[str]) -> bool:
    own = [m for m in later if m.startswith("spm_console.")]
    return len(own) >= MIN_OWN_MODULES or any(outside_stdlib(m) for m in later)


def test_every_import_inside_a_function_puts_off_something_slow() -> None:
    deferred = [s for s in statements() if s.where == "function" and s.own]
    assert len(deferred) > 10  # the walk sees them
    quick = sorted(f"{s.module}:{s.line} puts off {sorted(put_off(s)) or 'nothing'}"
                   for s in deferred if not slow(put_off(s)))
    assert quick == [], "move these imports to the top of their modules:\n" + "\n".join(quick)


def test_the_rule_tells_slow_from_quick() -> None:
    """The motion server puts off the following run (osqp and scipy: about 1 s), the CLI
    the whole console; an import of what a module loads anyway puts off nothing."""
    by_line = {(s.module, max(s.own, key=len)): s for s in statements() if s.where == "function" and s.own}
    follow = by_line["spm_console.motion.server", "spm_console.motion.follow.run"]
    assert "osqp" in put_off(follow) and slow(put_off(follow))
    assert slow(put_off(by_line["spm_console.cli.tui", "spm_console.tui.app"]))
    assert not slow(frozenset({"spm_console.errors", "json"}))
    assert put_off(ImportStatement("spm_console.motion.server", 0, "function",
                                   frozenset({"spm_console.motion.executor"}), frozenset())) == set()


def test_no_type_only_import_of_a_module_its_module_loads_anyway() -> None:
    """``if TYPE_CHECKING:`` keeps a module from loading; for one loaded anyway it only
    hides a dependency."""
    pointless = sorted(f"{s.module}:{s.line}" for s in statements()
                       if s.where == "type_checking" and s.own
                       and s.own <= loaded_by(s.module))
    assert pointless == []
