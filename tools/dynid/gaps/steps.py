"""F/T offset steps (`ft_step`): a sensor offset that changes at change points, piecewise constant per F/T channel.

Where the change points come from:
- declared by the user (`dynid gaps --steps T1,T2,…`, or the robot configuration's `ft_steps`), in the data's own
  seconds: then the offset is free on every segment between them (one `ft_step` per declared point, raised from it
  to the next), and those steps are taken as known: in the model whatever the held-out test says (it is printed);
- else found by ruptures (`KernelCPD`, linear kernel: the least-squares cost of a change in the mean) on each
  sensor's residual of the baseline refit, in noise units, averaged over BIN_S bins: the optimal segmentations with
  1 … MAX_POINTS change points, each point then refined at the kept samples' resolution (`change_points`).
  Candidates: the offset raised on [p_i, p_j) (an episode: it leaves its level and comes back) or on [p_i, end)
  (it stays), for every pair of points. Selection judges them like any effect of the library.

A step acts only on the channels where it lowers the held-out error (`prune`): a channel whose held-out SSE it
does not lower is dropped from it and the rest judged again, so a named step improves every channel it touches.
Each change point is tied to the events near it (`limit_events`): a joint arriving at or leaving its URDF limit
within EVENT_S, what a user checks first (a cable pulled taut in one posture, a cover touching at a stop).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import ruptures as rpt

from ..margins import below
from ..robot.effect_library import LIMIT_TOLERANCE, Candidate, Context
from ..robot.effects import FT_AXES, FT_STEP, Effect, effect_rows, ft_step_columns
from .selection import Design, Trial, columns_on, weighted_columns

BIN_S = 0.05  # s: the residual is averaged over bins this long for the search (a few thousand bins on minutes)
MIN_SEGMENT_S = 1.0  # s: no level is searched that lasts less
MAX_POINTS = 4  # change points per sensor, at most
REFINE_BINS = 2  # a point is refined at the kept samples' resolution within this many bins either side
EVENT_S = 0.5  # s: a limit event this close to a change point is tied to it


def _refine(e: np.ndarray, lo: int, split: int, hi: int, reach: int) -> int:
    """The split in [split − reach, split + reach] that best separates the means of e[lo:s] and e[s:hi]."""
    seg = e[lo:hi]
    n = seg.shape[0]
    csum = np.vstack([np.zeros((1, seg.shape[1])), np.cumsum(seg, axis=0)])
    s = np.arange(max(1, split - reach - lo), min(n - 1, split + reach - lo) + 1)
    if s.size == 0:
        return split
    left, right = csum[s] / s[:, None], (csum[n] - csum[s]) / (n - s)[:, None]
    gain = (s * (n - s) / n) * ((left - right) ** 2).sum(axis=1)  # the cost a change at s removes
    return lo + int(s[np.argmax(gain)])


def change_points(t: np.ndarray, e: np.ndarray, max_points: int = MAX_POINTS) -> list[float]:
    """Change points (s, as `t`) of the mean of e (N, k): the union of ruptures' optimal segmentations with
    1 … max_points points on BIN_S bins (min segment MIN_SEGMENT_S), each refined at the samples' resolution and
    given as the midpoint between the last sample of a level and the first of the next."""
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    per_bin = max(1, int(round(BIN_S / dt)))
    n_bins = n // per_bin
    min_bins = max(2, int(np.ceil(MIN_SEGMENT_S / (per_bin * dt))))
    if n_bins < 2 * min_bins:
        return []
    binned = e[: n_bins * per_bin].reshape(n_bins, per_bin, -1).mean(axis=1)
    search = rpt.KernelCPD(kernel="linear", min_size=min_bins).fit(binned)
    found: set[int] = set()
    for k in range(1, max_points + 1):
        try:
            found.update(search.predict(n_bkps=k)[:-1])
        except rpt.exceptions.BadSegmentationParameters:  # no room for k segments this long
            break
    bins = sorted(found)
    points = []
    for i, b in enumerate(bins):  # refine between the neighbouring points of the union
        lo = (bins[i - 1] if i else 0) * per_bin
        hi = bins[i + 1] * per_bin if i + 1 < len(bins) else n
        s = _refine(e, lo, b * per_bin, hi, REFINE_BINS * per_bin)
        points.append(float((t[s - 1] + t[s]) / 2))
    return sorted(set(points))


def _candidate(ctx: Context, sensor: str, from_s: float, to_s: float | None, axes: Sequence[str] = FT_AXES,
               declared: bool = False) -> Candidate | None:
    """The step on [from_s, to_s) of `sensor`'s `axes`, or None when it is all one level on this run (no sample
    inside, or none outside: the offset itself)."""
    cols = ft_step_columns(ctx.model, sensor, ctx.t + ctx.t0, from_s, to_s, axes)
    inside = cols[:, :, 0].any(axis=1)
    if inside.all() or not inside.any():
        return None
    nonlinear: dict[str, float | str] = {"from_s": from_s, "to_s": "end" if to_s is None else to_s}
    if declared:
        nonlinear["declared"] = "yes"

    def interpret(th: np.ndarray, phi: np.ndarray) -> dict[str, float]:
        out = {"from_s": from_s, **({} if to_s is None else {"to_s": to_s})}
        out.update({f"d{a}": float(v) for a, v in zip(axes, th)})
        force = [abs(float(v)) for a, v in zip(axes, th) if a[0] == "f"]
        torque = [abs(float(v)) for a, v in zip(axes, th) if a[0] == "t"]
        out.update({"force": float(np.linalg.norm(force))} if force else {})  # its size, as limit_step's
        out.update({"torque": float(np.linalg.norm(torque))} if torque else {})
        return out

    return Candidate(FT_STEP, f"sensor {sensor}", nonlinear, cols, tuple(f"d{a}" for a in axes), interpret)


def sensor_residuals(ctx: Context, resid: np.ndarray) -> dict[str, np.ndarray]:
    """Each sensor's (N, 6) rows of the weighted residual `resid` (noise units)."""
    return {s.name: resid[:, 6 * i : 6 * i + 6] for i, s in enumerate(ctx.model.config.ft_sensors)}


