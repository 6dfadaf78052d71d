"""`dynid export`: the identified model -> the coefficient file of the real-time monitor; `--print` dumps one."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from ..config.bus import LOAD_LIMIT
from ..config.robot_config import DEFAULT_ROBOT, RobotConfig, load_config
from ..errors import InputError
from ..export.coefficients import (
    DEFAULT_END_S,
    DEFAULT_ONSET_S,
    DEFAULT_HYSTERESIS,
    MAX_WINDOW,
    EventSettings,
    describe,
    read_coefficients,
)
from ..detect.momentum import DEFAULT_BANDWIDTH_HZ
from ..export.model_export import MOMENTUM_EVENTS, ExportSettings, export_cad, export_model
from ..identify.model_file import load_model
from .commands import COMMANDS
from .common import check_outputs, model_robot
from .common import confidence as alpha
from .common import int_in, json_arg, payload_arg, payloads, plural, positive_float, split_data_window
from .common import non_negative_int as lag


# Debounce counts are samples (an int32 in the file: a larger one ended `export` in a struct.error traceback); a
# million is over 16 minutes at 1 kHz.
MAX_DEBOUNCE = 1_000_000


def _settings(args: argparse.Namespace) -> ExportSettings:
    """Given event settings apply to the residual the monitor runs; unset ones take that residual's defaults."""
    def events(default: EventSettings) -> EventSettings:
        given = (args.debounce_on, args.debounce_off, args.hysteresis)
        fallback = (default.debounce_on, default.debounce_off, default.hysteresis)
        return EventSettings(*(g if g is not None else d for g, d in zip(given, fallback)))

    split = [split_data_window(text) for text in args.data or ()]  # --data RUN@FROM:TO, as every command takes it
    return ExportSettings(tuple(p for p, _ in split), tuple(w for _, w in split), args.lag, args.window, args.alpha,
                          events(EventSettings()), args.residual, args.bandwidth, events(MOMENTUM_EVENTS),
                          args.rate or 1000.0, tuple(payloads(args, len(split))))


def _export_bus(args: argparse.Namespace, edited: RobotConfig | None) -> dict[str, Any]:
    """--dbc OUT.dbc and --monitor-config OUT.conf: the robot's bus description as a DBC written through cantools, and
    compiled into the monitor's configuration; the robot of --model, else --robot. Nothing is written unless the
    monitor can hold the bus (its capacity) and every output can be written."""
    from ..export.monitor_config import check_capacity, monitor_config_text
    from ..io.can_database import dbc_files
    from ..io.dataset import atomic_write

    # the bus alone: a robot whose URDF the user supplies exports its DBC and monitor configuration without it. With
    # --model and its robot's configuration edited since the fit (--robot), the edited bus: the bus is not the fit's (a
    # walkthrough's changed F/T scale went unwritten, the monitor then refused the model at start, with no hint why)
    if edited is not None:
        print(f"note: {args.robot} is not the configuration {args.model} was fitted with (edited since): its bus is "
              "written; the model's own configuration is kept for the rest (fit again to take the edit there)")
    config = edited or (load_model(args.model).config if args.model else load_config(args.robot, args.urdf,
                                                                                     need_urdf=False))
    bus = check_capacity(config)
    dbcs = dbc_files(bus, config.name) if args.dbc else {}
    paths = {}
    for suffix, text in dbcs.items():  # IDs shared between buses: one DBC per bus, OUT-<bus>.dbc
        out = Path(args.dbc)
        paths[suffix] = str(out.with_name(f"{out.stem}-{suffix}{out.suffix}")) if suffix else args.dbc
    outputs = {f"dbc ({k or 'all buses'})": v for k, v in paths.items()}
    if args.monitor_config:
        outputs["monitor-config"] = args.monitor_config
    check_outputs(args, outputs)
    load = bus.load()
    full = next((b for b, v in load.items() if v >= 1.0), None)
    if full is not None:  # a sample's frames do not fit in its period: no bus carries that
        raise InputError(f"{config.name}: bus {full} would be loaded at {100 * load[full]:.0f} % (at {bus.rate:g} Hz, "
                         f"worst-case bit stuffing, {bus.bitrate / 1e6:g} Mbit/s): a sample's frames do not fit in its "
                         "period; move frames to another bus, or check 'rate' and 'bitrate'")
    conf_text = monitor_config_text(config, args.lcm_url) if args.monitor_config else ""
    for suffix, path in paths.items():
        atomic_write(path, lambda f, t=dbcs[suffix]: f.write(t.encode()))
    if args.monitor_config:
        atomic_write(args.monitor_config, lambda f: f.write(conf_text.encode()))
    n_signals = sum(len(f.signals) for f in bus.frames)
    origin = "the iCub protocol ('can')" if bus.origin == "can" else "its 'bus' description"
    print(f"{config.name}: {len(bus.frames)} frames, {n_signals} signals on {len(bus.buses)} bus"
          f"{'es' * (len(bus.buses) != 1)}, from {origin}; a sample every {1e3 / bus.rate:g} ms, completed by "
          f"{bus.clock}")
    for b, v in load.items():
        print(f"  bus {b}: load {100 * v:.1f} % at {bus.rate:g} Hz (worst-case bit stuffing, {bus.bitrate / 1e6:g} Mbit/s)"
              + ("  over the 70 % budget" if v >= LOAD_LIMIT else ""))
    for path in paths.values():
        print(f"  DBC -> {path} (python -m cantools decode {path} < candump.log)")
    if args.monitor_config:
        print(f"  monitor configuration -> {args.monitor_config} (rt_monitor --config {args.monitor_config})")
    return {"robot": config.name, "origin": bus.origin, "dbc": list(paths.values()),
            "monitor_config": args.monitor_config, "frames": len(bus.frames), "signals": n_signals,
            "rate_hz": bus.rate, "clock": bus.clock, "load": load}


