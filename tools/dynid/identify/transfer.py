"""Why an identified model predicts worse than CAD on a validation run: what `dynid validate` names beside Table II.

Two causes the data can show, each with its joints or its times:
- postures the fit never saw: joints that the validation run takes beyond the range they had in the fit's data
  (the model file's `data[].joint_range_deg`), with the share of samples outside; an unconstrained fit determines
  only the parameter combinations those postures excite, and is extrapolated elsewhere;
- the model's F/T offset steps (`ft_step`, named by `dynid gaps`, taken as known by `dynid fit --steps-from`):
  their times and sizes, and whether the validation run lies outside them (where their size is what the fit did
  not see).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..robot.effects import FT_AXES, FT_STEP
from .model_file import IdentifiedModel

MARGIN_DEG = 1.0  # a sample within this of the fit's range is inside it
MARGIN_M = 1e-3  # ... for a prismatic joint (its metres)
MIN_SHARE = 0.05  # a joint outside the fit's range on fewer samples than this is not named
AT_LIMIT_DEG = 1.0
MAX_PRINTED = 4  # joints named in the text; --json has them all


def worse_than_cad(tables: dict[str, Any]) -> list[dict]:
    """Every sensor and quantity (force, torque) whose identified mean error norm is above CAD's."""
    out = []
    for sensor, table in tables.items():
        for what in ("force", "torque"):
            i, c = table["identified"][what]["mean"], table["cad"][what]["mean"]
            if c > 0 and i > c:
                out.append({"sensor": sensor, "quantity": what, "identified": i, "cad": c})
    return out


def fit_spans_deg(identified: IdentifiedModel, joints: tuple[str, ...]) -> dict[str, tuple[float, float]] | None:
    """Each joint's range over the fit's data (the union of its runs' `joint_range_deg`; a joint no run records is
    left out); None when a run records none, or the inertias came from another model's data."""
    gaps = identified.gaps
    ranges = [d.joint_range_deg for d in identified.data]
    if (gaps is not None and gaps.given_model) or not ranges or any(r is None for r in ranges):
        return None
    spans = {j: [r[j] for r in ranges if j in r] for j in joints}
    return {j: (min(s[0] for s in v), max(s[1] for s in v)) for j, v in spans.items() if v}


def fit_ranges(identified: IdentifiedModel, joints: tuple[str, ...]) -> np.ndarray | None:
    """(joints, 2) rad, or m for a prismatic joint: `fit_spans_deg` widened by MARGIN_DEG (MARGIN_M for a prismatic
    joint), as `outside_fit` takes it; None where a joint's range is not recorded. What the monitor's coefficient file
    carries (fit_range). (`joint_range_deg` holds a prismatic joint's metres through the same rad2deg as the others'.)"""
    spans = fit_spans_deg(identified, joints)
    if spans is None or len(spans) < len(joints):
        return None
    prismatic = np.array(identified.robot_model.prismatic, bool)
    margin = np.where(prismatic, MARGIN_M, np.deg2rad(MARGIN_DEG))[:, None] * np.array([-1.0, 1.0])
    return np.deg2rad([spans[j] for j in joints]) + margin


def outside_fit(identified: IdentifiedModel, joints: tuple[str, ...], q: np.ndarray,
                limits: dict[str, tuple[float, float]]) -> list[dict] | None:
    """The joints this run (q, rad) takes beyond their range in the fit's data, most samples outside first; None
    when the model file does not record the fit's ranges, or its inertias came from another model's data."""
    spans = fit_spans_deg(identified, joints)
    if spans is None:
        return None
    prismatic = identified.robot_model.prismatic
    out = []
    for k, joint in enumerate(joints):
        if joint not in spans:
            continue
        lo, hi = spans[joint]
        here = np.rad2deg(q[:, k])
        # fit_ranges' margin (the monitor's): a prismatic joint's metres went through the same rad2deg
        margin = float(np.rad2deg(MARGIN_M)) if prismatic[k] else MARGIN_DEG
        share = float(np.mean((here < lo - margin) | (here > hi + margin)))
        if share < MIN_SHARE:
            continue
        limit = [float(np.round(np.rad2deg(v), 3)) for v in limits.get(joint, ()) if np.isfinite(v)
                 and (abs(np.rad2deg(v) - lo) <= AT_LIMIT_DEG or abs(np.rad2deg(v) - hi) <= AT_LIMIT_DEG)]
        out.append({"joint": joint, "fit_from_deg": lo, "fit_to_deg": hi, "here_from_deg": float(here.min()),
                    "here_to_deg": float(here.max()), "outside_share": share,
                    "fit_at_limit_deg": limit[0] if limit else None})
    return sorted(out, key=lambda d: -d["outside_share"])


