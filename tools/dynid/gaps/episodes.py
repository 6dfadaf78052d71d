"""When an unexplained residual steps: the episodes in which a channel's residual sits at another level, and the
joints held still during them.

A residual the library cannot name is still located: its moving mean (one second, in noise units) is split into
two levels (1-D two-means); when the levels differ by more than STEP_NOISE noise and each holds a fair share of
the run, each contiguous run of the rarer level lasting MIN_EPISODE_S or more is an episode. For each episode,
the joints that hold still inside it (range < HELD_DEG) but move outside it (range > MOVING_DEG) are named with
their position, and whether that is their URDF limit: what a user checks first (a joint on its stop, a posture
that loads a cable).
"""

from __future__ import annotations

import numpy as np

from ..robot.model import RobotModel
from ..robot.outputs import output_channels

WINDOW_S = 1.0
STEP_NOISE = 3.0  # levels closer than this (noise units) are no step
MIN_SHARE = 0.05
MIN_EPISODE_S = 2.0
HELD_DEG, MOVING_DEG, AT_LIMIT_DEG = 3.0, 10.0, 1.0
MAX_CHANNELS = 4  # the worst channels only: the rest of a sensor usually steps with them
MAX_EPISODES = 2  # per channel, the longest


def _two_means(x: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Labels (True = upper level) and the two levels of a 1-D two-means split."""
    lo, hi = float(np.percentile(x, 10)), float(np.percentile(x, 90))
    for _ in range(50):
        upper = np.abs(x - hi) < np.abs(x - lo)
        if upper.all() or not upper.any():
            break
        new_lo, new_hi = float(x[~upper].mean()), float(x[upper].mean())
        if new_lo == lo and new_hi == hi:
            break
        lo, hi = new_lo, new_hi
    return np.abs(x - hi) < np.abs(x - lo), lo, hi


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the True runs."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def residual_episodes(model: RobotModel, t: np.ndarray, q: np.ndarray, resid: np.ndarray,
                      over_noise: np.ndarray) -> list[dict]:
    """Episodes of the channels left above 3× noise (`over_noise`, per output channel), worst first.

    `resid` (N, n_out): weighted residuals (noise units, 0 where a row is left out); `t` s from the run's start.
    """
    out: list[dict] = []
    channels = output_channels(model)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    width = max(1, int(round(WINDOW_S / dt)))
    limits = model.joint_limits
    for c in [int(c) for c in np.argsort(-over_noise) if over_noise[c] > STEP_NOISE][:MAX_CHANNELS]:
        e = resid[:, c]
        if t.size < 4 * width:
            continue
        kernel = np.ones(width) / width
        level = np.convolve(e, kernel, mode="same")
        upper, lo, hi = _two_means(level)
        share = float(upper.mean())
        if hi - lo < STEP_NOISE or not MIN_SHARE <= share <= 1 - MIN_SHARE:
            continue
        # The fitted offset centres the residual, so either level may be "the step": a run that starts and ends
        # inside the window is the episode (the run's start and end set what is usual); else the rarer level's runs.
        runs = [(a, b) for mask in (upper, ~upper) for a, b in _runs(mask) if a > 0 and b < t.size]
        if not runs:
            runs = _runs(upper if share <= 0.5 else ~upper)
        for a, b in sorted(runs, key=lambda r: r[0] - r[1])[:MAX_EPISODES]:
            inside = np.zeros(t.size, bool)
            inside[a:b] = True
            if t[b - 1] - t[a] < MIN_EPISODE_S or abs(level[inside].mean() - level[~inside].mean()) < STEP_NOISE:
                continue
            core = np.zeros(t.size, bool)  # the episode's middle 80 %: its ends blur with the one-second mean
            core[a + (b - a) // 10 : b - (b - a) // 10] = True
            held = []
            for k, joint in enumerate(model.config.joints):
                qi, qo = np.rad2deg(q[core, k]), np.rad2deg(q[~inside, k])
                if np.ptp(qi) < HELD_DEG and qo.size and np.ptp(qo) > MOVING_DEG:
                    lim = [float(np.rad2deg(v)) for v in limits[joint] if np.isfinite(v)
                           and abs(np.rad2deg(v) - np.median(qi)) <= AT_LIMIT_DEG + np.ptp(qi)]
                    held.append({"joint": joint, "from_deg": float(qi.min()), "to_deg": float(qi.max()),
                                 "limit_deg": lim[0] if lim else None})
            out.append({"channels": [channels[c].name], "from_s": float(t[a]), "to_s": float(t[b - 1]),
                        "level_inside": float(level[inside].mean()), "level_outside": float(level[~inside].mean()),
                        "held_joints": held})
    return _merged(out)


def _merged(episodes: list[dict]) -> list[dict]:
    """One entry per episode: channels whose episodes overlap by 80 % or more are listed together."""
    merged: list[dict] = []
    for ep in episodes:
        for m in merged:
            overlap = min(m["to_s"], ep["to_s"]) - max(m["from_s"], ep["from_s"])
            union = max(m["to_s"], ep["to_s"]) - min(m["from_s"], ep["from_s"])
            if union > 0 and overlap / union >= 0.8:
                m["channels"] += ep["channels"]
                break
        else:
            merged.append(ep)
    return merged


def format_episode(ep: dict) -> str:
    held = "; ".join(
        f"{h['joint']} held at {h['from_deg']:.1f}…{h['to_deg']:.1f}°"
        + (f" (its limit {h['limit_deg']:g}°)" if h["limit_deg"] is not None else "")
        for h in ep["held_joints"]
    ) or "no joint held still"
    return (f"{', '.join(ep['channels'])}: the residual steps from {ep['from_s']:.1f} s to {ep['to_s']:.1f} s "
            f"({ep['level_outside']:+.1f} → {ep['level_inside']:+.1f}× noise, first channel); there {held}")