def cmd_export(args: argparse.Namespace) -> dict[str, Any]:
    edited = model_robot(args)  # the model carries its robot: another one given is a mistake, not ignored
    if edited is not None and not (args.dbc or args.monitor_config):
        print(f"note: {args.robot} is not the configuration {args.model} was fitted with (edited since): the model's "
              "own is used (fit again to take the edit)")
    if args.dbc or args.monitor_config:
        if args.cad or args.print or (args.urdf and args.model):
            raise InputError("--dbc and --monitor-config go with --model MODEL or --robot CFG [--urdf FILE] (and --out "
                             "COEF_FILE)")
        result = _export_bus(args, edited)
        if args.model and args.out:
            result["coefficients"] = _export_coefficients(args)
        return result
    if args.lcm_url:
        raise InputError("--lcm-url goes with --monitor-config OUT.conf")
    if args.print:
        c = read_coefficients(args.print)
        print(describe(c))
        return {"file": args.print, "robot": c.robot_name, "n_joints": c.n_joints, "n_outputs": c.n_outputs,
                "channels": list(c.channel_names), "threshold": c.threshold, "alpha": c.alpha,
                "window": c.window, "lag": c.lag}
    if args.rate is not None and not args.cad:
        raise InputError("--rate goes with --cad: a calibrated export takes its data's sample rate")
    if args.cad:
        if not args.out:
            raise InputError("export --cad needs --out COEF_FILE")
        config = load_config(args.robot, args.urdf)
        size = export_cad(config, args.out, _settings(args))
        print(f"exported the CAD model of {config.name} (uncalibrated: for tests and benchmarks) -> {args.out} "
              f"({size} bytes)")
        return {"out": args.out, "bytes": size, "robot": config.name, "cad": True}
    if args.nearest_physical and not (args.model and args.urdf):
        raise InputError("--nearest-physical goes with --model MODEL --urdf OUT.urdf")
    if args.model and args.urdf:
        return _export_urdf(args)
    if not args.model or not args.out:
        raise InputError("export needs --model MODEL and --out COEF_FILE, or --urdf OUT.urdf, or --dbc OUT.dbc / "
                         "--monitor-config OUT.conf (the robot's bus; --robot CFG or --model), or --print COEF_FILE")
    return _export_coefficients(args)