def step_effects(identified: IdentifiedModel, t: np.ndarray) -> list[dict]:
    """The model's F/T steps: times, sizes, and the share of this run's samples inside each."""
    out = []
    for e in identified.named_effects or ():
        if e.kind != FT_STEP:
            continue
        p = e.parameters
        inside = (t >= p["from_s"]) & (t < p.get("to_s", np.inf))
        out.append({"where": e.where, "from_s": p["from_s"], "to_s": p.get("to_s"),
                    **{f"d{a}": p[f"d{a}"] for a in FT_AXES if f"d{a}" in p}, "inside_share": float(inside.mean())})
    return out


def why_worse(identified: IdentifiedModel, tables: dict[str, Any], joints: tuple[str, ...], q: np.ndarray,
              t: np.ndarray, limits: dict[str, tuple[float, float]]) -> dict | None:
    """validate's `why_worse_than_cad` (docs/formats.md): None when identified is at or below CAD everywhere."""
    worse = worse_than_cad(tables)
    if not worse:
        return None
    return {"worse": worse, "fit_data": [{"path": d.path, "window": list(d.window) if d.window else None}
                                         for d in identified.data],
            "outside_fit": outside_fit(identified, joints, q, limits), "ft_steps": step_effects(identified, t)}


def postures_text(outside: list[dict]) -> str:
    """`outside_fit`'s joints, the first MAX_PRINTED: their range here against the fit's, the share of samples outside."""
    parts = []
    for o in outside[:MAX_PRINTED]:
        held = f", at its limit {o['fit_at_limit_deg']:g}°" if o["fit_at_limit_deg"] is not None else ""
        parts.append(f"{o['joint']} here {o['here_from_deg']:.1f}…{o['here_to_deg']:.1f}° against "
                     f"{o['fit_from_deg']:.1f}…{o['fit_to_deg']:.1f}° in the fit{held} "
                     f"({100 * o['outside_share']:.0f} % of samples outside)")
    more = f"; {len(outside) - MAX_PRINTED} more joints (--json)" if len(outside) > MAX_PRINTED else ""
    return "; ".join(parts) + more


def format_why(why: dict) -> list[str]:
    """The lines `dynid validate` prints under Table II."""
    worse = ", ".join(f"{w['sensor']} {w['quantity']} ({w['identified']:.4g} against CAD's {w['cad']:.4g})"
                      for w in why["worse"])
    lines = [f"  identified worse than CAD: {worse}"]
    windows = "; ".join(f"{d['path']}" + (f" {d['window'][0]:g}–{d['window'][1]:g} s" if d["window"] and
                                          None not in d["window"] else "") for d in why["fit_data"])
    outside = why["outside_fit"]
    if outside is None:
        lines.append("    (the model file does not record the postures of the data its inertias were fitted on)")
    elif outside:
        lines.append(f"    postures the fit never saw (fitted on {windows}): " + postures_text(outside)
                     + ": the fit determined only what its postures excite, and is extrapolated here")
    for s in why["ft_steps"]:
        to = "the end" if s["to_s"] is None else f"{s['to_s']:.2f} s"
        sizes = ", ".join(f"{a} {s[f'd{a}']:+.4g}" for a in FT_AXES if f"d{a}" in s)
        lines.append(f"    the model's F/T offset step on {s['where'].partition(' ')[2]} from {s['from_s']:.2f} s to {to} "
                     f"({sizes}; N, Nm) covers {100 * s['inside_share']:.0f} % of these samples; applied to CAD too")
    return lines
