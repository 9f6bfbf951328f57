"""``spm-console reproduce --out DIR``: every claim of the paper, checked in one run.

Runs on the shipped profiles and the emulated servo bus; writes ``DIR/report.md``
(tables: paper value, ours, difference, verdict) and the PNG figures it cites.
"""

from __future__ import annotations

import platform
import time
from collections.abc import Callable
from pathlib import Path

from spm_console import __version__
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.report.repro_kin import eq35_section, fk_section
from spm_console.report.repro_types import Check, ReproSettings, Section


def _fmt(x: float | None) -> str:
    if x is None:
        return "—"
    return f"{x:.1e}" if (x != 0 and (abs(x) < 1e-2 or abs(x) >= 1e4)) else f"{x:.4g}"


def _md_table(checks: list[Check]) -> str:
    lines = ["| quantity | paper | ours | difference | verdict |", "|---|---|---|---|---|"]
    for c in checks:
        verdict = c.verdict
        if c.explained:
            verdict += f" — {c.explained}"
        cells = [c.quantity, c.paper, c.ours, _fmt(c.diff), verdict]
        lines.append("| " + " | ".join(s.replace("|", "\\|") for s in cells) + " |")
    return "\n".join(lines)


def render(sections: list[Section], settings: ReproSettings, seconds: float) -> str:
    """The report as markdown."""
    out = [
        "# Reproduction of the paper",
        "",
        f"spm_console {__version__}, Python {platform.python_version()} on {platform.machine()}; "
        f"total {seconds:.1f} s{' (reduced settings)' if settings.quick else ''}.",
        "Verdicts: *reproduced* = within the paper's printed precision; *differs (explained)* = cannot "
        "match, the reason is given in the section; *reported* = the paper prints no comparable number.",
        "",
        "## Summary",
        "",
        "| section | checks | reproduced | differs (explained) | not reproduced | seconds |",
        "|---|---|---|---|---|---|",
    ]
    for s in sections:
        v = [c.verdict for c in s.checks]
        out.append(
            f"| [{s.title}](#{s.anchor}) | {len(v)} | {v.count('reproduced')} | "
            f"{v.count('differs (explained)')} | {v.count('NOT reproduced')} | {s.seconds:.1f} |"
        )
    for s in sections:
        out += ["", f'<a id="{s.anchor}"></a>', "", f"## {s.title}", "", _md_table(s.checks), ""]
        if s.text:
            out += [s.text, ""]
        for name, caption in s.figures:
            out += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    return "\n".join(out) + "\n"


def reproduce(
    out_dir: Path,
    settings: ReproSettings | None = None,
    agile_path: str = "profiles/agile_wrist.toml",
    coaxial_path: str = "profiles/coaxial_spm.toml",
    progress: Callable[[str], None] = lambda s: None,
) -> tuple[Path, list[Section]]:
    """Run every section, write ``report.md`` and its figures into ``out_dir`` (default
    settings: the full reproduction)."""

    settings = ReproSettings() if settings is None else settings

    out_dir.mkdir(parents=True, exist_ok=True)
    agile: Profile = load_profile(agile_path)
    coaxial: Profile = load_profile(coaxial_path)
    t0 = time.perf_counter()
    sections: list[Section] = []
    progress("forward kinematics …")
    sections.append(fk_section(agile, coaxial))
    progress("eq. (35) …")
    sections.append(eq35_section(agile))
    for name, fn in _extra_sections():
        progress(f"{name} …")
        sections.extend(fn(agile, out_dir, settings))
    report = out_dir / "report.md"
    report.write_text(render(sections, settings, time.perf_counter() - t0))
    return report, sections


def _extra_sections() -> list[tuple[str, Callable[[Profile, Path, ReproSettings], list[Section]]]]:
    """Workspace, MVN and minimum-time sections (modules that need the whole stack)."""
    from spm_console.report.repro_plan import plan_sections
    from spm_console.report.repro_ws import workspace_sections

    return [("workspace", workspace_sections), ("planning and execution", plan_sections)]