def _export_urdf(args: argparse.Namespace) -> dict[str, Any]:
    """--model MODEL --urdf OUT.urdf [--out COEF_FILE]: the identified robot as a URDF and its side file."""
    from ..export.urdf import export_urdf, side_file

    side = side_file(args.urdf)
    check_outputs(args, {"urdf": args.urdf, "urdf's side file": str(side)})
    identified = load_model(args.model)
    try:
        identified.robot_model  # noqa: B018 - the robot and its URDF, found before any work
    except InputError as e:
        raise InputError(f"{args.model}: the robot's URDF cannot be found or read (the model file names "
                         f"{identified.robot.urdf or 'none'}); put its folder in DYNID_URDF_PATH ({e})") from None
    done = export_urdf(identified, args.urdf, allow_residual=args.nearest_physical)
    ps = done.physical
    print(f"exported {identified.config.name} -> {args.urdf} (the identified robot) and {done.side}")
    print(f"  inertial: {len(done.identified_links)} links free to move, {len(done.moved_links)} moved from the URDF's "
          f"values ({', '.join(done.moved_links) or 'none'}), "
          f"{len(done.cad_links)} keep CAD; distance to CAD {ps.distance:.4g} (scaled), smallest scaled "
          f"pseudo-inertia eigenvalue {ps.min_eigenvalue:.3g}; largest base-parameter change "
          f"{100 * done.base_relative_error:.2g} % of the largest identified one")
    if done.rerooted:
        print(f"  written in the URDF's original tree (the configuration re-roots it at {identified.config.base_link})")
    for note in done.notes:  # an implausible written link (a centre of mass metres out) is not to be simulated unread
        implausible = note.startswith("the written set: ")
        print(f"  {'WARNING' if implausible else 'note'}: {note}"
              + (" (the data do not place this link: check it before a simulator loads the URDF)" if implausible else ""))
    result: dict[str, Any] = {
        "model": args.model, "urdf": args.urdf, "side_file": str(done.side), "robot": identified.config.name,
        "identified_links": done.identified_links, "moved_links": done.moved_links, "cad_links": len(done.cad_links), "distance_to_cad": ps.distance,
        "min_scaled_pseudo_inertia_eigenvalue": ps.min_eigenvalue, "base_relative_error": done.base_relative_error,
        "nearest_physical": bool(args.nearest_physical), "rerooted": done.rerooted, "notes": done.notes,
    }
    if args.out:
        result["coefficients"] = _export_coefficients(args)
    return result


def _sides(thresholds: dict[str, float]) -> str:
    return ", ".join(f"{s} {t:.4g}" for s, t in thresholds.items()) or "none (no F/T sensor)"


