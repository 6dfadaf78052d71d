"""`dynid play`: a recorded run onto the robot's CAN bus, through its bus description (dynid.export.player)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..config.robot_config import load_config
from ..errors import InputError
from ..export.player import ENCODERS, STAMPS, play_run
from ..io.load import apply_window, load_data
from .commands import COMMANDS
from .common import bad_rows, check_outputs, json_arg, robot_arg, skipped_rows, window, window_args


def cmd_play(args: argparse.Namespace) -> dict[str, Any]:
    kind, _, where = args.sink.partition(":")
    if kind not in ("candump", "loopback", "socketcan") or (kind != "socketcan" and not where):
        raise InputError(f"--sink must be candump:PATH, loopback:DIR or socketcan, got {args.sink!r}")
    if kind != "candump" and not args.realtime:  # a live monitor stamps frames as they come: they must come in time
        raise InputError(f"--sink {args.sink} is live: add --realtime (as fast as possible, rt_monitor would read the "
                         "samples microseconds apart and refuse their period)")
    if kind == "candump" and where != "-":
        check_outputs(args, {"sink": where})
    config = load_config(args.robot, args.urdf)
    data = load_data(args.data, config, bad_rows=bad_rows(args))
    data = apply_window(data, *window(args), source=args.data)
    dropped = skipped_rows(args.data, data.meta)
    played = play_run(config, data, args.sink, args.realtime, args.encoder, args.t0, args.strain_sat, args.stamps)
    lo, hi = played.step_range_s
    out = sys.stderr if args.sink == "candump:-" else sys.stdout  # the log itself is on standard output
    print(played.summary, file=out)
    if played.nominal_s is None:
        stamps = "their recorded stamps"
    elif abs(played.nominal_s - played.bus_period_s) <= 1e-6:
        stamps = f"stamps every {1e3 * played.nominal_s:.6g} ms (the bus's period)"
    else:
        stamps = (f"stamps every {1e3 * played.nominal_s:.6g} ms (the run's median step: the bus's period, "
                  f"{1e3 * played.bus_period_s:.6g} ms, is not the run's)")
    print(f"played {args.data} ({config.name}) -> {args.sink}: {played.samples} samples at {stamps} (recorded: mean "
          f"step {1e3 * played.period_s:.4g} ms, {1e3 * lo:.4g} to {1e3 * hi:.4g} ms), {played.frames} frames",
          file=out)
    first = float(data.t[0])
    played_on = "log" if kind == "candump" else "bus"
    on_grid = played.nominal_s is None or (abs(played.period_s - played.nominal_s) <= 1e-9
                                           and hi - lo <= 1e-6 * played.nominal_s)
    if not on_grid and played.samples > 1:  # re-stamped: the run's samples map to the log's by index, not by time
        print(f"time: the {played_on}'s sample k is the run's k-th sample from t = {first:.6g} s on, stamped k × "
              f"{1e3 * played.nominal_s:.6g} ms after the first; `dynid import`, `dynid spy` and rt_monitor count time "
              f"from that first sample, so a time T there is the run's sample k = T / {1e3 * played.nominal_s:.6g} ms "
              f"(its time is not T + {first:.6g} s where the recorded steps are not the grid's)", file=out)
    elif abs(first) > 1e-9:  # the log's times count from its first frame: say where that is in the run
        print(f"time: the {played_on}'s first sample is the run's t = {first:.6g} s; `dynid import`, `dynid spy` and "
              f"rt_monitor count time from it: a time there is the run's less {first:.6g} s (shift the run's "
              "episode labels by as much)", file=out)
    if played.dq_estimated:
        print("note: the run records no q̇ and the bus carries it: sent as the configuration's derivative filter "
              "estimates it from q (a recording's own q̇, where there is one, is what the robot would send)", file=out)
    if played.nominal_s is not None and hi - lo > 0.05 * played.nominal_s:
        print(f"note: the log's stamps are the nominal grid, not the recording's (its steps of {1e3 * lo:.4g} to "
              f"{1e3 * hi:.4g} ms each went out as {1e3 * played.nominal_s:.6g} ms): its time axis is the monitor's, "
              "not the robot's; analyse the recording itself offline (validate, detect), not this log", file=out)
    if data.contact is None and config.bus is not None and config.bus.patches:
        print("note: the run has no contact column: the skin boards' frames are not sent (the log reads back with no "
              "contact ground truth, and rt_monitor reports them as silent frames)", file=out)
    drift = played.drift
    if drift is not None and drift.misleads():
        print(f"note: the recorded steps are not whole periods of {1e3 * drift.period_s:.6g} ms: they drift "
              f"{drift.drift_s:+.4g} s over {drift.span_s:.4g} s ({drift.ppm:.0f} ppm) from rt_monitor's sample clock, "
              "which reads that as samples lost or late and bridges or holds them; --stamps nominal plays the "
              "samples one for one, as `dynid detect` and `dynid export` take them", file=out)
    return {"robot": config.name, "data": args.data, "sink": args.sink, "samples": played.samples,
            "frames": played.frames, "load": played.load, "period_s": played.period_s,
            "sent_period_s": played.nominal_s, "step_min_s": lo, "step_max_s": hi, "stamps": args.stamps,
            "realtime": args.realtime, "encoder": args.encoder, "dq_estimated": played.dq_estimated,
            "clock_drift": None if drift is None else {"period_s": drift.period_s, "drift_s": drift.drift_s,
                                                       "ppm": drift.ppm, "periods": drift.periods,
                                                       "misleads_the_monitor": drift.misleads()},
            "bad_rows": dropped, "first_sample_t_s": first}


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("play", help=COMMANDS["play"].help,
                        description="Play a recorded run (any form dynid reads: CSV, headerless log, folder of "
                        "files, YARP folder, ROS 2 bag, simulated run, dataset, candump log) onto the robot's CAN bus as its bus "
                        "description says (the configuration's 'bus', or the iCub protocol's 'can'), through "
                        "firmware_like's boards: a candump log, the loopback transport rt_monitor --loopback reads, "
                        "or SocketCAN. Samples are never resampled: they go out at their recorded stamps (a jittered log "
                        "stays jittered) or, with --stamps nominal, on the grid of the nominal period; paced in real time or "
                        "as fast as possible; each bus's load is printed.")
    robot_arg(sp)
    sp.add_argument("--data", required=True, metavar="RUN", help="the run to play (RUN@FROM:TO: a window of it)")
    sp.add_argument("--sink", required=True, metavar="SINK", help="candump:PATH (a candump -L log; candump:- to "
                    "standard output), loopback:DIR (rt_monitor --loopback DIR), or socketcan (the buses' interfaces)")
    sp.add_argument("--realtime", action="store_true", help="pace the samples at the run's own times (the live "
                    "sinks, loopback and socketcan, need it and are refused without; default: as fast as possible)")
    sp.add_argument("--encoder", choices=ENCODERS, default="auto", help="auto (default: the iCub board emulators for "
                    "the iCub protocol's bus, the generic encoder for any other), generic, or icub")
    sp.add_argument("--strain-sat", choices=("auto", "on", "off"), default="auto", help="frames' long forms (the "
                    "iCub strain board's 7-byte saturation variant): where one of their flags would be set in the "
                    "run (auto), always, never")
    sp.add_argument("--stamps", choices=STAMPS, default="recorded", help="recorded (default: each sample at its own "
                    "stamp; a jittered log stays jittered and the monitor bridges its gaps) or nominal (sample k at "
                    "the first stamp + k times the nominal period: the bus's where its rate agrees with the run's "
                    "median step to 5 %%, else that median step; the run's samples one for one, none bridged, as the "
                    "offline analysis and `dynid export` take them)")
    # not --t0, which a --to typed one key off would become: the stamps moved, and the window left open
    sp.add_argument("--first-stamp", dest="t0", type=float, default=None, metavar="S",
                    help="the first sample's stamp on the bus, s (default 1700000000)")
    window_args(sp)
    json_arg(sp)
    sp.set_defaults(func=cmd_play)
