"""`dynid detect`: T² contact detection offline, every variant side by side, and the lines it prints about its alarms
(how many stretches above the level; the same alarms as the exported monitor's debounce and hysteresis make contact
events of them, `monitor_events`)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from dataclasses import replace

from ..detect.combined import calibrate_combined, combined_detection, stored_combined
from ..detect.evaluation import detection
from ..detect.momentum import DEFAULT_BANDWIDTH_HZ, VELOCITY_WINDOW_S, measured_velocity
from ..detect.momentum_t2 import (alarm_runs, calibration_runs, momentum_detection, stored_detector,
                                  stored_in_sample)
from ..detect.t2 import ALPHA, debounced_events, episode_peaks
from ..errors import DataError, InputError
from ..export.model_export import bus_carries_velocity
from ..identify.model_sections import DEFAULT_N_MODE, N_MODES
from ..identify.transfer import outside_fit
from ..identify.validation import evaluate
from ..io.dataset import contact_episodes
from ..io.episodes import check_widening, episodes_in_data, episodes_mask, read_episodes
from ..paper import PAPER, PAPER_ROBOT
from .commands import COMMANDS
from .common import confidence as alpha
from .common import (bad_rows, finite_float, json_arg, non_negative_float, one_blas_thread, payload_arg, plural,
                     positive_float, skipped_rows, window, window_args)
from .out_of_sample import out_of_sample, print_out_of_sample

def stretches(t: np.ndarray, statistic: np.ndarray, events: list | None) -> str:
    """'N stretches above its threshold' of a normalised statistic (a contact above 1; dynid.detect.momentum_t2
    .alarm_runs), and with `events` (they are --json's) how many of them those describe (contact_events' limit)."""
    n = len(alarm_runs(t, statistic)[0])
    said = f"{plural(n, 'stretch', 'stretches')} above its threshold"
    if events is None:
        return said
    return said + (f" (--json's events: the first {len(events)})" if n > len(events) else " (--json's events)")


def monitor_events(t: np.ndarray, combined, momentum, found) -> dict[str, Any] | None:
    """The default detector's alarms as the exported monitor's defaults debounce them into contact events (the same
    counts and level: dynid.detect.t2.debounced_events), for a lab to set beside the monitor's events."""
    from ..export.coefficients import EventSettings

    if combined is not None:
        variant, statistic, level = "combined", combined.statistic, 1.0  # s: the sum over κ, a contact above 1
    elif momentum is not None:
        variant, statistic, level = "momentum", momentum.statistic, 1.0
    elif "calibrated" in found.t2:
        variant, statistic, level = "calibrated", found.t2["calibrated"], found.detectors["calibrated"].threshold
    else:
        return None
    if t.size < 2:
        return None
    settings = EventSettings().at(float(np.median(np.diff(t))))
    events = debounced_events(statistic, level, settings.debounce_on, settings.debounce_off, settings.hysteresis)
    return {"residual": variant, "debounce_on": settings.debounce_on, "debounce_off": settings.debounce_off,
            "hysteresis": settings.hysteresis, "onsets_s": [float(t[k]) for k, _ in events],
            "ends_s": [None if j is None else float(t[j]) for _, j in events],
            "peaks_s": [float(t[k]) for k in episode_peaks(statistic, events)]}


MISFIT_FPR = 0.5  # every detector above its level on more than half of the contact-free samples: not a contact


