"""Text shown to people: values at the precision they mean, never digits below it.

One owner for wording that the CLI, the console and the reports share, so that a
value that depends on the CPU's floating-point kernels (a residual of 5.5e-16 on one
machine, 7.4e-16 on another) reads the same everywhere: as a bound.
"""

from __future__ import annotations

#: Residuals below this are shown as a bound; the exact value stays in JSON output.
RESIDUAL_SHOWN_BELOW = 1e-12


def fmt_residual(value: float) -> str:
    """``"< 1e-12"`` for a converged residual, else the value to 2 significant digits."""
    if value < RESIDUAL_SHOWN_BELOW:
        return f"< {RESIDUAL_SHOWN_BELOW:.0e}"
    return f"{value:.1e}"
