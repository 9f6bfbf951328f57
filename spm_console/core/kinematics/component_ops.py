"""The few non-arithmetic operations of the continuation kernel, for its two forms.

The kernel (:mod:`spm_console.core.kinematics.continuation`) writes every vector as three
components and every 3×3 matrix as nine. A component is a (n,) array when many rows advance
together, or a Python float when one pose does: arithmetic is the same code for both, and the
operations here are the rest (trigonometry, guarded division, NaN-propagating maxima). For one
row, float arithmetic is about twenty times cheaper than numpy calls on (1,) arrays.

Both forms give the same verdicts: a non-finite value propagates as NaN where the array form
gives NaN or ±inf, a division by zero gives 0 in both, and nothing raises. Radians.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

C = NDArray[np.floating[Any]] | float
"""One component: a (n,) array over rows, or a float for one row."""
Vec = Sequence[C]
"""Three components: x, y, z."""
Mat = Sequence[Sequence[C]]
"""Nine components: M[row][col]."""


def as_array(x: C) -> NDArray[np.float64]:
    """A component of the array form as the (n,) float array it is."""
    return np.asarray(x, np.float64)


class Ops(Protocol):
    """What the kernel needs beyond + − × of its components."""

    def cos_sin(self, x: C) -> tuple[C, C]: ...
    def sqrt(self, x: C) -> C: ...
    def abs(self, x: C) -> C: ...
    def max_abs3(self, a: C, b: C, c: C) -> C:
        """max(|a|, |b|, |c|), NaN if any is NaN."""
        ...
    def div0(self, x: C, d: C) -> C:
        """x / d, 0 where that is not finite (d = 0 included)."""
        ...
    def expm_coeffs(self, t2: C) -> tuple[C, C]:
        """(sin θ / θ, (1 − cos θ) / θ²) for θ² = ``t2`` (series below θ = 1e-8)."""
        ...
    def ratio01(self, num: C, den: C) -> C:
        """num / den clipped to [0, 1]; 0 where den ≤ 0 (or NaN)."""
        ...
    def finite_or_identity(self, M: Mat) -> Mat:
        """M, with the identity in the rows where any entry is not finite."""
        ...


class ArrayOps:
    """Components are (n,) arrays."""

    def cos_sin(self, x: C) -> tuple[C, C]:
        with np.errstate(invalid="ignore"):  # (±inf: NaN)
            return np.cos(x), np.sin(x)

    def sqrt(self, x: C) -> C:
        return np.sqrt(x)

    def abs(self, x: C) -> C:
        return np.abs(x)

    def max_abs3(self, a: C, b: C, c: C) -> C:
        return np.maximum(np.maximum(np.abs(a), np.abs(b)), np.abs(c))

    def div0(self, x: C, d: C) -> C:
        with np.errstate(all="ignore"):
            q = np.divide(x, d)
        return np.where(np.isfinite(q), q, 0.0)

    def expm_coeffs(self, t2: C) -> tuple[C, C]:
        th = np.sqrt(t2)
        small = th < 1e-8
        ths = np.where(small, 1.0, th)
        a = np.where(small, 1.0 - np.divide(t2, 6.0), np.sin(ths) / ths)
        b = np.where(small, 0.5 - np.divide(t2, 24.0), (1.0 - np.cos(ths)) / (ths * ths))
        return a, b

    def ratio01(self, num: C, den: C) -> C:
        pos = np.greater(den, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(pos, np.divide(num, np.where(pos, den, 1.0)), 0.0)
        return np.clip(z, 0.0, 1.0)

    def finite_or_identity(self, M: Mat) -> Mat:
        fin = np.isfinite(M[0][0])
        for a in range(3):
            for b in range(3):
                if a or b:
                    fin = fin & np.isfinite(M[a][b])
        return [[np.where(fin, M[a][b], float(a == b)) for b in range(3)] for a in range(3)]


def _f(x: C) -> float:
    assert isinstance(x, float)
    return x


class FloatOps:
    """Components are Python floats (one row)."""

    def cos_sin(self, x: C) -> tuple[C, C]:
        v = _f(x)
        return (math.cos(v), math.sin(v)) if math.isfinite(v) else (math.nan, math.nan)

    def sqrt(self, x: C) -> C:
        v = _f(x)
        return math.sqrt(v) if v >= 0.0 else math.nan  # (a sum of squares: < 0 only as NaN)

    def abs(self, x: C) -> C:
        return abs(_f(x))

    def max_abs3(self, a: C, b: C, c: C) -> C:
        x, y, z = abs(_f(a)), abs(_f(b)), abs(_f(c))
        return math.nan if math.isnan(x + y + z) else max(x, y, z)

    def div0(self, x: C, d: C) -> C:
        v, w = _f(x), _f(d)
        if w == 0.0:
            return 0.0
        q = v / w
        return q if math.isfinite(q) else 0.0

    def expm_coeffs(self, t2: C) -> tuple[C, C]:
        s = _f(t2)
        th = math.sqrt(s) if s >= 0.0 else math.nan
        if th < 1e-8:
            return 1.0 - s / 6.0, 0.5 - s / 24.0
        if not math.isfinite(th):
            return math.nan, math.nan
        return math.sin(th) / th, (1.0 - math.cos(th)) / (th * th)

    def ratio01(self, num: C, den: C) -> C:
        n, d = _f(num), _f(den)
        if not d > 0.0:
            return 0.0
        z = n / d
        return math.nan if math.isnan(z) else min(max(z, 0.0), 1.0)

    def finite_or_identity(self, M: Mat) -> Mat:
        if all(math.isfinite(_f(x)) for row in M for x in row):
            return M
        return [[float(a == b) for b in range(3)] for a in range(3)]


ARRAY_OPS = ArrayOps()
FLOAT_OPS = FloatOps()