@one_blas_thread
def cmd_detect(args: argparse.Namespace) -> dict[str, Any]:
    calibration_given = bool(args.calibration) or (args.calibration_from, args.calibration_to) != (None, None)
    if calibration_given and args.residual == "acceleration":
        raise InputError("--calibration, --calibration-from and --calibration-to set the momentum residual's "
                         "calibration: not with --residual acceleration")
    labels = read_episodes(args.episodes) if args.episodes else None  # a bad file: exit 2 before any work
    if labels is not None:
        check_widening(labels, args.label_widening, args.episodes)
    ev = evaluate(args.model, args.data, window=window(args), payload=args.payload, bad_rows=bad_rows(args))
    if labels is not None:
        episodes_in_data(ev.dataset.t, labels, args.episodes)
        ds = replace(ev.dataset, contact=episodes_mask(ev.dataset.t, labels))
        ev = replace(ev, dataset=ds)
    elif ev.dataset.contact is not None:
        t = ev.dataset.t
        check_widening(np.array([(t[a], t[b - 1]) for a, b in contact_episodes(ev.dataset.contact)]).reshape(-1, 2),
                       args.label_widening, f"{args.data}'s contact column")
    found = detection(ev, args.model, args.data, args.alpha, args.n_mode, args.label_widening)
    if labels is not None:
        found.result["episodes_file"] = {"path": args.episodes, "episodes": int(len(labels)),
                                         "in_data": len(contact_episodes(ev.dataset.contact))}
    momentum, skipped, skipped_combined = None, None, None
    if args.residual in (None, "momentum"):
        try:
            # the fit's own calibration where it matches (the model file's `observer` section), else calibrate now
            stored = None if calibration_given or ev.identified.effects else stored_detector(
                ev.identified, "detect", args.alpha, args.bandwidth, VELOCITY_WINDOW_S)
            if stored is not None:
                runs, paths = None, ev.identified.data_paths
            else:
                runs, paths = calibration_runs(ev.identified, args.calibration,
                                               (args.calibration_from, args.calibration_to))
            # the runs it was fitted on: each time block's residual through the Φ fitted without it
            folds = None if calibration_given else ev.identified.folds
            momentum = momentum_detection(ev.identified, ev.dataset, runs, args.alpha, args.bandwidth,
                                          args.label_widening, found.side, detector=stored, folds=folds,
                                          in_sample=stored_in_sample(ev.identified) if stored is not None else None)
        except DataError as e:
            # asked for (the residual, its calibration runs or its bandwidth): its failure is the command's
            if args.residual == "momentum" or calibration_given or args.bandwidth != DEFAULT_BANDWIDTH_HZ:
                raise
            skipped = str(e)  # the default: say why, and report the acceleration-based variants
    combined = None
    if momentum is not None:
        if args.residual is None:  # the default: both residuals in one detector
            try:
                combined = combine(ev, found, momentum, args, stored is not None, calibration_given, runs, folds)
            except DataError as e:
                if calibration_given:
                    raise
                skipped_combined = str(e)
        found.result["variants"] = {"momentum": momentum.result, **found.result["variants"]}
        found.result["events"] = momentum.events
        found.result["calibration"] = paths
    if combined is not None:
        found.result["variants"] = {"combined": combined.result, **found.result["variants"]}
        found.result["events"] = combined.events
    found.result["residual"] = "combined" if combined is not None else "momentum" if momentum is not None else \
        "acceleration"
    found.result["out_of_sample"] = out_of_sample(ev.identified, args.data, window(args),
                                                  paths if momentum is not None else [], calibration_given,
                                                  (args.calibration_from, args.calibration_to),
                                                  found.result["variants"], ev.dataset.t)
    # α's promise is for data like the fit's: postures it never saw are the model's extrapolation, named beside it
    found.result["out_of_sample"]["postures_outside_fit"] = outside_fit(
        ev.identified, ev.dataset.joints, ev.dataset.q, ev.identified.robot_model.joint_limits)
    if skipped:
        found.result["momentum_skipped"] = skipped
    if skipped_combined:
        found.result["combined_skipped"] = skipped_combined
    print(f"T² contact detection with {args.model} on {args.data} ({ev.dataset.n_samples} samples), α = {args.alpha}")
    if (skipped_bad := skipped_rows(args.data, ev.dataset.meta)) is not None:
        found.result["bad_rows"] = skipped_bad
    if labels is not None:
        print(f"  contact labels: {args.episodes} ({plural(len(labels), 'episode')}, "
              f"{found.result['episodes_file']['in_data']} in the data)"
              + (": the run is scored as contact-free" if not len(labels) else ""))
    elif ev.dataset.contact is None:
        print("  no contact ground truth in the data: FPR assumes the run is contact-free")
    if skipped:
        print(f"  momentum residual skipped: {skipped}")
    if skipped_combined:
        print(f"  combined detector skipped: {skipped_combined}")
    if momentum is not None:
        print(f"  momentum: observer bandwidth {args.bandwidth:g} Hz, calibrated on {momentum.detector.samples} "
              f"contact-free samples; "
              f"{stretches(momentum.residuals.t, momentum.statistic, None if combined else momentum.events)}")
    if combined is not None:  # the events of --json are the default detector's
        print(f"  combined: {stretches(momentum.residuals.t, combined.statistic, combined.events)}")
    debounced = monitor_events(ev.dataset.t, combined, momentum, found)
    found.result["monitor_events"] = debounced
    if debounced is not None:
        print(f"  as the monitor's events ({debounced['residual']}, its default debounce and hysteresis: "
              f"{plural(debounced['debounce_on'], 'sample')} above the threshold to begin, {debounced['debounce_off']} under "
              f"{debounced['hysteresis']:g} of it to end): {plural(len(debounced['onsets_s']), 'onset')} "
              "(--json's monitor_events; on the offline residuals, which the monitor's causal filter only approaches)")
        model = ev.identified.robot_model
        if momentum is not None and measured_velocity(model, ev.dataset) is not None and not bus_carries_velocity(model):
            debounced["monitor_velocity"] = "estimated"
            print(f"  note: these take the run's recorded q̇, but {model.config.name}'s bus carries none: the monitor "
                  "estimates q̇ from q, causally, with more noise and lag, and finds less (docs/detection.md#the-monitor)")
    print_out_of_sample(found.result["out_of_sample"])
    rates = [s["fpr"] for s in found.result["variants"].values() if s.get("fpr") is not None]
    if rates and min(rates) > MISFIT_FPR:  # α promises 1 - α: no detector is anywhere near, the data are not the model's
        found.result["data_misfit"] = True
        print(f"  note: every detector is above its level on at least {100 * min(rates):.0f} % of the samples taken "
              "as contact-free: these data do not fit the model (another robot or set-up, units or columns, a sensor "
              "offset that moved), or the run is in contact throughout")
    for variant, s in found.result["variants"].items():
        tpr = "n/a" if s.get("tpr") is None else f"{100 * s['tpr']:.1f} %"
        # the combined statistic is the two ratios' sum over κ (its JSON `threshold`), a contact above 1
        level = (f"level 1 (κ {s['threshold']:.3g})" if variant == "combined" else f"threshold {s['threshold']:9.3g}")
        line = f"  {variant:10s} {level}: TPR {tpr}, FPR {100 * s['fpr']:.2f} %"
        if "auc" in s:
            line += f", AUC {s['auc']:.3f}"
        if s.get("episodes"):
            delay = s["delay_s"]
            line += f", episodes {s['episodes_detected']}/{s['episodes']}"
            held = s.get("episodes_sustained")
            if held and held["samples"] > 1:  # at 100 Hz one sample is the monitor's onset: the same count
                line += f", {held['found']}/{s['episodes']} held {held['samples']} samples as the monitor's onset"
            if delay["median"] is not None:
                line += f", delay median {1e3 * delay['median']:.0f} ms p90 {1e3 * delay['p90']:.0f} ms"
                line += f" max {1e3 * delay['max']:.0f} ms"
            if "delay_s_shifted" in s:
                d = s["delay_s_shifted"]
                line += (f" (against start + {d['shift_s']:g} s: median {1e3 * d['median']:.0f} ms, "
                         f"max {1e3 * d['max']:.0f} ms)")
        print(line)
        if s.get("tpr_by_side"):
            print("             TPR by side of the F/T sensor: " + ", ".join(
                f"{k} {100 * v:.1f} %" for k, v in s["tpr_by_side"].items() if v is not None))
    vis = found.result.get("visibility")
    if vis:
        hidden = [v for v in vis["episodes"] if not v["visible"]]
        print(f"  calibrated: the contact alone reaches T²_α in {vis['visible']} of {len(vis['episodes'])} episodes "
              f"(plant truth), {vis['visible_found']} of them found"
              + ("; below it: " + ", ".join(f"{v['start_s']:.1f} s (peak {v['peak_t2']:.3g})" for v in hidden) if hidden else ""))
    if ev.config.name == PAPER_ROBOT:
        print(f"  paper (real iCub arm, α = 0.99): TPR {100 * PAPER['tpr']:.0f} %, FPR {100 * PAPER['fpr']:.0f} %")
    return found.result