def found_candidates(ctx: Context, resid: np.ndarray) -> tuple[list[Candidate], dict[str, list[float]]]:
    """(the steps between the change points ruptures finds in each sensor's residual, the points per sensor)."""
    out: list[Candidate] = []
    points: dict[str, list[float]] = {}
    for sensor, e in sensor_residuals(ctx, resid).items():
        p = change_points(ctx.t + ctx.t0, e)
        points[sensor] = p
        for i, a in enumerate(p):
            for b in [*p[i + 1 :], None]:
                c = _candidate(ctx, sensor, a, b)
                if c is not None:
                    out.append(c)
    return out, points


def declared_candidates(ctx: Context, steps: Sequence[float]) -> list[Candidate]:
    """One step per declared point and sensor, raised from it to the next point (the last: to the end): together a
    free offset on every segment. Points outside this window are left out, as the segment ends they were (a point
    beyond the data made the step before it run "to" it)."""
    t = ctx.t + ctx.t0
    pts = sorted(float(s) for s in steps if t[0] < float(s) < t[-1])
    out = []
    for sensor in (s.name for s in ctx.model.config.ft_sensors):
        for i, a in enumerate(pts):
            c = _candidate(ctx, sensor, a, pts[i + 1] if i + 1 < len(pts) else None, declared=True)
            if c is not None:
                out.append(c)
    return out


