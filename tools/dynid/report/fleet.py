"""`dynid fleet`: robots of one kind compared parameter by parameter, the one that stands out named, one HTML page.

Each robot has its own model (`dynid fit` on its runs). What is compared are the base combinations that every robot's
fit shares, word for word (the same runs' structure: on one kind of robot driven the same way, all of them), each
robot's value with its standard error.

**The rule.** For robot r and a group of parameters g (one joint's or motor's four friction coefficients, one motor's
gain, one F/T sensor's six offsets), each coefficient k is set against the *other* robots: their median m and robust
spread s = 1.4826 · MAD (a fleet of a dozen has no room for a variance that one worn joint would inflate), on a log
scale for what is positive by nature (friction and gains: a wear or a wrong gain is a factor, and the fleet's spread
is proportional), else as it is (offsets). z_k = (x_rk − m_k) / √(s_k² + se_rk²), and the group's statistic is
S = Σ_k z_k / √n (every coefficient of a worn joint moves the same way, which a sum adds up and a maximum does
not). A robot is named when |S| exceeds the two-sided Bonferroni bound for the whole comparison,
Φ⁻¹(1 − α / (2 · robots · groups)) with α = 1 %: under a fleet whose robots differ only by chance, the chance of
naming any robot at all is about 1 %.

**A common scale.** Where the measured torques carry a scale of their own on one robot (its currents read in
other units, a current sensor's gain, a known motor gain that is wrong), every base combination of that robot
scales with them, inertial and friction alike. It is a group of its own, `scale`, read where the fits are surest and
friction plays no part: the gravity torques. Each robot's factor c_r is the median ratio of its gravity torques over
the other robots' median, at 256 postures within every robot's fitted range, on the joints gravity loads (robots of
one kind are one design, while friction wears); its standard error is the jackknife's over the model file's folds
(the Φ fitted without each time block); the statistic is log c_r against the other robots' factors, as above. A robot
named for its scale has its friction compared with c_r taken out, so a scale is named once, as a scale, not as
friction on every joint (taken out of every robot, c_r's own noise would move each robot's coefficients together);
and as measured: a load its runs carry makes it heavier, not scaled, and named `scale` too, its friction the fleet's
as measured, so where c_r > 1 friction is named only where it stands out both ways (a wear up to about c_r² then
hides: which of the two it is, a per-joint test of the gravity torques could tell). With unknown gains the
gains absorb an input's scale, c_r stays near 1 and the gains are named.

What it cannot see: a factor smaller than the fleet's own spread. The simulated fleet draws each friction
coefficient within ×2.4 (5–12 % of a joint's load); a joint whose friction was at the bottom of that range and
doubled can stay within it (docs/validation.md#a-fleet).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter
from scipy.stats import norm

from ..errors import DataError
from ..identify.model_file import IdentifiedModel
from ..identify.regression import jackknife_se
from ..identify.transfer import fit_ranges
from ..robot.regressors.rigid_body import rigid_body_regressors
from . import html as H
from .figures import png

FAMILY_ALPHA = 0.01
MAD_SCALE = 1.4826  # MAD → standard deviation of a normal
SE_FLOOR = 1e-12
SCALE_WHY = ("the measured inputs' unit or a sensor's gain, a known motor gain that is wrong, or a load it carries that "
             "the others do not")
GRAVITY_POSTURES = 256
# A joint enters the common scale where its RMS gravity torque is above this share of the largest joint's, and a
# posture's torque on it where above this share of that joint's RMS (near zero, a ratio is noise)
GRAVITY_SHARE = 0.1
KINDS = ("friction", "gain", "ft_offset", "inertial")
FLAGGED_KINDS = ("friction", "gain", "ft_offset")
COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2"]


@dataclass(frozen=True)
class Compared:
    combination: str  # the base combination, as the model files write it
    name: str  # its leading parameter (layout name)
    kind: str  # friction | gain | ft_offset | inertial
    group: str  # e.g. "friction r_elbow", "gain m3", "F/T offset r_arm_ft", "inertial r_hand"
    values: np.ndarray  # (robots,)
    errors: np.ndarray  # (robots,) standard errors
    log: bool  # compared on a log scale


def _kind(name: str, layout_kinds: dict[str, str]) -> tuple[str, str]:
    kind = layout_kinds.get(name, "inertial")
    owner = name.rsplit(".", 1)[0]
    if kind == "ft_offset":
        owner = name.split(".")[1]
    label = {"friction": "friction", "gain": "gain", "ft_offset": "F/T offset", "inertial": "inertial"}[kind]
    return kind, f"{label} {owner}"


def shared_parameters(models: dict[str, IdentifiedModel], layout_kinds: dict[str, str]) -> list[Compared]:
    """The base combinations every robot's fit has, with each robot's value and standard error."""
    robots = list(models)
    per_robot = []
    for r in robots:
        base = models[r].base
        if base is None:
            raise DataError(f"{models[r].path}: model file lacks its 'base' section")
        per_robot.append({_key(name, k, list(base.dependent)): (float(v), float(e), c) for name, k, c, v, e in
                          zip(base.independent, base.K, base.combinations, base.values, base.standard_errors)})
    shared = [key for key in per_robot[0] if all(key in p for p in per_robot[1:])]
    out = []
    for key in shared:
        name, c = key[0], per_robot[0][key][2]
        kind, group = _kind(name, layout_kinds)
        values = np.array([p[key][0] for p in per_robot])
        errors = np.array([p[key][1] for p in per_robot])
        log = kind in ("friction", "gain") and bool(np.all(values > 0))
        out.append(Compared(c, name, kind, group, values, errors, log))
    return out


def _key(name: str, k_row: np.ndarray, dependent: list[str]) -> tuple:
    """What makes two robots' base combinations the same: the leading parameter and the others' coefficients, to 4
    significant digits, rounding-level ones (|k| < 1e-6, a rank decision's dust) left out."""
    return (name, *((d, float(f"{k:.4g}")) for d, k in zip(dependent, k_row) if abs(k) >= 1e-6))


def _scaled(p: Compared) -> tuple[np.ndarray, np.ndarray]:
    if p.log:
        return np.log(p.values), p.errors / p.values
    return p.values, p.errors


def z_scores(p: Compared) -> np.ndarray:
    """Each robot's z against the others' median and robust spread (module docstring)."""
    y, se = _scaled(p)
    z = np.zeros(y.size)
    for r in range(y.size):
        others = np.delete(y, r)
        m = np.median(others)
        s = MAD_SCALE * np.median(np.abs(others - m))
        z[r] = (y[r] - m) / max(math.hypot(s, se[r]), SE_FLOOR)
    return z


def common_scales(models: dict[str, IdentifiedModel], seed: int = 0) -> tuple[np.ndarray, np.ndarray] | None:
    """(log c_r, its standard error) per robot (module docstring, "A common scale"), or None where the fleet's
    gravity torques say nothing (no joint loaded by gravity, no posture every fit saw, a model without its folds)."""
    fitted = list(models.values())
    if any(m.folds is None for m in fitted):
        return None
    model = fitted[0].robot_model
    q = _common_postures(fitted, seed)
    if q is None:
        return None
    Y = rigid_body_regressors(model, q, np.zeros_like(q), np.zeros_like(q)).tau  # (N, joints, 10 bodies)
    span = model.layout.span("inertial")
    torques = np.stack([Y @ m.phi[span] for m in fitted])  # (robots, N, joints)
    folds = [np.stack([Y @ phi[span] for phi in m.folds.parameters]) for m in fitted]  # (B, N, joints) each
    loaded = np.median(np.sqrt(np.mean(torques**2, axis=1)), axis=0)  # each joint's RMS gravity torque
    joints = loaded > GRAVITY_SHARE * loaded.max() if loaded.max() > 0 else np.zeros(loaded.size, dtype=bool)
    if not joints.any():
        return None
    log_c, se = np.zeros(len(fitted)), np.zeros(len(fitted))
    for r in range(len(fitted)):
        others = np.median(np.delete(torques, r, axis=0), axis=0)
        log_c[r] = _log_scale(torques[r], others, loaded, joints)
        se[r] = float(jackknife_se(np.array([_log_scale(f, others, loaded, joints) for f in folds[r]])))
    if not np.all(np.isfinite(log_c)) or not np.all(np.isfinite(se)):
        return None
    return log_c, se


def _common_postures(fitted: list[IdentifiedModel], seed: int) -> np.ndarray | None:
    """GRAVITY_POSTURES postures drawn within every robot's fitted range of every joint (each robot's the union over
    its runs, dynid.identify.transfer.fit_ranges), or None where a range is not recorded or the robots' do not
    overlap."""
    joints = fitted[0].robot_model.config.joints
    ranges = [fit_ranges(m, joints) for m in fitted]
    if any(r is None for r in ranges):
        return None
    lo, hi = np.max([r[:, 0] for r in ranges], axis=0), np.min([r[:, 1] for r in ranges], axis=0)
    if not np.all(lo <= hi):
        return None
    return np.random.default_rng(seed).uniform(lo, hi, (GRAVITY_POSTURES, lo.size))


def _log_scale(torques: np.ndarray, others: np.ndarray, loaded: np.ndarray, joints: np.ndarray) -> float:
    """The median log ratio of a robot's gravity torques over the others' median, on the loaded joints where the
    others' torque is at least GRAVITY_SHARE of that joint's RMS and of the same sign."""
    use = joints[None, :] & (np.abs(others) > GRAVITY_SHARE * loaded[None, :]) & (torques * others > 0)
    return float(np.median(np.log(torques[use] / others[use]))) if use.any() else float("nan")


def _without_scale(p: Compared, log_c: np.ndarray) -> Compared:
    """A friction coefficient with each robot's common scale taken out."""
    c = np.exp(log_c)
    return Compared(p.combination, p.name, p.kind, p.group, p.values / c, p.errors / c, p.log)


def compare(models: dict[str, IdentifiedModel], layout_kinds: dict[str, str],
            alpha: float = FAMILY_ALPHA) -> dict[str, Any]:
    """The fleet's comparison (JSON-able): every shared parameter, each group's statistic per robot, the bound, the
    robots named with the groups that make them stand out."""
    robots = list(models)
    if len(robots) < 3:
        raise ValueError("a fleet needs at least 3 robots")
    params = shared_parameters(models, layout_kinds)
    groups: dict[str, list[tuple[Compared, np.ndarray]]] = {}
    scales = common_scales(models)
    flagged = {p.group for p in params if p.kind in FLAGGED_KINDS}
    n_tests = max(1, len(robots) * (len(flagged) + (scales is not None)))
    bound = float(norm.isf(alpha / (2 * n_tests)))
    taken_out = np.zeros(len(robots))  # log c_r of the robots named for a scale, 0 elsewhere
    if scales is not None:
        log_c, se = scales
        scale = Compared("common scale", "scale", "scale", "scale", np.exp(log_c), se * np.exp(log_c), True)
        z = z_scores(scale)
        groups["scale"] = [(scale, z)]
        # Only a scale the fleet names is taken out of friction: c_r's own noise, shared by every coefficient of a
        # robot, would otherwise move a joint's four together (the default arms' fleet: robot 8's elbow -2.9 -> -4.9)
        taken_out = np.where(np.abs(z) > bound, log_c, 0.0)
    as_measured: dict[str, list[np.ndarray]] = {}  # friction groups' z before a named scale is taken out
    for p in params:
        if p.kind in FLAGGED_KINDS:
            compared = _without_scale(p, taken_out) if p.kind == "friction" and taken_out.any() else p
            groups.setdefault(p.group, []).append((compared, z_scores(compared)))
            if compared is not p:
                as_measured.setdefault(p.group, []).append(z_scores(p))
    group_rows = []
    outliers: dict[str, list[dict[str, Any]]] = {}
    for g, members in groups.items():
        z = np.array([zk for _, zk in members])  # (k, robots)
        stat = z.sum(axis=0) / math.sqrt(len(members))
        if g in as_measured:
            # A robot named for a scale: its friction is named only if it stands out both with the scale taken out
            # and as measured. A scale of its torques leaves friction the fleet's once taken out; a load its runs
            # carry (named `scale` too: heavier, not scaled) leaves it the fleet's as measured, and taking the scale
            # out made it look low (a walkthrough's UR10e with 2.8 kg: friction named on four joints, ×0.73-0.87)
            # A load only adds (c_r > 1): a robot whose torques read low has its scale taken out alone, or its wear
            # would hide behind it (c_r 1/w against a wear w: as measured, nothing)
            raw = np.array(as_measured[g]).sum(axis=0) / math.sqrt(len(members))
            stat = np.where((taken_out > 0) & (np.abs(raw) < np.abs(stat)), raw, stat)
        group_rows.append({"group": g, "kind": members[0][0].kind, "parameters": [p.combination for p, _ in members],
                           "statistic": dict(zip(robots, stat.tolist()))})
        for r, s in zip(robots, stat):
            if abs(s) > bound:
                ratio = [float(p.values[robots.index(r)] / np.median(np.delete(p.values, robots.index(r))))
                         for p, _ in members]
                outliers.setdefault(r, []).append({"group": g, "statistic": float(s), "ratio_to_median": ratio})
    return {
        "robots": robots, "alpha": alpha, "bound": bound, "tests": n_tests,
        # whether the common scale could be tested (gravity torques at postures every robot's fit saw, and folds)
        "scale_tested": scales is not None,
        # c_r, each robot's gravity torques against the others' (1: none), with its standard error
        "scale": None if scales is None else {"values": dict(zip(robots, np.exp(scales[0]).tolist())),
                                              "standard_errors": dict(zip(robots, (scales[1] * np.exp(scales[0])).tolist()))},
        "parameters": [{"combination": p.combination, "name": p.name, "kind": p.kind, "group": p.group,
                        "log_scale": p.log, "values": dict(zip(robots, p.values.tolist())),
                        "standard_errors": dict(zip(robots, p.errors.tolist())),
                        "median": float(np.median(p.values))} for p in params],
        "groups": group_rows,
        "outliers": [{"robot": r, "groups": g} for r, g in outliers.items()],
    }


# ------------------------------------------------------------------------------------------------------------
# The page


def group_figure(result: dict[str, Any], kind: str, title: str) -> Figure | None:
    """One panel per group of `kind`, the robots side by side, with ±1.96 standard errors; a named robot's column in
    red. Friction and gains: each coefficient over the fleet's median, on a log scale where every value in the panel
    is positive, else over the median's magnitude on a linear one (a negative coefficient, the outlier it may be,
    has no place on a log axis); offsets: their values."""
    robots = result["robots"]
    params = [p for p in result["parameters"] if p["kind"] == kind]
    if kind == "scale" and result.get("scale"):  # c_r: a ratio to the other robots already
        params = [{"kind": "scale", "group": "scale", "name": "c_r", "log_scale": True, **result["scale"]}]
    if not params:
        return None
    groups = list(dict.fromkeys(p["group"] for p in params))
    named = {(o["robot"], g["group"]) for o in result["outliers"] for g in o["groups"]}
    cols = min(3, len(groups))
    rows = math.ceil(len(groups) / cols)
    fig = Figure(figsize=(4.2 * cols, 2.8 * rows + 0.4))
    x = np.arange(len(robots))
    for i, g in enumerate(groups):
        ax = fig.add_subplot(rows, cols, i + 1)
        members = [p for p in params if p["group"] == g]
        log = all(p["log_scale"] for p in members)
        for j, p in enumerate(members):
            v = np.array([p["values"][r] for r in robots])
            e = np.array([p["standard_errors"][r] for r in robots])
            if kind in ("friction", "gain"):
                med = abs(float(np.median(v))) or 1.0
                v, e = v / med, e / med
            off = (j - (len(members) - 1) / 2) * 0.12
            ax.errorbar(x + off, v, yerr=1.96 * e, fmt="o", ms=3, lw=0.8, color=COLORS[j % len(COLORS)],
                        label=p["name"].rsplit(".", 1)[-1])
        if kind in ("friction", "gain", "scale"):
            ax.axhline(1.0, color="#888", lw=0.8)
            if log:
                ax.set_yscale("log")
                low, high = ax.get_ylim()
                if high / low < 20:  # within a decade or so a log axis labels 1 alone: label its 0.7, 0.8, 2, ...
                    ax.yaxis.set_major_locator(LogLocator(subs=np.arange(1.0, 10.0)))
                    ax.yaxis.set_major_formatter(FormatStrFormatter("%.2g"))
                    ax.yaxis.set_minor_formatter(NullFormatter())
            else:
                ax.axhline(0.0, color="#888", lw=0.8, ls=":")
        for r in range(len(robots)):
            if (robots[r], g) in named:
                ax.axvspan(r - 0.45, r + 0.45, color="#d62728", alpha=0.15)
        ax.set_title(g, fontsize=9)
        ax.set_xticks(x, robots, rotation=60, fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.legend(fontsize=6, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def page(result: dict[str, Any], robot_kind: str) -> str:
    robots = result["robots"]
    if result["outliers"]:
        items = "".join(
            f"<li><b>{H.esc(o['robot'])}</b>: " + "; ".join(
                f"{H.esc(g['group'])} (S = {g['statistic']:.1f}; × "
                + ", ".join(f"{r:.2f}" for r in g["ratio_to_median"]) + " the others' median"
                + (f": every torque of its fit scaled, {H.esc(SCALE_WHY)})" if g["group"] == "scale" else ")")
                for g in o["groups"])
            + "</li>" for o in result["outliers"])
        summary = f"<p>Standing out beyond the fleet's spread:</p><ul>{items}</ul>"
    else:
        summary = "<p>No robot stands out beyond the fleet's spread.</p>"
    summary += (f'<p class="note">{len(robots)} robots; a group is named when |S| exceeds {result["bound"]:.2f} (the '
                f'Bonferroni bound of α = {result["alpha"]:g} over {result["tests"]} robot-group tests): '
                "S sums each coefficient's z against the other robots' median and robust spread (docs/validation.md#a-fleet).</p>")
    stat_rows = []
    for g in result["groups"]:
        cells = []
        for r in robots:
            s = g["statistic"][r]
            style = ' style="background:#f6c8c8"' if abs(s) > result["bound"] else ""
            cells.append(f'<td{style} data-key="groups/{H.esc(g["group"])}/{H.esc(r)}" data-value="{s!r}">{s:.1f}</td>')
        stat_rows.append(f"<tr>{H.text(g['group'])}{''.join(cells)}</tr>")
    sections = [f"<h2>Summary</h2>{summary}",
                "<h2>Each group's statistic S, robot by robot</h2>" + H.table(["group", *robots], stat_rows)]
    figures = []
    for kind, title in (("scale", "Common torque scale c_r (±1.96 SE): gravity torques against the other robots'"),
                        ("friction", "Friction: each coefficient over the fleet's median (±1.96 SE)"),
                        ("gain", "Motor gains over the fleet's median (±1.96 SE)"),
                        ("ft_offset", "F/T offsets (N, Nm; ±1.96 SE)")):
        fig = group_figure(result, kind, title)
        if fig is not None:
            figures.append(H.figure(f"fig-{kind}", png(fig), title))
    sections.append("<h2>The robots side by side</h2>" + "".join(figures))
    rows = []
    for p in result["parameters"]:
        cells = "".join(f'<td data-value="{p["values"][r]!r}">{p["values"][r]:.4g} ± {p["standard_errors"][r]:.2g}</td>'
                        for r in robots)
        rows.append(f'<tr><td class="combo">{H.esc(p["combination"])}</td>{cells}</tr>')
    sections.append("<h2>Every shared base parameter (value ± standard error)</h2>" + H.table(["combination", *robots], rows))
    return H.page(f"Fleet of {len(robots)} {robot_kind} robots", sections)