def combine(ev, found, momentum, args: argparse.Namespace, stored: bool, calibration_given: bool, runs, folds):
    """The combined detector (dynid.detect.combined) on the run: its level κ the fit kept, else calibrated now on the
    momentum detector's calibration runs (cross-validated where they are the fit's own)."""
    if ev.identified.effects or "calibrated" not in found.detectors:
        return None
    det_c = found.detectors["calibrated"]
    det = stored_combined(ev.identified, args.alpha) if stored else None
    if det is None:
        if runs is None:
            runs, _ = calibration_runs(ev.identified, args.calibration, (args.calibration_from, args.calibration_to))
        det = calibrate_combined(ev.identified, momentum.detector, det_c, runs, folds)
    return combined_detection(ev.identified, ev.dataset, momentum, found.t2["calibrated"], det_c, det, found.side,
                              args.label_widening)


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("detect", help=COMMANDS["detect"].help,
                        description="T² per sample, four variants side by side: combined (the default where it can be "
                        "calibrated: the momentum observer's and the calibrated acceleration residuals' T² summed, so "
                        "that neither side of an F/T sensor is blind; docs/detection.md#no-blind-side), momentum (the "
                        "generalized-momentum observer's residuals, no q̈), calibrated (acceleration-based residuals, Λ "
                        "and T²_α calibrated on contact-free data) and paper (diagonal Λ and the F threshold); Λ and "
                        "T²_α cross-validated over the fit's time blocks, the false positives on data outside the fit "
                        "and calibration reported beside the in-sample ones. Against the data's contact column (the skin's) or "
                        "--episodes labels: TPR, FPR, ROC/AUC, episodes found, onset delays, TPR per side of the F/T "
                        "sensor; without either, the false positives of a contact-free run.")
    sp.add_argument("--model", required=True, metavar="MODEL", help="a model file of `dynid fit`")
    sp.add_argument("--data", required=True, metavar="DATA",
                    help="the run to examine: a CSV, candump log, dataset file, simulate directory, YARP folder, ROS 2 "
                    "bag or a folder of files the configuration's 'files' describes")
    window_args(sp)
    payload_arg(sp, repeatable=False)
    sp.add_argument("--alpha", type=alpha, default=ALPHA, help=f"confidence level (default {ALPHA})")
    sp.add_argument("--n-mode", choices=N_MODES, default=DEFAULT_N_MODE, help="n of the paper's F threshold")
    sp.add_argument("--residual", choices=["momentum", "acceleration"], default=None,
                    help="default: the combined detector (the momentum observer's and the calibrated acceleration "
                    "residuals' T² summed, docs/detection.md#no-blind-side) and, beside it, the momentum detector and "
                    "the two acceleration-based variants; momentum: T² on the generalized-momentum observer's "
                    "residuals, which need no q̈, beside the acceleration-based variants (without the combined "
                    "detector); acceleration: those two only")
    sp.add_argument("--bandwidth", type=positive_float, default=DEFAULT_BANDWIDTH_HZ, metavar="HZ",
                    help=f"the momentum observer's bandwidth K_O/2π (default {DEFAULT_BANDWIDTH_HZ:g} Hz: "
                    f"a {1e3 / (2 * np.pi * DEFAULT_BANDWIDTH_HZ):.1f} ms time constant)")
    sp.add_argument("--calibration", action="append", metavar="DATA",
                    help="a contact-free run to calibrate the momentum detector on (repeatable; default: the runs "
                    "the model was fitted on)")
    sp.add_argument("--calibration-from", type=finite_float, metavar="S", help="calibrate on --calibration from S on")
    sp.add_argument("--calibration-to", type=finite_float, metavar="S", help="calibrate on --calibration up to S")
    sp.add_argument("--episodes", metavar="EPISODES.csv",
                    help="contact labels, a CSV 't_start,t_end' one episode a row in the data's seconds; "
                    "replaces the data's contact column")
    sp.add_argument("--label-widening", type=non_negative_float, default=0.0, metavar="S",
                    help="the labels were widened by S on each side: also report onset delays against start + S")
    json_arg(sp)
    sp.set_defaults(func=cmd_detect)

