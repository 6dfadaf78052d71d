"""Which contacts the sensors can see: the T² a contact alone adds, from the simulated plant's ground truth.

The model's residual e = y − ŷ(q, q̇, q̈) of a contact is the contact itself, whatever the controller does
with it: on the F/T channels the contact wrench (distal contacts), on the motor inputs minus its joint torques
(torque the motors need not give) through the row maps, divided by the gains. The plant records both (truth.npz: ``extra/contact.<sensor>.<c>``
and ``extra/contact.tau.<joint>``). A contact whose own T², over the channels the detector uses at that sample
(moving rows), never stays above T²_α for the detector's debounce cannot be told from the noise at that
threshold by this model: a push through a joint's axis gives no torque at all, and while a joint rests its
static friction takes any torque inside its band.

`scripts/main`'s summary and the end-to-end tests use it to split the episodes the monitor missed into those it
could see and those nothing in these sensors shows.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from ..io.dataset import contact_episodes
from ..robot.model import RobotModel
from ..robot.regressors.stack import joint_row_shares, row_channels, rows_at_rest

FT_FIELDS = ("fx", "fy", "fz", "tx", "ty", "tz")


def contact_residuals(model: RobotModel, divisors: np.ndarray, truth: Mapping[str, np.ndarray]) -> np.ndarray:
    """(N, n_out) what the recorded contact adds to e, channel by channel; `divisors`: each channel's gain."""
    cfg = model.config
    try:
        tau = np.column_stack([np.asarray(truth[f"extra/contact.tau.{j}"], float) for j in cfg.joints])
        ft = {s.name: np.column_stack([np.asarray(truth[f"extra/contact.{s.name}.{c}"], float) for c in FT_FIELDS])
              for s in cfg.ft_sensors}
    except KeyError as e:
        raise DataError(f"the ground truth has no contact record {e} (not a simulated contact run?)") from None
    out = np.zeros((tau.shape[0], len(row_channels(model))))
    for c, share in joint_row_shares(model).values():  # joint torques reach the rows through L
        out -= np.outer(tau[:, c], share)  # torque the motors need not give
    n_ft = 6 * len(cfg.ft_sensors)
    out[:, n_ft:] /= np.asarray(divisors, float)[n_ft:]
    for i, s in enumerate(cfg.ft_sensors):
        out[:, 6 * i : 6 * i + 6] = ft[s.name]
    return out


@dataclass(frozen=True)
class EpisodeVisibility:
    start: int  # samples
    end: int
    peak_t2: float  # the largest T² the contact alone adds, over the channels in use at each sample
    longest_run: int  # samples in a row with that T² above T²_α
    visible: bool  # longest_run ≥ the debounce
    # Samples from the start to the last of the first `debounce` in a row above T²_α (−1 if never): the earliest onset
    # a detector with this Λ, T²_α and debounce could confirm, were its residual free of noise and of filter lag
    earliest: int = -1

    def as_dict(self) -> dict:
        return {"start": self.start, "end": self.end, "peak_t2": self.peak_t2, "longest_run": self.longest_run,
                "visible": self.visible, "earliest": self.earliest}


def episode_visibility(contact: np.ndarray, signal: np.ndarray, active: np.ndarray, variance: np.ndarray,
                       threshold: float, debounce: int) -> list[EpisodeVisibility]:
    """Per contact episode: can the detector (Λ = `variance`, T²_α = `threshold`, `debounce` samples) see the
    contact's own residual `signal` (N, n_out) on the channels `active` (N, n_out) at each sample?"""
    t2 = np.sum(np.where(active, signal**2 / np.asarray(variance, float), 0.0), axis=1)
    out = []
    for a, b in contact_episodes(contact):
        runs = contact_episodes(t2[a:b] > threshold)
        best = max((e - s for s, e in runs), default=0)
        earliest = next((s + debounce - 1 for s, e in runs if e - s >= debounce), -1)
        out.append(EpisodeVisibility(int(a), int(b), float(t2[a:b].max()), best, best >= debounce, int(earliest)))
    return out


def monitor_visibility(model: RobotModel, coef, truth: Mapping[str, np.ndarray]) -> list[EpisodeVisibility]:
    """The episodes of a simulated contact run that the monitor's detector (a coefficient file: Λ, T²_α through
    its online filter, the debounce, the gates) can see, with the channels in use decided on the true q̇; for a
    file that runs the momentum observer, `observer_visibility`."""
    if "contact" not in truth or "dq" not in truth:
        raise DataError("the ground truth has no contact or q̇ record (not a simulated contact run?)")
    if getattr(coef, "residual", 0) == 1:
        return observer_visibility(model, coef, truth)
    signal = contact_residuals(model, np.asarray(coef.divisor, float), truth)
    active = ~rows_at_rest(model, np.asarray(truth["dq"], float), float(coef.min_speed))
    return episode_visibility(np.asarray(truth["contact"]), signal, active, np.asarray(coef.residual_variance, float),
                              float(coef.threshold), int(coef.debounce_on))


def observer_visibility(model: RobotModel, coef, truth: Mapping[str, np.ndarray]) -> list[EpisodeVisibility]:
    """The same for the momentum observer: the contact's own residual in row units (−L τ_contact, the F/T wrench)
    through the observer's low-pass, outside the file's static-friction band on the rows of resting coordinates
    (true q̇), against the observer's Λ and T²_α."""
    from .momentum import band_at_rest, first_order

    dq = np.asarray(truth["dq"], float)
    t = np.arange(dq.shape[0]) * float(coef.sample_period)
    r = first_order(t, contact_residuals(model, np.ones(len(coef.divisor)), truth), float(coef.observer_bandwidth))
    band = {("joint_friction", j): tuple(b) for j, b in zip(coef.joint_names, coef.joint_band)}
    band.update({("motor_friction", m): tuple(b) for m, b in zip(coef.motor_names, coef.motor_band)})
    rest, lo, hi = band_at_rest(model, dq, band, float(coef.min_speed))
    e = np.where(rest, r - np.clip(r, lo, hi), r)
    return episode_visibility(np.asarray(truth["contact"]), e, np.ones(e.shape, bool),
                              np.asarray(coef.observer_variance, float), float(coef.observer_threshold),
                              int(coef.debounce_on))
