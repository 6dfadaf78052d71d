"""Which base combinations a fit determines: a jackknife standard error under 10 % of the combination's value, or
under 5 % of its size (its CAD value; an F/T offset's channel's reading), past the margin's band (dynid.margins), and
for a consistent fit not resting on a bound."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ..margins import BORDERLINE_RTOL
from ..robot.model import RobotModel
from ..robot.regressors.base import BaseParameters
from .statistics import Statistics

IDENTIFIED_RSE = 0.1  # a combination is identified when its standard error is below 10 % of its size …
IDENTIFIED_SCALE = 0.05  # … or below 5 % of its size (`sizes`: a physical quantity that is truly near zero)


class Estimate(Protocol):
    """What the decision reads of a fit's estimate (dynid.identify.fit.Estimate): β and its standard errors."""

    beta: np.ndarray
    se: np.ndarray


def sizes(model: RobotModel, base: BaseParameters, stats: Statistics) -> np.ndarray:
    """(rank,) each combination's size, IDENTIFIED_SCALE's yardstick: the CAD value of the combination; for one whose
    representative is an F/T offset, which no CAD gives, the RMS of what its channel reads on the fit's rows, so an
    offset known to a twentieth of its channel's reading is determined whatever its own value (TIAGo's torque offsets,
    ±4 mNm near 0, beside torques of 0.3 Nm)."""
    size = np.abs(base.base(np.nan_to_num(model.cad_parameters(), nan=0.0)))
    offsets = model.layout.span("ft_offset")
    p = stats.p
    gram = stats.gram.sum(axis=0)  # (channels, p+1, p+1): a channel's ‖Wb‖² at [p, p], its offset's ‖W·1‖² at [j, j]
    for i, j in enumerate(base.independent):
        if offsets.start <= j < offsets.stop:
            c = int(np.argmax(gram[:, j, j]))  # the one channel the offset acts on
            if gram[c, j, j] > 0:
                size[i] = np.sqrt(gram[c, p, p] / gram[c, j, j])  # RMS of y in its units, weighted by the rows' W²
    return size


def determined(e: Estimate, cad: np.ndarray) -> np.ndarray:
    """(rank,) bool: combinations whose jackknife error is under 10 % of their value or 5 % of their size (`sizes`),
    past the margin's band (dynid.margins: on the band, not determined, and `borderline_determined` names them)."""
    rse, rsc = _error_ratios(e, cad)
    return (rse < IDENTIFIED_RSE) & ~_near(rse, IDENTIFIED_RSE) | (rsc < IDENTIFIED_SCALE) & ~_near(rsc, IDENTIFIED_SCALE)


def _error_ratios(e: Estimate, cad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    with np.errstate(divide="ignore", invalid="ignore"):
        return (np.where(np.abs(e.beta) > 0, e.se / np.abs(e.beta), np.inf),
                np.where(cad > 0, e.se / cad, np.inf))


def _near(ratio: np.ndarray, threshold: float) -> np.ndarray:
    return np.abs(ratio - threshold) <= BORDERLINE_RTOL * threshold


def borderline_determined(e: Estimate, cad: np.ndarray) -> np.ndarray:
    """(rank,) bool: combinations whose determination sits on its threshold (taken as not determined)."""
    rse, rsc = _error_ratios(e, cad)
    return (_near(rse, IDENTIFIED_RSE) | _near(rsc, IDENTIFIED_SCALE)) & ~determined(e, cad)


def at_bound(base: BaseParameters, model: RobotModel, consistent: dict) -> np.ndarray:
    """(rank,) bool: the base combinations that involve a friction coefficient or a gain at its bound."""
    names = model.layout.names
    bound = {names.index(n) for n in consistent["active"]["friction"] + consistent["active"]["gain"]}
    out = np.array([i in bound for i in base.independent])
    for j, d in enumerate(base.dependent):
        if d in bound:
            out |= base.K[:, j] != 0
    return out
