"""Text shown to people: values at the precision they mean, never digits below it.

One owner for wording that the CLI, the console and the reports share, so that a
value that depends on the CPU's floating-point kernels (a residual of 5.5e-16 on one
machine, 7.4e-16 on another) reads the same everywhere: as a bound.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: Residuals below this are shown as a bound; the exact value stays in JSON output.
RESIDUAL_SHOWN_BELOW = 1e-12


def fmt_residual(value: float) -> str:
    """``"< 1e-12"`` for a converged residual, else the value to 2 significant digits."""
    if value < RESIDUAL_SHOWN_BELOW:
        return f"< {RESIDUAL_SHOWN_BELOW:.0e}"
    return f"{value:.1e}"


def fmt_num(x: float, digits: int = 2, signed: bool = False) -> str:
    """``x`` at ``digits`` decimals; a value that rounds to zero reads 0 (never −0.00)."""
    r = round(float(x), digits) + 0.0  # (−0.0 + 0.0 is +0.0)
    return f"{r:{'+' if signed else ''}.{digits}f}"


def fmt_vec(v: Any, digits: int = 4, signed: bool = False) -> str:
    """``[a, b, c]`` at ``digits`` decimals (with a sign on every value when ``signed``)."""
    return "[" + ", ".join(fmt_num(x, digits, signed) for x in np.ravel(v)) + "]"


def fmt_deg(v: Any, digits: int = 2) -> str:
    """Angles in degrees: ``[a, b, c]°``."""
    return fmt_vec(v, digits) + "°"
