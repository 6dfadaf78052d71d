"""The monitor's contact events against the skin's ground truth: what `scripts/main` prints at the end.

Events come from an LCM log of `DYNID_CONTACT` (`dynid.contact_event_t`, decoded with the lcm-gen Python types of
rt_monitor/lcmtypes, `dynid.export.lcm_messages`), sample times from the boards' CAN time (sample k at t0 + k · period). Figures:
- TPR / FPR per sample: the fraction of contact (contact-free) samples during which the monitor is between an
  onset and its end — the paper's definition of its 67 % / 6 % (Traversaro et al. 2013, at α = 0.99);
- episodes found: an onset between the episode's start and `slack` samples after its end (the causal filter's
  lag and the debounce make every onset late); the detection delay is that onset's time after the start;
- false onsets: onsets outside every such window;
- T² TPR / FPR: the per-sample test T² > T²_α itself (no debounce), on the decimated residual stream
  (`DYNID_RESIDUAL`, every 10th sample): the figure the paper's 67 % / 6 % are closest to.

Run as `python -m dynid.export.monitor_log --events LOG --data RUN_DIR --model COEF [--json OUT]`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import load_config
from ..detect.visibility import monitor_visibility
from ..errors import DataError, InputError
from ..io.dataset import beside_run
from ..io.dataset import contact_episodes as episodes
from ..io.load import load_data
from ..paper import PAPER
from ..robot.model import RobotModel
from .coefficients import read_coefficients


def ratios_text(ratios: Any) -> str:
    """The input channels' supply ratios, in the coefficient file's order: '1.0123 0.9871 …'."""
    return " ".join(f"{r:.4f}" for r in ratios)


def summarize(contact: np.ndarray, events: list[tuple[int, int]], period_s: float, slack: int,
              t2: list[tuple[int, float, float]] | None = None, side: np.ndarray | None = None,
              visible: list[bool] | None = None, earliest: list[int] | None = None) -> dict[str, Any]:
    """events: (kind, sample) with kind 1 onset, 2 end, 3 cut (the filter restarted in contact: it ends there), in
    time order; t2: (sample, T², T²_α) of the residual
    stream. The filter's lag shifts the T² test: a sample's alarm is compared with the truth `lag` earlier
    than it, here taken as 0 (the lag is a few ms against contacts of 0.3 s or more). side: the simulator's
    skin.side (1 distal of the F/T sensor, -1 proximal) for a per-side count of the episodes found. visible:
    per episode, whether the contact alone reaches the monitor's T²_α for its debounce (dynid.detect.visibility);
    earliest: per episode, the first sample at which it could confirm that (−1: never), whose delays bound the
    monitor's from below."""
    truth = np.asarray(contact) != 0
    n = truth.size
    state = np.zeros(n, bool)
    on: int | None = None
    for kind, k in events:
        if kind == 1 and on is None:
            on = max(0, min(k, n))
        elif kind in (2, 3) and on is not None:
            state[on:max(on, min(k, n))] = True
            on = None
    if on is not None:
        state[on:] = True
    eps = episodes(truth)
    onsets = [k for kind, k in events if kind == 1]
    delays, found = [], 0
    by_side = {"distal": [0, 0], "proximal": [0, 0]}  # found, total
    missed_visible: list[int] = []
    for i, (a, e) in enumerate(eps):
        hits = [k for k in onsets if a <= k <= e + slack]
        if visible is not None and visible[i] and not hits:
            missed_visible.append(int(a))
        name = None if side is None else {1: "distal", -1: "proximal"}.get(int(side[a]))
        if name:
            by_side[name][1] += 1
        if hits:
            found += 1
            delays.append((hits[0] - a) * period_s)
            if name:
                by_side[name][0] += 1
    false_onsets = sum(1 for k in onsets if not any(a <= k <= e + slack for a, e in eps))
    t2_rates = {}
    if t2:
        k = np.array([x[0] for x in t2])
        ok = (k >= 0) & (k < n)
        alarm = np.array([x[1] > x[2] for x in t2])[ok]
        hit = truth[k[ok]]
        t2_rates = {"t2_tpr": float(alarm[hit].mean()) if hit.any() else float("nan"),
                    "t2_fpr": float(alarm[~hit].mean()) if (~hit).any() else float("nan"),
                    "t2_samples": int(ok.sum())}
    if side is not None:
        t2_rates["episodes_by_side"] = {k: {"found": v[0], "episodes": v[1]} for k, v in by_side.items()}
    if visible is not None:
        t2_rates["episodes_visible"] = int(sum(visible))
        t2_rates["visible_missed_at"] = missed_visible  # sample of each visible episode's start
    if earliest is not None:  # the delays a residual free of noise and lag would give, the same episodes' debounce
        bound = [k * period_s for k in earliest if k >= 0]
        t2_rates["delay_bound_median_s"] = float(np.median(bound)) if bound else float("nan")
        t2_rates["delay_bound_p90_s"] = float(np.percentile(bound, 90)) if bound else float("nan")
    return {
        **t2_rates,
        "samples": int(n), "episodes": len(eps), "episodes_found": found, "onsets": len(onsets),
        "false_onsets": false_onsets,
        "tpr": float(state[truth].mean()) if truth.any() else float("nan"),
        "fpr": float(state[~truth].mean()) if (~truth).any() else float("nan"),
        "delay_median_s": float(np.median(delays)) if delays else float("nan"),
        "delay_p90_s": float(np.percentile(delays, 90)) if delays else float("nan"),
        "paper": {k: PAPER[k] for k in ("tpr", "fpr")},
    }