def _export_coefficients(args: argparse.Namespace) -> dict[str, Any]:
    identified = load_model(args.model)
    done = export_model(identified, args.out, _settings(args))
    est, cal, tracking, alpha = done.filter, done.calibration, done.tracking, done.alpha
    det = identified.calibrated
    offline = cal.variance if det is None else det.variance
    print(f"exported {identified.config.name} -> {args.out} ({done.size} bytes)")
    for e in done.effects:
        print(f"  effect {e.kind} on {e.where}: " + ", ".join(f"{k} {v:.4g}" for k, v in e.parameters.items()))
    print(f"  online filter: fixed-lag Savitzky-Golay, window {est.window}, order {est.order}, lag {est.lag} "
          f"({1e3 * est.lag * est.sample_period:.3g} ms) at {1 / est.sample_period:.6g} Hz")
    if tracking is not None:
        print(f"  supply tracking: time constant {tracking.time_constant_s:g} s, gate {tracking.gate:g} noise stds")
    print(f"  T²_α (α = {alpha}) through the online filter: {cal.threshold:.4g} (offline "
          f"{float('nan') if det is None else det.threshold:.4g}); F/T-side thresholds {_sides(cal.ft_thresholds)}; {cal.samples} "
          "calibration samples")
    print("  Λ online / offline: " + ", ".join(f"{n} {a / b:.2f}" for n, a, b in zip(done.channels, cal.variance, offline)))
    obs = done.observer
    if obs is not None:
        d = obs.detector
        velocity = ("the robot's measured q̇ (dq.J on its bus)" if obs.measured
                    else f"causal q̇ over {obs.velocity_window} samples")
        print(f"  momentum observer: bandwidth {d.bandwidth_hz:g} Hz, {velocity}; "
              f"T²_α {d.threshold:.4g}, F/T-side thresholds {_sides(d.ft_thresholds)}; {d.samples} "
              "calibration samples")
    else:
        print(f"  momentum observer: not carried ({done.observer_note})")
    if done.combined_scale > 0:
        print(f"  combined detector: s = (T²_o/T²_o,α + T²/T²_α)/{done.combined_scale:.4g}, κ the sum's α-quantile on "
              "paired contact-free samples of both residuals")
    else:
        print(f"  combined detector: not carried ({done.combined_note})")
    ev = done.events
    level = "1 (s)" if done.residual == "combined" else "T²_α"
    print(f"  the monitor runs the {done.residual} residuals; events: onset after {plural(ev.debounce_on, 'sample')} "
          f"above {level}, end after {ev.debounce_off} below {ev.hysteresis:g}·{level}")
    if done.residual == "acceleration" and obs is not None and args.residual is None:
        # the default fell back from the combined detector: the observer is in the file all the same
        print("  the file carries the momentum observer too: `rt_monitor --residual momentum` (or export "
              "--residual momentum) runs it instead, on q and q̇ with no q̈ to filter")
    momentum = None if obs is None else {
        "bandwidth_hz": obs.detector.bandwidth_hz, "velocity": "measured" if obs.measured else "causal",
        "velocity_window": obs.velocity_window,
        "threshold": obs.detector.threshold, "ft_thresholds": obs.detector.ft_thresholds,
        "residual_variance": dict(zip(done.channels, obs.detector.variance.tolist())),
        "calibration_samples": obs.detector.samples}
    return {"model": args.model, "out": args.out, "residual": done.residual, "momentum": momentum,
            "combined_scale": done.combined_scale or None,
            "events": {"debounce_on": ev.debounce_on, "debounce_off": ev.debounce_off, "hysteresis": ev.hysteresis},
            "bytes": done.size, "threshold": cal.threshold,
            "ft_thresholds": cal.ft_thresholds, "alpha": alpha,
            "residual_variance": dict(zip(done.channels, cal.variance.tolist())),
            "filter": est.as_dict(), "calibration_samples": cal.samples,
            "effects": [{"kind": e.kind, "where": e.where, "parameters": e.parameters} for e in done.effects]}


