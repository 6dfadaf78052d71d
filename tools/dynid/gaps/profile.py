"""Where a channel's residual grows, binned: by the speed of each joint it depends on (near zero … fast), at that
joint's direction reversals, by its position, and over time; before and after the fix, in noise units (1.0 is
the channel's noise floor). The figures (dynid.report.gaps_figures) plot exactly these numbers from the JSON."""

from __future__ import annotations

import numpy as np

from ..robot.effect_library import Context
from ..robot.model import RobotModel
from ..robot.outputs import output_channels

SPEED_EDGES = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0, np.inf)  # rad/s: near zero … high speed
POSITION_BINS = 8
TIME_BINS = 10
REVERSAL_S = 0.05  # a sample within this of a sign change of q̇ is "at a reversal"
MIN_COUNT = 10  # fewer samples in a bin: no value (null)


def speed_labels() -> list[str]:
    e = SPEED_EDGES
    return [f"<{e[1]:g}"] + [f"{a:g}-{b:g}" for a, b in zip(e[1:-2], e[2:-1])] + [f"≥{e[-2]:g}"]


def _rms(x: np.ndarray, masks: list[np.ndarray]) -> tuple[list[float | None], list[int]]:
    out, counts = [], []
    for m in masks:
        n = int(m.sum())
        counts.append(n)
        out.append(float(np.sqrt(np.mean(x[m] ** 2))) if n >= MIN_COUNT else None)
    return out, counts


def _reversals(dq: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Samples within REVERSAL_S of a sign change of dq (the moving sign: zeros carry the last one)."""
    s = np.sign(dq)
    idx = np.flatnonzero(s != 0)
    if idx.size < 2:
        return np.zeros(dq.shape, bool)
    filled = s[idx][np.clip(np.searchsorted(idx, np.arange(dq.size), side="right") - 1, 0, idx.size - 1)]
    flips = t[1:][filled[1:] != filled[:-1]]
    if flips.size == 0:
        return np.zeros(dq.shape, bool)
    k = np.clip(np.searchsorted(flips, t), 1, flips.size) - 1
    near = np.minimum(np.abs(t - flips[k]), np.abs(t - flips[np.minimum(k + 1, flips.size - 1)]))
    return near <= REVERSAL_S


def channel_joints(model: RobotModel, channel_row: int) -> list[str]:
    """The joints a channel's row depends on: every joint for an F/T row, the joints of its group otherwise."""
    cfg = model.config
    nft = 6 * len(cfg.ft_sensors)
    if channel_row < nft:
        return list(cfg.joints)
    start = nft
    for g in cfg.actuation:
        if start <= channel_row < start + len(g.joints):
            return list(g.joints)
        start += len(g.joints)
    return list(cfg.joints)


def profile(model: RobotModel, ctx: Context, before: np.ndarray, after: np.ndarray, weights: np.ndarray) -> dict:
    """{channel: {joints: {joint: {speed, reversal, position}}, time}} with "before"/"after" RMS (noise units)
    and sample counts per bin; rows at rest (weight 0) left out, as the fit leaves them out."""
    t = ctx.t
    out: dict = {"speed_bins": speed_labels(), "speed_edges": [float(e) for e in SPEED_EDGES[:-1]] + ["inf"],
                 "reversal_window_s": REVERSAL_S, "channels": {}}
    q, dq = ctx.sig.q, ctx.sig.dq
    time_edges = np.linspace(t[0], t[-1], TIME_BINS + 1)
    for c, ch in enumerate(output_channels(model)):
        live = weights[:, c] > 0
        if not live.any():
            continue
        entry: dict = {"joints": {}}
        for j in channel_joints(model, c):
            k = model.config.joints.index(j)
            v = np.abs(dq[:, k])
            speed = [live & (v >= a) & (v < b) for a, b in zip(SPEED_EDGES[:-1], SPEED_EDGES[1:])]
            rev = _reversals(dq[:, k], t)
            lo, hi = float(q[live, k].min()), float(q[live, k].max())
            pe = np.linspace(lo, hi, POSITION_BINS + 1)
            pos = [live & (q[:, k] >= a) & ((q[:, k] < b) | (i == POSITION_BINS - 1))
                   for i, (a, b) in enumerate(zip(pe[:-1], pe[1:]))]
            rv = [live & rev, live & ~rev]
            row: dict = {"position_edges": pe.tolist()}
            for name, masks in (("speed", speed), ("reversal", rv), ("position", pos)):
                b_rms, counts = _rms(before[:, c], masks)
                a_rms, _ = _rms(after[:, c], masks)
                row[name] = {"before": b_rms, "after": a_rms, "count": counts}
            entry["joints"][j] = row
        tm = [live & (t >= a) & ((t < b) | (i == TIME_BINS - 1))
              for i, (a, b) in enumerate(zip(time_edges[:-1], time_edges[1:]))]
        b_rms, counts = _rms(before[:, c], tm)
        a_rms, _ = _rms(after[:, c], tm)
        entry["time"] = {"edges_s": time_edges.tolist(), "before": b_rms, "after": a_rms, "count": counts}
        out["channels"][ch.name] = entry
    return out