def subset(c: Candidate, axes: Sequence[str]) -> Candidate | None:
    """The step `c` on `axes` only (None for no axis): its columns and parameters of those axes."""
    if not axes:
        return None
    keep = [c.labels.index(f"d{a}") for a in axes]
    whole = c.interpret

    def interpret(th: np.ndarray, phi: np.ndarray) -> dict[str, float]:
        full = np.zeros(len(c.labels))
        full[keep] = th
        out = {k: v for k, v in whole(full, phi).items() if not k.startswith("d") or k[1:] in axes}
        out.pop("force", None), out.pop("torque", None)
        force = [abs(out[f"d{a}"]) for a in axes if a[0] == "f"]
        torque = [abs(out[f"d{a}"]) for a in axes if a[0] == "t"]
        out.update({"force": float(np.linalg.norm(force))} if force else {})  # its size, as limit_step's
        out.update({"torque": float(np.linalg.norm(torque))} if torque else {})
        return out

    return replace(c, values=c.values[:, :, keep], labels=tuple(c.labels[k] for k in keep), interpret=interpret)


def prune(design: Design, cand: Candidate, weights: np.ndarray, cur_cv: np.ndarray,
          full: np.ndarray | None = None) -> Trial:
    """The step on the channels whose held-out SSE it lowers, judged again without the others until every channel
    it keeps is lowered (a Trial of gain 0 when none is). Each column of a step is one channel's. (A step the
    selection has accepted stays on the channels it had: a later effect may change them, which `held_out` shows.)"""
    c: Candidate | None = cand
    if full is None:
        full = weighted_columns(cand.values, weights)
    while c is not None:
        E = full if c is cand else design.columns_of(full, [cand.labels.index(label) for label in c.labels])
        channels = columns_on(E)[0]
        cv = design.cv_sse(E)
        before, after = cur_cv[:, channels], cv[:, channels]
        # lowered past the margins' band (dynid.margins): a channel on it is dropped, the conservative answer
        better = {int(ch): below(float(a), float(b))[0]
                  for ch, a, b in zip(channels, after.sum(axis=0), before.sum(axis=0))}
        if all(better.values()):
            return Trial(c, channels, before.sum(axis=1), after.sum(axis=1), float("nan"))
        row = [int(np.flatnonzero(np.abs(c.values[:, :, k]).sum(axis=0))[0]) for k in range(len(c.labels))]
        c = subset(c, [label[1:] for label, r in zip(c.labels, row) if better.get(r, False)])
    channels = columns_on(full)[0]
    before = cur_cv[:, channels].sum(axis=1)
    return Trial(cand, channels, before, before, float("nan"))


def limit_events(ctx: Context) -> list[dict]:
    """Every time (the data's own seconds) a joint arrives at or leaves one of its URDF limits (within 1°)."""
    out = []
    for k, joint in enumerate(ctx.model.config.joints):
        for limit in ctx.model.joint_limits[joint]:
            if not np.isfinite(limit) or abs(limit) > 1e3:
                continue
            at = np.abs(ctx.sig.q[:, k] - limit) <= LIMIT_TOLERANCE
            for i in np.flatnonzero(np.diff(at.astype(np.int8))):
                out.append({"joint": joint, "limit_deg": float(np.round(np.rad2deg(limit), 3)),
                            "event": "arrives" if at[i + 1] else "leaves",
                            "at_s": float((ctx.t[i] + ctx.t[i + 1]) / 2 + ctx.t0)})
    return out


def tied_events(events: list[dict], at_s: float) -> list[dict]:
    """The limit events within EVENT_S of a change point, nearest first."""
    near = [e for e in events if abs(e["at_s"] - at_s) <= EVENT_S]
    return sorted(near, key=lambda e: abs(e["at_s"] - at_s))


def describe(effect: dict, events: list[dict], held_out: dict[str, tuple[float, float]]) -> dict:
    """What the gap result adds to a named `ft_step`: each change point with the limit events tied to it, and the
    held-out RMS (× noise) of each channel it touches, before and after the fix."""
    p = effect["parameters"]
    points = [("from_s", p["from_s"])] + ([("to_s", p["to_s"])] if "to_s" in p else [])
    return {"change_points": [{"at_s": v, "events": tied_events(events, v)} for _, v in points],
            "held_out": {ch: {"before_over_noise": b, "after_over_noise": a} for ch, (b, a) in held_out.items()}}


