"""Hotelling T² contact detection on the model's residuals (DESIGN.md §3), two variants.

- ``paper`` (Traversaro et al. 2013): T² = eᵀ Λ⁻¹ e over every output, Λ = diag of the residual variances on
  the identification data, threshold T²_α = n(N−1)/(N−n)·F(n, N−n; α), n = dim(e) by default (the paper writes
  n = ν; `n_mode="nu"`). That F threshold assumes independent Gaussian residuals; the PWM residuals are neither:
  at velocity reversals and while a joint rests, Coulomb friction flips or static friction holds what the
  model cannot say, so they are heavy-tailed and autocorrelated, and the threshold does not keep its promise.
- ``calibrated`` (dynid's default): a motor channel whose row is at rest (a joint or motor of it slower than
  `min_speed`, `dynid.regressors.stack.rows_at_rest`) is left out of the sum for that sample, Λ of the motor
  channels comes from moving samples only, and the threshold is the empirical α-quantile of this T² on the
  contact-free identification data: a false-positive rate of 1 − α by construction, whatever the residuals'
  distribution, as long as new contact-free data look like the identification data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats as scipy_stats

from .model import RobotModel
from .outputs import output_channels
from .regressors.stack import rows_at_rest

ALPHA = 0.99
VARIANTS: tuple[str, ...] = ("calibrated", "paper")


def f_threshold(n: int, N: int, alpha: float) -> float:
    """T²_α = n(N−1)/(N−n) · F(n, N−n; α)."""
    return float(n * (N - 1) / (N - n) * scipy_stats.f.ppf(alpha, n, N - n))


@dataclass(frozen=True)
class Detector:
    variant: str
    variance: np.ndarray  # Λ (n_out,)
    threshold: float
    alpha: float
    min_speed: float
    n: int  # the n of the F threshold (paper) or dim(e)

    def active(self, model: RobotModel, dq: np.ndarray) -> np.ndarray:
        """(N, n_out) bool: the channels that enter T² at each sample."""
        if self.variant == "paper":
            return np.ones((dq.shape[0], len(self.variance)), dtype=bool)
        return ~rows_at_rest(model, dq, self.min_speed)

    def t2(self, model: RobotModel, e: np.ndarray, dq: np.ndarray) -> np.ndarray:
        return np.sum(np.where(self.active(model, dq), e**2 / self.variance, 0.0), axis=1)

    def as_dict(self) -> dict:
        return {"variant": self.variant, "variance": self.variance.tolist(), "threshold": self.threshold,
                "alpha": self.alpha, "min_speed": self.min_speed, "n": self.n}

    @classmethod
    def from_dict(cls, d: dict) -> Detector:
        return cls(d["variant"], np.asarray(d["variance"], float), float(d["threshold"]), float(d["alpha"]),
                   float(d["min_speed"]), int(d["n"]))


def calibrate(model: RobotModel, e: np.ndarray, dq: np.ndarray, alpha: float = ALPHA, min_speed: float = 0.01,
              n_mode: str = "dim", nu: int | None = None) -> dict[str, Detector]:
    """Both detectors from contact-free residuals e (N, n_out) of the identification data."""
    N, n_out = e.shape
    n = n_out if n_mode == "dim" else int(nu or n_out)
    paper = Detector("paper", e.var(axis=0), f_threshold(n, N, alpha), alpha, min_speed, n)
    rest = rows_at_rest(model, dq, min_speed)
    moving = np.where(rest, np.nan, e)
    variance = np.nanmean(moving**2, axis=0)
    variance = np.where(np.isfinite(variance) & (variance > 0), variance, e.var(axis=0))
    draft = Detector("calibrated", variance, np.inf, alpha, min_speed, n_out)
    threshold = float(np.quantile(draft.t2(model, e, dq), alpha))
    return {"paper": paper, "calibrated": Detector("calibrated", variance, threshold, alpha, min_speed, n_out)}


# ------------------------------------------------------------------------------------------------------------
# Scoring against the skin's ground truth


def episodes(contact: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) sample ranges where contact != 0."""
    c = np.concatenate([[0], (contact != 0).astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(c))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def score(t: np.ndarray, t2: np.ndarray, threshold: float, contact: np.ndarray | None,
          side: np.ndarray | None = None) -> dict:
    """TPR, FPR (per sample), ROC and AUC, detection delays per episode, TPR per side of the F/T sensor."""
    from sklearn.metrics import roc_auc_score, roc_curve

    alarm = t2 > threshold
    out: dict = {"threshold": threshold, "alarm_rate": float(alarm.mean()), "samples": int(t2.size)}
    if contact is None:
        out["fpr"] = out["alarm_rate"]
        return out
    truth = contact != 0
    out["contact_fraction"] = float(truth.mean())
    out["tpr"] = float(alarm[truth].mean()) if truth.any() else None
    out["fpr"] = float(alarm[~truth].mean()) if (~truth).any() else None
    if truth.any() and (~truth).any():
        fpr, tpr, _ = roc_curve(truth, t2)
        keep = np.unique(np.linspace(0, fpr.size - 1, min(fpr.size, 400)).round().astype(int))
        out["auc"] = float(roc_auc_score(truth, t2))
        out["roc"] = {"fpr": fpr[keep].tolist(), "tpr": tpr[keep].tolist()}
    delays, missed = [], 0
    for a, b in episodes(contact):
        hits = np.flatnonzero(alarm[a:b])
        if hits.size:
            delays.append(float(t[a + hits[0]] - t[a]))
        else:
            missed += 1
    out["episodes"] = len(delays) + missed
    out["episodes_detected"] = len(delays)
    out["delay_s"] = {"median": float(np.median(delays)) if delays else None,
                      "p90": float(np.percentile(delays, 90)) if delays else None}
    if side is not None:
        out["tpr_by_side"] = {}
        for name, code in (("distal", 1.0), ("proximal", -1.0)):
            sel = truth & (side == code)
            out["tpr_by_side"][name] = float(alarm[sel].mean()) if sel.any() else None
    return out


def channel_names(model: RobotModel) -> list[str]:
    return [o.name for o in output_channels(model)]
