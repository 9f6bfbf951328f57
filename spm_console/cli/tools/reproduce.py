"""``reproduce --out DIR``: the paper's claims checked in one run (report.md + figures)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from spm_console.cli.common import emit, info, output_folder
from spm_console.errors import ExitCode
from spm_console.report.reproduce import ReproSettings, reproduce


def register(sub: Any) -> None:
    p = sub.add_parser("reproduce", help="reproduce the paper's numbers and figures into a report")
    p.add_argument("--out", type=Path, required=True, help="output directory for report.md and figures")
    p.add_argument("--quick", action="store_true", help="reduced settings (fewer verifier samples)")
    p.add_argument("--no-execute", action="store_true", help="plan only; do not run on the emulated bus")
    p.add_argument("--fine-grid", action="store_true",
                   help="also plan the minimum-time pair on a 1° workspace grid (slow, ~1 GB) and "
                        "compare with the profile's grid refined near the boundary")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.set_defaults(func=cmd_reproduce)


def cmd_reproduce(args: argparse.Namespace) -> int:

    output_folder(args.out, "--out")
    settings = ReproSettings(quick=args.quick, execute=not args.no_execute, fine_grid=args.fine_grid)
    report, sections = reproduce(args.out, settings, progress=lambda s: info(f"reproduce: {s}"))
    verdicts = [c.verdict for s in sections for c in s.checks]
    summary = {
        "report": str(report),
        "figures": [str(args.out / f) for s in sections for f, _ in s.figures],
        "checks": len(verdicts),
        "reproduced": verdicts.count("reproduced"),
        "explained": verdicts.count("differs (explained)"),
        "not_reproduced": verdicts.count("NOT reproduced"),
        "sections": {s.anchor: round(s.seconds, 2) for s in sections},
    }
    emit(args, summary, f"report written to {report}\n"
         f"{summary['reproduced']} reproduced, {summary['explained']} explained differences, "
         f"{summary['not_reproduced']} not reproduced, of {summary['checks']} checks")
    return int(ExitCode.OK if summary["not_reproduced"] == 0 else ExitCode.ASSERTION_FAILED)