def add_commands(sub: argparse._SubParsersAction) -> None:
    def fraction(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
        if not 0 < value <= 1:
            raise argparse.ArgumentTypeError(f"must be in (0, 1], got {text}")
        return value

    sp = sub.add_parser("export", help=COMMANDS["export"].help,
                        description="Write the coefficient file rt_monitor loads (rt_monitor/README.md): the chain, "
                        "the identified parameters, the channels, the fixed-lag derivative filter, the momentum "
                        "observer and the combined detector's level, each Λ and T²_α computed as the monitor computes "
                        "its residuals on the contact-free identification data, cross-validated over the fit's time "
                        "blocks (or on --data), and the answers the monitor checks its core against at start. "
                        "With --urdf OUT.urdf: the robot's URDF with the identified inertial parameters in every link "
                        "(the physically consistent full set nearest CAD that reproduces the identified base "
                        "parameters), the symmetric friction in <dynamics>, and the rest in OUT.dynamics.yaml "
                        "(docs/formats.md). With --dbc / --monitor-config: the robot's CAN bus as a DBC and as the "
                        "monitor's configuration (of --model's robot, or of --robot without a model).")
    sp.add_argument("--model", metavar="MODEL", help="the model file of `dynid fit`")
    sp.add_argument("--out", metavar="COEF_FILE", help="the coefficient file to write (atomically)")
    sp.add_argument("--print", metavar="COEF_FILE", help="print a coefficient file readably instead")
    sp.add_argument("--cad", action="store_true", help="export the CAD model of --robot, uncalibrated (for tests "
                    "and benchmarks: nominal gains, no friction, Λ = the noise σ², the F threshold, at --rate)")
    sp.add_argument("--rate", type=positive_float, default=None, metavar="HZ",
                    help="with --cad: the boards' sample rate (default 1000 Hz)")
    sp.add_argument("--robot", default=None, metavar="CFG", help="robot of --cad, --dbc and --monitor-config when no "
                    f"--model is given (default {DEFAULT_ROBOT}); with --model, the model's robot (another is refused)")
    sp.add_argument("--dbc", metavar="OUT.dbc", help="write the robot's CAN bus (its configuration's bus description) "
                    "as a DBC that cantools reads (`python -m cantools decode OUT.dbc < candump.log`); one DBC per bus, "
                    "OUT-<bus>.dbc, where buses share IDs; prints each bus's load")
    sp.add_argument("--monitor-config", metavar="OUT.conf", help="write rt_monitor's configuration: the settings and "
                    "the bus description compiled into the table the monitor decodes (docs/formats.md)")
    sp.add_argument("--lcm-url", metavar="URL", help="with --monitor-config: the LCM URL the monitor publishes to")
    sp.add_argument("--urdf", metavar="FILE", help="with --model: the URDF to write, the identified robot (and its "
                    "side file FILE.dynamics.yaml: asymmetric friction, motor gains, coupling, F/T offsets); with "
                    "--cad: the URDF of --robot, replacing the configuration's")
    sp.add_argument("--nearest-physical", action="store_true", help="with --urdf: where no physically consistent "
                    "full set reproduces the identified base parameters, write the nearest one and state its residual "
                    "(default: exit 2 and say so)")
    sp.add_argument("--data", action="append", metavar="DATA",
                    help="contact-free data for Λ and T²_α (default: the model's identification data, each run with "
                    "the payload the fit was told of); repeatable")
    payload_arg(sp, repeatable=True)
    sp.add_argument("--lag", type=lag, metavar="N", help="filter lag in samples, 0 = causal (default: window // 4)")
    sp.add_argument("--window", type=int_in(3, MAX_WINDOW), metavar="N", help="filter window in samples, 3 to "
                    f"{MAX_WINDOW} (the monitor's capacity; default: the configuration's offline window)")
    sp.add_argument("--alpha", type=alpha, help="confidence level (default: the model's)")
    sp.add_argument("--residual", choices=["combined", "acceleration", "momentum"], default=None,
                    help="what the monitor runs: combined (default where the observer and the combined level can be "
                    "calibrated: both residuals' T² summed, docs/detection.md#no-blind-side; else acceleration), "
                    "acceleration (the fixed-lag derivative filter's q̈) or momentum (the generalized-momentum "
                    "observer, no q̈; not for a model with named effects). The file carries every calibration it can "
                    "(rt_monitor --residual switches); docs/detection.md#the-monitor")
    sp.add_argument("--bandwidth", type=positive_float, default=DEFAULT_BANDWIDTH_HZ, metavar="HZ",
                    help=f"the momentum observer's bandwidth K_O/2π (default {DEFAULT_BANDWIDTH_HZ:g} Hz)")
    sp.add_argument("--debounce-on", type=int_in(1, MAX_DEBOUNCE), default=None, metavar="N",
                    help=f"samples above T²_α for an onset (default {DEFAULT_ONSET_S * 1e3:g} ms of samples at the "
                    "file's rate: 10 at 1 kHz, 1 at 100 Hz)")
    sp.add_argument("--debounce-off", type=int_in(1, MAX_DEBOUNCE), default=None, metavar="N",
                    help=f"samples below the hysteresis level for an end (default {DEFAULT_END_S * 1e3:g} ms of "
                    "samples: 100 at 1 kHz)")
    sp.add_argument("--hysteresis", type=fraction, default=None,
                    help=f"end level as a fraction of T²_α (default {DEFAULT_HYSTERESIS})")
    json_arg(sp)
    sp.set_defaults(func=cmd_export)
