"""Decisions with margins: a statistic compared with a threshold, and whether it sits on the threshold.

dynid takes yes/no decisions on computed numbers: a gap candidate's held-out gain against its minimum, a p-value
against its level, a combination's relative standard error against 10 %, a singular value against the rank cut, a
fixed-point iteration's last step against its tolerance. The numbers carry rounding that depends on the CPU's BLAS
kernels (numpy's OpenBLAS picks them at run time) and on memory alignment, so a value within rounding of its
threshold can answer differently on another machine. Every such decision therefore has a band around its
threshold, far wider than the rounding (1e-3 relative, against 1e-16 … 1e-7 of rounding in the sums behind them):
inside it the decision is taken the conservative way (not named, not determined, not settled) and reported as
borderline, so the output says that the case sits on the threshold instead of silently answering otherwise
elsewhere.
"""

from __future__ import annotations

import math

BORDERLINE_RTOL = 1e-3


def borderline(value: float, threshold: float, rtol: float = BORDERLINE_RTOL) -> bool:
    """Whether `value` lies within `rtol` (relative to the threshold) of `threshold`."""
    return bool(math.isfinite(value) and abs(value - threshold) <= rtol * abs(threshold))


def borderline_log(value: float, threshold: float, rtol: float = BORDERLINE_RTOL) -> bool:
    """The same on a logarithmic scale, for quantities compared by ratio (p-values, singular-value ratios)."""
    if not (value > 0 and threshold > 0 and math.isfinite(value)):
        return False
    return abs(math.log(value / threshold)) <= rtol


def above(value: float, threshold: float, rtol: float = BORDERLINE_RTOL) -> tuple[bool, bool]:
    """(value clearly above threshold, borderline): above only when past the band; inside it, not above."""
    near = borderline(value, threshold, rtol)
    return (value > threshold and not near), near


def below(value: float, threshold: float, rtol: float = BORDERLINE_RTOL) -> tuple[bool, bool]:
    """(value clearly below threshold, borderline): below only when past the band; inside it, not below."""
    near = borderline(value, threshold, rtol)
    return (value < threshold and not near), near
