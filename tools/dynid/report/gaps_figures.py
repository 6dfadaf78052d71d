"""`dynid gaps --figures DIR`: the gap before/after per channel, and a figure per finding, drawn only from the
result's numbers (``gap`` and ``profile``, dynid.gaps.profile) with matplotlib's Agg canvas.

A finding is a channel whose residual a named effect (on a joint it depends on) lowers by more than 10 %
("explained", or "partly explained" while it stays above UNEXPLAINED × its noise floor), or a channel that stays
above that after the fix ("unexplained"). Each finding's figure shows where its residual grows: by the speed
of the joint it depends on most (near zero … high speed), at that joint's direction reversals, by position and
over time, before and after the fix. DIR also gets gaps.json (the result) and figures.json (what is drawn).
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..errors import DataError
from ..io.dataset import atomic_write
from ..outputs import output_dir
from . import html as H
from .figures import png

UNEXPLAINED = 1.3  # × noise floor (the issue's bar for a closed gap)
BEFORE, AFTER, GIVEN = "#d62728", "#1f77b4", "#7f7f7f"


def findings(result: dict) -> list[tuple[str, str, str]]:
    """(channel, joint, why) per finding, in channel order: every channel a named effect on one of its joints or on its
    own motor helps, and every channel left unexplained."""
    prof = result.get("profile", {}).get("channels", {})
    out = []
    effects = result.get("effects", [])
    effect_joints = {e["where"].partition(" ")[2] for e in effects if e["where"].startswith("joint ")}
    effect_motors = {e["where"].partition(" ")[2] for e in effects if e["where"].startswith("motor ")}
    for g in result["gap"]:
        ch = g["channel"]
        if ch not in prof:
            continue
        gain = 1 - g["after_over_noise"] / g["before_over_noise"] if g["before_over_noise"] > 0 else 0.0
        joints = prof[ch]["joints"]
        named = [j for j in joints if j in effect_joints]
        own_motor = ch.partition(".")[2] in effect_motors  # current.M, pwm.M: the motor's own input channel
        if (named or own_motor) and gain > 0.1:
            why = "explained" if g["after_over_noise"] <= UNEXPLAINED else "partly explained"
        elif g["after_over_noise"] > UNEXPLAINED:
            why = "unexplained"
        else:
            continue
        out.append((ch, named[0] if named else _worst_joint(joints), why))
    return out


def _worst_joint(joints: dict) -> str:
    """The joint whose speed bins spread the residual most (where it depends on that joint's motion)."""
    def spread(j: str) -> float:
        v = [x for x in joints[j]["speed"]["before"] if x is not None]
        return (max(v) - min(v)) if v else 0.0

    return max(joints, key=spread)


def _series(ax, x: np.ndarray, before: list, after: list, kind: str) -> None:
    b = np.array([np.nan if v is None else v for v in before], float)
    a = np.array([np.nan if v is None else v for v in after], float)
    if kind == "bar":
        w = 0.38
        ax.bar(x - w / 2, b, w, color=BEFORE, label="before", gid="before")
        ax.bar(x + w / 2, a, w, color=AFTER, label="after", gid="after")
    else:
        ax.plot(x, b, "o-", color=BEFORE, label="before", gid="before")
        ax.plot(x, a, "s-", color=AFTER, label="after", gid="after")
    ax.axhline(1.0, color="k", linestyle=":", linewidth=0.8)
    ax.set_ylabel("residual RMS / noise")


def gap_figure(result: dict) -> Figure:
    fig = Figure(figsize=(9, 3.6))
    ax = fig.add_subplot()
    names = [g["channel"] for g in result["gap"]]
    x = np.arange(len(names))
    _series(ax, x, [g["before_over_noise"] for g in result["gap"]], [g["after_over_noise"] for g in result["gap"]], "bar")
    if result.get("given_model"):
        ax.plot(x, [g["given_model_over_noise"] for g in result["gap"]], "D", color=GIVEN, label="given model",
                gid="given")
    ax.axhline(UNEXPLAINED, color="k", linestyle="--", linewidth=0.8, label=f"{UNEXPLAINED}× noise")
    ax.set_xticks(x, [n.replace("ft.", "").replace("r_arm_ft.", "") for n in names], rotation=30, fontsize=8)
    named = "; ".join(f"{e['name']} on {e['where']}" + ("" if e.get("confident") else " (tentative)")
                      for e in result.get("effects", [])) or "nothing named"
    # Several named effects make a long line: wrapped, it stays inside the figure.
    ax.set_title(textwrap.fill(f"gap per channel on held-out time blocks: {named}", 110), fontsize=9, loc="left")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def finding_figure(result: dict, channel: str, joint: str, why: str) -> Figure:
    prof = result["profile"]
    ch, j = prof["channels"][channel], prof["channels"][channel]["joints"][joint]
    fig = Figure(figsize=(10, 6.4))
    axes = fig.subplots(2, 2)
    labels = prof["speed_bins"]
    _series(axes[0, 0], np.arange(len(labels)), j["speed"]["before"], j["speed"]["after"], "line")
    axes[0, 0].set_xticks(np.arange(len(labels)), labels, fontsize=8)
    axes[0, 0].set_xlabel(f"|q̇| of {joint} (rad/s)")
    _series(axes[0, 1], np.arange(2), j["reversal"]["before"], j["reversal"]["after"], "bar")
    axes[0, 1].set_xticks([0, 1], [f"within {1e3 * prof['reversal_window_s']:.0f} ms of a reversal", "elsewhere"],
                          fontsize=8)
    pe = np.asarray(j["position_edges"])
    _series(axes[1, 0], 0.5 * (pe[:-1] + pe[1:]), j["position"]["before"], j["position"]["after"], "line")
    axes[1, 0].set_xlabel(f"q of {joint} (rad)")
    te = np.asarray(ch["time"]["edges_s"]) + result.get("t0_s", 0.0)  # the data's own seconds, as --from/--to
    _series(axes[1, 1], 0.5 * (te[:-1] + te[1:]), ch["time"]["before"], ch["time"]["after"], "line")
    axes[1, 1].set_xlabel("time (s, the data's own)")
    axes[0, 0].legend(fontsize=8)
    gap = next(g for g in result["gap"] if g["channel"] == channel)
    # The title's figures are the held-out ones of the gap table; the panels bin the residual over the whole run
    # (in sample): the title says both, so neither contradicts the other.
    fig.suptitle(f"{channel} ({why}): held-out RMS {gap['before_over_noise']:.2f}× → {gap['after_over_noise']:.2f}× "
                 f"noise\npanels: the residual over the run (in sample) against {joint}'s speed, its reversals, its "
                 "position, and against time", fontsize=9)
    fig.tight_layout()
    return fig


def build(result: dict) -> list[tuple[str, str, Figure]]:
    """(file name, caption, figure): the gap, then one per finding."""
    out = [("gap.png", "the gap before and after the fix, per channel (held-out RMS / noise floor)", gap_figure(result))]
    for channel, joint, why in findings(result):
        out.append((f"finding_{channel}.png", f"{channel}: where the residual grows ({why})",
                    finding_figure(result, channel, joint, why)))
    return out


def write_figures(result: dict, directory: str) -> list[str]:
    """PNGs, gaps.json and figures.json (file -> caption, channel) into DIR, each written atomically."""
    d = output_dir(directory)
    index: list[dict[str, Any]] = []
    for name, caption, fig in build(result):
        data = png(fig)
        atomic_write(d / name, lambda f, data=data: f.write(data))
        index.append({"file": name, "caption": caption})
    text = json.dumps(result, indent=1, default=float) + "\n"
    atomic_write(d / "gaps.json", lambda f: f.write(text.encode()))
    idx = json.dumps(index, indent=1) + "\n"
    atomic_write(d / "figures.json", lambda f: f.write(idx.encode()))
    written = {i["file"] for i in index}
    for old in d.glob("finding_*.png"):  # a finding of an earlier run into the same folder: not this result's
        if old.name not in written:
            old.unlink()
    return [i["file"] for i in index]


def report_section(directory: str) -> tuple[list[str], dict]:
    """HTML of `dynid report --gaps DIR`: the named effects, the gap table and every figure of DIR."""
    d = Path(directory)
    try:
        result = json.loads((d / "gaps.json").read_text(encoding="utf-8"))
        index = json.loads((d / "figures.json").read_text(encoding="utf-8"))
        pngs = [(i["file"], i["caption"], (d / i["file"]).read_bytes()) for i in index]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise DataError(f"{d}: not a `dynid gaps --figures` directory ({e.__class__.__name__}: {e})") from None
    rows = []
    for e in result.get("effects", []):
        se = e.get("standard_errors", {})
        params = ", ".join((f"{k} {v:.4g}" if isinstance(v, (int, float)) else f"{k} {v}")  # a limit step's joint
                           + (f" ± {se[k]:.2g}" if se.get(k) is not None else "")
                           for k, v in e["parameters"].items())
        rows.append(f"<tr>{H.text(e['name'])}{H.text(e['where'])}{H.text(params)}"
                    f"{H.num(e['cv_gain'], '.1f', scale=100.0)}</tr>")
    gap_rows = [f"<tr>{H.text(g['channel'])}{H.num(g['before_rms'], '.4g')}{H.num(g['after_rms'], '.4g')}"
                f"{H.num(g['before_over_noise'], '.2f')}{H.num(g['after_over_noise'], '.2f')}{H.text(g['unit'])}</tr>"
                for g in result["gap"]]
    named = (H.table(["effect", "where", "parameters (± block-jackknife SE)", "held-out error −%"], rows, left=3)
             if rows else "<p>Nothing named: no effect in the library explains a significant part of the residual.</p>")
    html = [f"<h2>Model gaps (<code>{H.esc(result.get('data', '?'))}</code>)</h2>", named,
            H.table(["channel", "before RMS", "after RMS", "before / noise", "after / noise", "unit"], gap_rows),
            "<p class=\"note\">RMS on held-out time blocks; before: the standard model refitted on the run; after: with "
            "the named effects. Each finding's figure bins the residual by the speed, reversals and position of the "
            "joint it depends on most, and by time.</p>"]
    html += [H.figure(f"fig-gaps-{i}", data, caption) for i, (_, caption, data) in enumerate(pngs)]
    return html, result
