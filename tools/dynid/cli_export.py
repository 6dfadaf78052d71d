"""`dynid export`: the identified model -> the coefficient file of the real-time monitor; `--print` dumps one."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from .errors import DataError, InputError


def _calibration_data(identified, model, data: list[str] | None) -> tuple[list, str]:
    """The contact-free data Λ and T²_α come from: --data, else what the model was fitted on (checked by sha256)."""
    from .evaluation import load_run
    from .identified import data_file, file_digest

    if data:
        paths = data
    else:
        record = identified.record.get("data") or []
        if not record:
            raise DataError(f"{identified.path} names no identification data; pass --data")
        paths = []
        for entry in record:
            p = data_file(entry["path"])
            if not p.is_file():
                raise DataError(f"the identification data {entry['path']} are gone; pass the contact-free data with --data")
            if file_digest(p) != entry["sha256"]:
                raise DataError(f"the identification data {entry['path']} changed since the fit (sha256); pass --data")
            paths.append(entry["path"])
    digests = ",".join(file_digest(data_file(p)) for p in paths)
    return [load_run(p, model) for p in paths], digests


CAD_SAMPLES = 100_000  # the N of the F threshold of an uncalibrated (CAD) export


def _export_cad(args: argparse.Namespace) -> dict[str, Any]:
    """The CAD model with nominal gains and no friction or offsets, Λ = the channels' noise σ², the F threshold:
    uncalibrated, for tests and benchmarks that need a coefficient file without a fit."""
    from .config import load_config
    from .detection import f_threshold
    from .export import build_coefficients, write_coefficients
    from .model import RobotModel
    from .online import estimator_for
    from .outputs import output_channels

    if not args.out:
        raise InputError("export --cad needs --out COEF_FILE")
    config = load_config(args.robot)
    model = RobotModel(config)
    phi = np.nan_to_num(model.cad_parameters(), nan=0.0)
    for m in model.layout.owners("motor_gain"):
        phi[model.layout.block("motor_gain", m).start] = config.motor(m).nominal_gain
    outs = output_channels(model)
    variance = np.array([o.sigma for o in outs]) ** 2
    alpha = 0.99 if args.alpha is None else args.alpha
    est = estimator_for(model, np.arange(3) * 1e-3, args.lag, args.window)
    c = build_coefficients(model, phi, variance, f_threshold(len(outs), CAD_SAMPLES, alpha),
                           f_threshold(6, CAD_SAMPLES, alpha), alpha, 0.01, CAD_SAMPLES, est, {"estimator": "cad"},
                           args.debounce_on, args.debounce_off, args.hysteresis)
    size = write_coefficients(c, args.out)
    print(f"exported the CAD model of {config.name} (uncalibrated: for tests and benchmarks) -> {args.out} ({size} bytes)")
    return {"out": args.out, "bytes": size, "robot": config.name, "cad": True}


def cmd_export(args: argparse.Namespace) -> dict[str, Any]:
    from .export import build_coefficients, describe, exportable_effects, read_coefficients, write_coefficients
    from .online import calibrate_online, estimator_for

    if args.print:
        c = read_coefficients(args.print)
        print(describe(c))
        return {"file": args.print, "robot": c.robot_name, "n_joints": c.n_joints, "n_outputs": c.n_outputs,
                "channels": list(c.channel_names), "threshold": c.threshold, "alpha": c.alpha,
                "window": c.window, "lag": c.lag}
    if args.cad:
        return _export_cad(args)
    if not args.model or not args.out:
        raise InputError("export needs --model MODEL and --out COEF_FILE (or --print COEF_FILE)")
    from .identified import file_digest, load_model

    identified = load_model(args.model)
    model = identified.robot_model
    effects = identified.effects
    exportable_effects(effects)  # before the (slow) calibration: an effect the monitor lacks is refused at once
    datasets, data_digest = _calibration_data(identified, model, args.data)
    est = estimator_for(model, datasets[0].t, args.lag, args.window)
    for ds in datasets[1:]:
        if abs(estimator_for(model, ds.t, args.lag, args.window).sample_period - est.sample_period) > 1e-9:
            raise DataError("the calibration data have different sample rates")
    det = identified.record.get("detector", {}).get("calibrated", {})
    alpha = float(det.get("alpha", 0.99)) if args.alpha is None else args.alpha
    min_speed = float(det.get("min_speed", 0.01))
    tracking = identified.supply_tracking
    cal = calibrate_online(model, identified.phi, datasets, est, alpha, min_speed, effects=effects, tracking=tracking)
    c = build_coefficients(model, identified.phi, cal.variance, cal.threshold, cal.ft_threshold, alpha, min_speed,
                           cal.samples, est, {"model_sha256": file_digest(args.model), "data_sha256": data_digest,
                                               "estimator": str(identified.record.get("estimator", ""))},
                           args.debounce_on, args.debounce_off, args.hysteresis, effects, tracking)
    size = write_coefficients(c, args.out)
    offline = np.asarray(det.get("variance", cal.variance), float)
    print(f"exported {model.config.name} -> {args.out} ({size} bytes)")
    for e in effects:
        print(f"  effect {e.kind} on {e.where}: " + ", ".join(f"{k} {v:.4g}" for k, v in e.parameters.items()))
    print(f"  online filter: fixed-lag Savitzky-Golay, window {est.window}, order {est.order}, lag {est.lag} "
          f"({1e3 * est.lag * est.sample_period:.3g} ms) at {1 / est.sample_period:.6g} Hz")
    if tracking is not None:
        print(f"  supply tracking: time constant {tracking.time_constant_s:g} s, gate {tracking.gate:g} noise stds")
    print(f"  T²_α (α = {alpha}) through the online filter: {cal.threshold:.4g} (offline {det.get('threshold', float('nan')):.4g});"
          f" F/T-side threshold {cal.ft_threshold:.4g}; {cal.samples} calibration samples")
    print("  Λ online / offline: " + ", ".join(f"{n} {a / b:.2f}" for n, a, b in zip(c.channel_names, cal.variance, offline)))
    return {"model": args.model, "out": args.out, "bytes": size, "threshold": cal.threshold,
            "ft_threshold": cal.ft_threshold, "alpha": alpha, "residual_variance": dict(zip(c.channel_names, cal.variance.tolist())),
            "filter": est.as_dict(), "calibration_samples": cal.samples,
            "effects": [{"kind": e.kind, "where": e.where, "parameters": e.parameters} for e in effects]}


def add_commands(sub: argparse._SubParsersAction, json_arg, positive_int) -> None:
    from .export import DEFAULT_DEBOUNCE_OFF, DEFAULT_DEBOUNCE_ON, DEFAULT_HYSTERESIS
    from .cli import confidence as alpha
    from .cli import non_negative_int as lag

    def fraction(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
        if not 0 < value <= 1:
            raise argparse.ArgumentTypeError(f"must be in (0, 1], got {text}")
        return value

    sp = sub.add_parser("export", help="write the real-time monitor's coefficient file (or --print one)",
                        description="Write the coefficient file rt_monitor loads (rt_monitor/README.md): the chain, "
                        "the identified parameters, the channels, Λ and T²_α computed through the monitor's own "
                        "fixed-lag derivative filter on the contact-free identification data, and the filter.")
    sp.add_argument("--model", metavar="MODEL", help="the model file of `dynid fit`")
    sp.add_argument("--out", metavar="COEF_FILE", help="the coefficient file to write (atomically)")
    sp.add_argument("--print", metavar="COEF_FILE", help="print a coefficient file readably instead")
    sp.add_argument("--cad", action="store_true", help="export the CAD model of --robot, uncalibrated (for tests "
                    "and benchmarks: nominal gains, no friction, Λ = the noise σ², the F threshold, 1 kHz)")
    sp.add_argument("--robot", default="icub_right_arm", metavar="CFG", help="robot of --cad (default icub_right_arm)")
    sp.add_argument("--data", action="append", metavar="DATA",
                    help="contact-free data for Λ and T²_α (default: the model's identification data); repeatable")
    sp.add_argument("--lag", type=lag, metavar="N", help="filter lag in samples, 0 = causal (default: window // 4)")
    sp.add_argument("--window", type=positive_int, metavar="N", help="filter window in samples (default: the "
                    "configuration's offline window)")
    sp.add_argument("--alpha", type=alpha, help="confidence level (default: the model's)")
    sp.add_argument("--debounce-on", type=positive_int, default=DEFAULT_DEBOUNCE_ON, metavar="N",
                    help=f"samples above T²_α for an onset (default {DEFAULT_DEBOUNCE_ON})")
    sp.add_argument("--debounce-off", type=positive_int, default=DEFAULT_DEBOUNCE_OFF, metavar="N",
                    help=f"samples below the hysteresis level for an end (default {DEFAULT_DEBOUNCE_OFF})")
    sp.add_argument("--hysteresis", type=fraction, default=DEFAULT_HYSTERESIS,
                    help=f"end level as a fraction of T²_α (default {DEFAULT_HYSTERESIS})")
    json_arg(sp)
    sp.set_defaults(func=cmd_export)