def format_step(effect: dict) -> str:
    """One line: when the offset steps, by how much per axis, the events at those times, and the held-out gain."""
    p = effect["parameters"]
    sizes = ", ".join(f"{a} {p[f'd{a}']:+.4g} {'N' if a[0] == 'f' else 'Nm'}" for a in FT_AXES if f"d{a}" in p)

    def at(point: dict) -> str:
        ev = "; ".join(f"{e['joint']} {'reaches' if e['event'] == 'arrives' else 'leaves'} its limit "
                       f"{e['limit_deg']:g}° at {e['at_s']:.2f} s" for e in point["events"][:2])
        return f"{point['at_s']:.2f} s" + (f" ({ev})" if ev else "")

    cps = effect["change_points"]
    when = f"from {at(cps[0])} to {at(cps[1])}" if len(cps) > 1 else f"from {at(cps[0])} to the end"
    held = ", ".join(f"{ch.rsplit('.', 1)[1]} {v['before_over_noise']:.2f}→{v['after_over_noise']:.2f}×"
                     for ch, v in effect["held_out"].items())
    return f"  the offset steps {when}: {sizes}; held-out {held}"


def offset_levels(effects: list[dict]) -> dict[str, list[dict]]:
    """Per sensor, the named steps (those in the model) summed into one piecewise-constant offset against its level
    outside every step: [{from_s, to_s (None: the end), d<axis>…}] for each segment where it differs."""
    out: dict[str, list[dict]] = {}
    for sensor in sorted({e["where"].partition(" ")[2] for e in effects if e["name"] == FT_STEP and e["in_model"]}):
        steps = [e["parameters"] for e in effects if e["name"] == FT_STEP and e["in_model"]
                 and e["where"] == f"sensor {sensor}"]
        edges = sorted({p["from_s"] for p in steps} | {p["to_s"] for p in steps if "to_s" in p})
        segments = []
        for a, b in zip(edges, [*edges[1:], None]):
            level = {f"d{x}": sum(p.get(f"d{x}", 0.0) for p in steps
                                  if p["from_s"] <= a and (b is not None and b <= p.get("to_s", np.inf)
                                                           or "to_s" not in p))
                     for x in FT_AXES}
            level = {k: float(v) for k, v in level.items() if v != 0.0}
            if level:
                segments.append({"from_s": float(a), "to_s": None if b is None else float(b), **level})
        out[sensor] = segments
    return out


def format_levels(levels: dict[str, list[dict]]) -> list[str]:
    """One line per sensor: its offset on each segment, against its level outside the steps."""
    lines = []
    for sensor, segments in levels.items():
        parts = []
        for s in segments:
            to = "the end" if s["to_s"] is None else f"{s['to_s']:.2f} s"
            sizes = ", ".join(f"{a} {s[f'd{a}']:+.4g}" for a in FT_AXES if f"d{a}" in s)
            parts.append(f"{s['from_s']:.2f} s to {to}: {sizes}")
        lines.append(f"offset of {sensor} against its level outside the steps (N, Nm): " + "; ".join(parts))
    return lines


def cad_offsets_with_steps(ctx: Context, A: np.ndarray, b: np.ndarray, w: np.ndarray,
                           effects: Sequence[Effect]) -> np.ndarray | None:
    """The F/T offsets that fit the CAD inertia best on the run with the named steps taken out (the augmented
    model's `cad_ft_offsets`: validate's CAD column gets the same steps), or None when no step is named."""
    steps = [e for e in effects if e.kind == FT_STEP]
    if not steps:
        return None
    model = ctx.model
    layout = model.layout
    phi = np.nan_to_num(model.cad_parameters(), nan=0.0)
    inertial = layout.span("inertial")
    rest = b - A[:, :, inertial] @ phi[inertial] - effect_rows(model, steps, ctx.sig, ctx.t + ctx.t0)
    out = np.zeros(len(layout))
    for i, s in enumerate(model.config.ft_sensors):
        for k in range(6):
            live = w[:, 6 * i + k] > 0
            level = float(rest[live, 6 * i + k].mean()) if live.any() else 0.0
            out[layout.block("ft_offset", s.name).start + k] = level
    return out