# The last status's counters the summary keeps: the sample count and the timing artefacts of the run.
MONITOR_COUNTERS = ("frames", "samples", "stale_samples", "interpolated", "late", "filter_restarts")


def monitor_counters(status: Any) -> dict[str, Any]:
    """The summary's "monitor" entry from the last DYNID_STATUS (a monitor_status_t): its counters and the input
    channels' supply ratios (in the coefficient file's channel order)."""
    out: dict[str, Any] = {k: int(getattr(status, k)) for k in MONITOR_COUNTERS}
    out["supply_ratio"] = [float(r) for r in status.supply_ratio]
    return out


def format_summary(s: dict[str, Any]) -> str:
    return (f"contact summary: {s['episodes_found']} of {s['episodes']} contact episodes found, "
            f"{s['false_onsets']} false onsets"
            + ("".join(f", {k} {v['found']} of {v['episodes']}" for k, v in s["episodes_by_side"].items())
               if "episodes_by_side" in s else "") + "\n"
            + (f"  episodes the contact alone makes visible to the monitor (plant truth): {s['episodes_visible']}, "
               f"{s['episodes_visible'] - len(s['visible_missed_at'])} of them found\n" if "episodes_visible" in s else "")
            + f"  monitor in contact (onset to end, debounced): {100 * s['tpr']:.1f} % of contact samples, "
            f"{100 * s['fpr']:.2f} % of contact-free ones\n"
            f"  detection delay median {1e3 * s['delay_median_s']:.0f} ms, p90 {1e3 * s['delay_p90_s']:.0f} ms "
            f"(from the skin's onset to the monitor's confirmed onset)"
            + (f"; the contact alone, without noise or filter lag: median {1e3 * s['delay_bound_median_s']:.0f} ms, "
               f"p90 {1e3 * s['delay_bound_p90_s']:.0f} ms" if "delay_bound_median_s" in s else "")
            + (f"\n  T² > T²_α per sample (every 10th, no debounce): TPR {100 * s['t2_tpr']:.1f} %, "
               f"FPR {100 * s['t2_fpr']:.2f} %  <- the paper's definition: TPR 67 %, FPR 6 % (α = 0.99)"
               if "t2_tpr" in s else "")
            + (f"\n  {format_monitor(s['monitor'])}" if "monitor" in s else ""))


def format_monitor(m: dict[str, Any]) -> str:
    return ("monitor's last status: " + ", ".join(f"{k.replace('_', ' ')} {m[k]}" for k in MONITOR_COUNTERS)
            + (f"; supply ratios {ratios_text(m['supply_ratio'])}" if m["supply_ratio"] else ""))


def read_lcm_log(path: Path) -> dict[str, list]:
    """Every DYNID_* message of an LCM log file, decoded with the lcm-gen types of rt_monitor/lcmtypes
    (dynid.export.lcm_messages, generated by scripts/setup)."""
    import lcm

    from .lcm_messages import contact_event_t, monitor_status_t, residual_t

    if not Path(path).is_file():
        raise InputError(f"LCM log not found: {path}")
    types = {"DYNID_CONTACT": contact_event_t, "DYNID_STATUS": monitor_status_t, "DYNID_RESIDUAL": residual_t}
    out: dict[str, list] = {c: [] for c in types}
    try:
        for e in lcm.EventLog(str(path), "r"):
            if e.channel in types:
                out[e.channel].append(types[e.channel].decode(e.data))
    except (OSError, ValueError) as err:
        raise DataError(f"{path}: not a readable LCM log: {err}") from None
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m dynid.export.monitor_log", description=__doc__.splitlines()[0])
    p.add_argument("--events", required=True, type=Path, help="LCM log with DYNID_CONTACT")
    p.add_argument("--data", required=True, type=Path, help="the run the boards played (directory or data.csv)")
    p.add_argument("--model", required=True, type=Path, help="the coefficient file the monitor ran (lag, debounce)")
    p.add_argument("--robot", default="icub_right_arm")
    p.add_argument("--t0", type=float, default=1_700_000_000.0, help="CAN time of the first sample (boards --t0)")
    p.add_argument("--json", type=Path)
    a = p.parse_args(argv)
    try:
        config = load_config(a.robot)
        data = load_data(a.data, config)
        if data.contact is None:
            raise DataError(f"{a.data}: no 'contact' ground truth")
        coef = read_coefficients(a.model)
        msgs = read_lcm_log(a.events)
        period = float(np.median(np.diff(data.t)))
        t0_us = round(a.t0 * 1e6)
        events = [(int(m.kind), round((m.utime - t0_us) / (period * 1e6))) for m in msgs["DYNID_CONTACT"]]
        t2 = [(round((m.utime - t0_us) / (period * 1e6)), float(m.t2), float(m.threshold))
              for m in msgs["DYNID_RESIDUAL"]]
        visible = earliest = None
        truth = beside_run(a.data, "truth.npz")
        if truth.is_file():
            seen = monitor_visibility(RobotModel(config), coef, np.load(truth))
            visible, earliest = [v.visible for v in seen], [v.earliest for v in seen]
        s = summarize(data.contact, events, period, coef.lag + coef.debounce_on + 5, t2, data.extra.get("skin.side"),
                      visible, earliest)
        if msgs["DYNID_STATUS"]:
            s["monitor"] = monitor_counters(msgs["DYNID_STATUS"][-1])
    except (DataError, InputError) as e:
        print(f"dynid.export.monitor_log: error: {e}", file=sys.stderr)
        return 2
    print(format_summary(s))
    if a.json:
        tmp = a.json.with_name(a.json.name + ".tmp")
        tmp.write_text(json.dumps(s, indent=2) + "\n")
        tmp.replace(a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
