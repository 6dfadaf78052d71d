"""`dynid import`, `dynid structure`, `dynid simulate`: data in, the structure it excites, simulated runs."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import load_config
from ..errors import InputError
from ..io.csv_format import read_csv
from ..io.load import apply_window, check_reference_velocities, load_data
from ..robot.model import RobotModel
from ..robot.regressors.base import data_base_parameters, exciting_signals
from ..robot.regressors.stack import row_channels, rows_at_rest, signals_from_dataset
from ..simulation import SimulationSettings, parse_effect, simulate
from ..simulation.controller import GivenTrajectory
from ..simulation.effects import CATALOG, catalog_text
from ..simulation.output import check_output_dir, write_simulation
from .commands import COMMANDS
from .common import (bad_rows, int_in, json_arg, min_speed_arg, positive_float, robot_arg, seed, skipped_rows, window,
                     window_args)


# `structure --samples`: 2000 random states give the structural rank; 10⁵ take about 0.7 GB, 10¹² ended in a
# MemoryError traceback.
MAX_STATES = 100_000


def cmd_import(args: argparse.Namespace) -> dict[str, Any]:
    config = load_config(args.robot, args.urdf)
    model = RobotModel(config)
    if not Path(args.data).exists() and (args.data.startswith("@") or any(c in args.data for c in "*?[")):
        raise InputError(f"{args.data}: import reads one run, and this names many (an @LIST or a glob, as fit and "
                         "fleet take them): import each run alone")
    dataset = apply_window(load_data(Path(args.data), config, joint_limits=model.joint_limits,
                                     bad_rows=bad_rows(args)), *window(args), source=args.data)
    dataset.meta.setdefault("robot", config.name)
    dataset.meta.setdefault("config_digest", config.digest)
    dataset.save(Path(args.out))
    skipped = int(dataset.meta.get("skipped_lines", 0)) if dataset.meta.get("source") == str(Path(args.data)) else 0
    fresh = dataset.meta.get("source") == str(Path(args.data))  # not a dataset file's record of an earlier import
    channels = (
        [f"q.{j}" for j in dataset.joints]
        + ([f"dq.{j}" for j in dataset.joints] if dataset.dq is not None else [])
        + ([f"ddq.{j}" for j in dataset.joints] if dataset.ddq is not None else [])
        + [f"pwm.{m}" for m in dataset.pwm]
        + [f"current.{m}" for m in dataset.current]
        + [f"tau.{j}" for j in dataset.tau]
        + [f"ft.{s}" for s in dataset.ft]
    )
    print(
        f"imported {dataset.n_samples} samples ({dataset.duration:.3f} s) of {config.name} from {args.data} -> {args.out}\n"
        f"  channels: {', '.join(channels)}"
        + ("" if dataset.dq is not None else "\n  no dq/ddq columns: derivatives will be estimated from q when needed")
        + (f"\n  extra columns kept: {len(dataset.extra)} ({', '.join(sorted(dataset.extra)[:4])}"
           f"{', ...' if len(dataset.extra) > 4 else ''})" if dataset.extra else "")
    )
    bad = skipped_rows(args.data, dataset.meta) if fresh else None
    ros2 = dataset.meta.get("ros2") if fresh else None
    if ros2:  # how the samples were formed (dynid.io.rosbag)
        print_ros2(ros2)
    yarp = dataset.meta.get("yarp")
    if yarp:  # what aligning the ports did (dynid.io.yarp)
        print(f"  yarp ports on one {yarp['rate_hz']:g} Hz time base (time 0 = Unix {yarp['origin_unix_s']:.3f} s):")
        for port, p in yarp["ports"].items():
            dropped = p["dropped_not_increasing"] + p["dropped_cut_last_line"] + p.get("dropped_bad_lines", 0)
            print(f"    {port}: {p['messages']} messages from {p['first_s']:.3f} s to {p['last_s']:.3f} s, every "
                  f"{1e3 * p['median_interval_s']:.1f} ms (longest {1e3 * p['max_interval_s']:.1f} ms)"
                  + (f", {dropped} dropped" if dropped else "")
                  + (f", {p['cut_short']} cut short (beyond another port's start or end)" if p.get("cut_short") else ""))
    return {
        "robot": config.name,
        "samples": dataset.n_samples,
        "duration_s": dataset.duration,
        "channels": channels,
        "has_derivatives": dataset.dq is not None,
        "contact": dataset.contact is not None,
        "skipped_lines": skipped,
        **({"bad_rows": bad} if bad is not None else {}),
        "out": args.out,
        **({"yarp": dataset.meta["yarp"]} if "yarp" in dataset.meta else {}),
        **({"ros2": ros2} if ros2 else {}),
    }


def print_ros2(info: dict[str, Any]) -> None:
    """How a bag's samples were formed: the clock, the wrenches' alignment, what was left out."""
    clock = info["clock"]
    if clock == "grid":
        print(f"  ROS 2 bag ({info['storage']}): every topic on one {info['rate_hz']:g} Hz grid (time 0 = "
              f"{info['origin_s']:.6f} s)")
    else:
        out = info["outside_wrench_span"]
        align = (f"; wrenches {info['wrench_alignment']} within {info['wrench_tolerance_s']:g} s"
                 if info["wrench_alignment"] else "")
        left = (f"; {out['before']} joint states before and {out['after']} after the wrenches left out"
                if out["before"] or out["after"] else "")
        print(f"  ROS 2 bag ({info['storage']}): {clock} is the sample clock{align}{left}")
    for topic, t in info["topics"].items():
        notes = [f"{t[k]} {what}" for k, what in (("other_publishers", "of other publishers left out"),
                                                  ("dropped_not_increasing", "dropped (stamp not increasing)"))
                 if t.get(k)]
        print(f"    {topic}: {t['messages']} messages" + (f", {', '.join(notes)}" if notes else ""))


def cmd_structure(args: argparse.Namespace) -> dict[str, Any]:
    config = load_config(args.robot, args.urdf)
    model = RobotModel(config)
    if args.data:
        data = load_data(Path(args.data), config, joint_limits=model.joint_limits, bad_rows=bad_rows(args))
        sig = signals_from_dataset(model, apply_window(data, *window(args), source=args.data))
        source = args.data
        skipped = skipped_rows(args.data, data.meta)
    else:
        skipped = None
        sig = exciting_signals(model, args.samples, args.seed)
        source = f"{args.samples} random states within the joint limits (seed {args.seed})"
    bp = data_base_parameters(model, sig, min_speed=args.min_speed)
    layout = model.layout
    print(f"robot {config.name}: {model.n_joints} joints, {len(model.bodies)} bodies, {len(layout)} parameters")
    print(f"  bodies: {', '.join(b.name for b in model.bodies)}")
    for kind in ("ft_offset", "joint_friction", "motor_friction", "motor_gain"):
        owners = layout.owners(kind)  # type: ignore[arg-type]
        if owners:
            print(f"  {kind.replace('_', ' ')}: {', '.join(owners)}")
    print(f"  rows per sample: {', '.join(c.name for c in row_channels(model))}")
    print(f"excitation: {source}")
    rest = rows_at_rest(model, sig.dq, args.min_speed)
    if rest.any():
        print(f"  rows left out where a friction coordinate is slower than {args.min_speed:g} rad/s (static friction): "
              f"{100 * rest.mean():.1f} % of all rows")
    print(f"numerical rank {bp.rank} of {len(layout)}; condition number {bp.condition_number:.4g} (the column-normalised, "
          "weighted regressor: largest over rank-th singular value)")
    if bp.unidentifiable:
        print(f"  act on no row (unidentifiable): {', '.join(bp.unidentifiable)}")
    if args.combinations:
        print("base parameters (identifiable combinations):")
        for c in bp.combinations():
            print(f"  {c}")
    return {
        "robot": config.name,
        "parameters": list(layout.names),
        "bodies": [b.name for b in model.bodies],
        "rows_per_sample": [c.name for c in row_channels(model)],
        "excitation": source,
        "rank": bp.rank,
        "condition_number": bp.condition_number,
        "unidentifiable": list(bp.unidentifiable),
        "base_parameters": bp.combinations(),
        "singular_values": bp.singular_values,
        **({"bad_rows": skipped} if skipped is not None else {}),
    }


def tilt_degrees(text: str) -> float:
    """--tilt DEG: 0 to 45 degrees (beyond, a robot does not stand)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of degrees") from None
    if not 0.0 <= value <= 45.0:
        raise argparse.ArgumentTypeError(f"{text} degrees is outside 0..45")
    return value


def _trajectory(path: str | None, config) -> GivenTrajectory | None:  # config: RobotConfig
    """--trajectory TRAJ.csv: an experiment CSV with t, q and dq of every joint (ddq optional, unused), t from 0, dq
    the rate of q."""
    if path is None:
        return None
    model = RobotModel(config)
    data = read_csv(path, config, joint_limits=model.joint_limits, require_all=False)
    if data.dq is None:
        raise InputError(f"{path}: the trajectory has no dq.<joint> columns; the controller follows q and dq "
                         "(dynid excite writes both)")
    if abs(float(data.t[0])) > 1e-9:
        raise InputError(f"{path}: the trajectory's time starts at {data.t[0]:g} s, not 0")
    check_reference_velocities(data, f"{path}: ")  # a dq that is not q's rate bends the path the plant follows
    return GivenTrajectory(data.t - data.t[0], data.q, data.dq, str(path))


def friction_scales(given: list[str], config) -> tuple[tuple[str, float], ...]:  # noqa: ANN001 - RobotConfig
    """--friction-scale [JOINT=]K, repeatable: (joint, factor) pairs; without JOINT, every joint. Later ones
    multiply earlier ones."""
    out: dict[str, float] = {}
    for text in given:
        joint, eq, value = text.rpartition("=")
        try:
            factor = float(value)
        except ValueError:
            factor = float("nan")
        if not np.isfinite(factor) or factor <= 0:
            raise InputError(f"--friction-scale {text}: the factor must be a positive number (e.g. 2, or "
                             f"{config.joints[-1]}=2)")
        if eq and joint not in config.joints:
            raise InputError(f"--friction-scale {text}: no joint '{joint}' in {config.name} (joints: "
                             f"{', '.join(config.joints)})")
        for j in ([joint] if eq else config.joints):
            out[j] = out.get(j, 1.0) * factor
    return tuple(out.items())


def cmd_simulate(args: argparse.Namespace) -> dict[str, Any]:

    if args.list_effects:
        print(catalog_text())

        return {"effects": {k: {"target": e.target, "stage": e.stage, "summary": e.summary, "defaults": e.defaults,
                                "units": e.units} for k, e in CATALOG.items()}}
    if not args.out:
        raise InputError("--out DIR is required (the directory to write the experiment to)")
    check_output_dir(args.out)  # before any work: a folder that is not an earlier simulated run is refused
    config = load_config(args.robot, args.urdf)
    bodies = tuple(b.name for b in RobotModel(config).bodies)
    effects = tuple(parse_effect(text, config, bodies) for text in args.effect)
    settings = SimulationSettings(
        kind=args.kind, duration=args.duration, seed=args.seed, robot_seed=args.robot_seed,
        noise=args.noise == "realistic", disturbance=args.disturbance == "realistic", effects=effects,
        rate_hz=args.rate, tilt_deg=args.tilt, trajectory=_trajectory(args.trajectory, config),
        friction_scale=friction_scales(args.friction_scale, config),
    )
    started = time.perf_counter()
    sim = simulate(config, settings)
    elapsed = time.perf_counter() - started
    files = write_simulation(sim, args.out)
    truth, realism = sim.truth, sim.truth["realism"]
    print(
        f"simulated {args.kind} of {config.name}: {settings.seconds:g} s at {args.rate:g} Hz "
        f"({truth['samples']} samples) in {elapsed:.1f} s -> {args.out}"
    )
    print(f"  true robot: seed {args.robot_seed}; experiment seed {args.seed}; noise {args.noise}; "
          f"motor disturbance {'on' if truth['disturbance'] else 'off'}")
    if effects:
        print(f"  hidden effects: {', '.join(e.kind + (f' on {e.target}' if e.target else '') for e in effects)}")
    if truth["contacts"]:
        sides = [c["side"] for c in truth["contacts"]]
        print(f"  contacts: {len(sides)} ({sides.count('distal')} distal, {sides.count('proximal')} proximal of the F/T sensor)")
    drive = (f"PWM within ±1: {100 * realism['pwm_within_limits']:.3f} % of samples; "
             if config.motors_with_input("pwm") else "")
    print(
        f"  {drive}joint limits respected: "
        f"{100 * realism['joint_limits_respected']:.2f} %; "
        + (f"{realism['reaching_targets']} reaching targets" if args.trajectory is None else f"following {args.trajectory}")
    )
    return {
        "robot": config.name, "kind": args.kind, "duration_s": settings.seconds, "rate_hz": args.rate,
        "samples": truth["samples"], "seed": args.seed, "robot_seed": args.robot_seed, "noise": args.noise,
        "friction_scale": dict(settings.friction_scale),
        "disturbance": truth["disturbance"], "effects": truth["effects"], "contacts": len(truth["contacts"]),
        "realism": realism, "wall_time_s": elapsed, "files": files,
    }


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("import", help=COMMANDS["import"].help,
                        description="Read an experiment (CSV as in docs/design.md §4, or a dataset file), check every "
                        "column against the robot configuration, and write the dataset file (.npz).")
    robot_arg(sp)
    sp.add_argument("--data", required=True, metavar="DATA",
                    help="the experiment: a .csv (with a header, or one the configuration's 'columns' describe), a "
                    "candump log, a ROS 2 bag (MCAP or SQLite), a YARP dumper folder, a folder of files the "
                    "configuration's 'files' describes, or a .npz dataset; RUN@FROM:TO "
                    "for a window")
    window_args(sp)
    sp.add_argument("--out", required=True, metavar="DATASET", help="the dataset file to write (.npz, atomically)")
    json_arg(sp)
    sp.set_defaults(func=cmd_import)

    sp = sub.add_parser("structure", help=COMMANDS["structure"].help,
                        description="Print the parameter vector's layout and the base-parameter structure: the "
                        "numerical rank of the weighted stacked A and the identifiable combinations, on random "
                        "exciting states (the structural rank) or on a recorded experiment (--data).")
    robot_arg(sp)
    sp.add_argument("--data", metavar="DATA", help="measure the rank on this experiment instead of random states")
    window_args(sp)
    sp.add_argument("--samples", type=int_in(1, MAX_STATES), default=2000,
                    help=f"random states for the structural rank, at most {MAX_STATES} (default 2000)")
    sp.add_argument("--seed", type=seed, default=0, help="seed of the random states, 0 or more (default 0)")
    sp.add_argument("--combinations", action="store_true", help="print every base-parameter combination")
    min_speed_arg(sp)
    json_arg(sp)
    sp.set_defaults(func=cmd_structure)

    sp = sub.add_parser("simulate", help=COMMANDS["simulate"].help,
                        description="Run the simulated plant: a true robot that is not the CAD model (perturbed "
                        "inertia, cables, friction, gains, F/T offsets) reaching random points under joint impedance, "
                        "PWM through the motor model and the coupling, with the boards' sensors. Writes dataset.npz, "
                        "data.csv, truth.json and truth.npz to DIR (tools/dynid/simulation/output.py). The same "
                        "--robot-seed is the same arm in every kind.")
    robot_arg(sp)
    sp.add_argument("--kind", default="identification", choices=["identification", "validation", "contact"],
                    help="identification (default 300 s), validation (120 s) or contact (120 s, with skin ground truth)")
    sp.add_argument("--duration", type=positive_float, metavar="S", help="seconds to simulate (default: per kind)")
    sp.add_argument("--seed", type=seed, default=0, metavar="N", help="experiment seed: reference, contacts, noise (default 0)")
    sp.add_argument("--robot-seed", type=seed, default=0, metavar="N", help="which true arm (default 0)")
    sp.add_argument("--noise", choices=["realistic", "none"], default="realistic",
                    help="'none' turns off sensor noise, quantisation and the motor disturbance")
    sp.add_argument("--disturbance", choices=["realistic", "none"], default="realistic",
                    help="supply-voltage variation and torque ripple of the motors (default realistic)")
    sp.add_argument("--effect", action="append", default=[], metavar="NAME[:k=v,...]",
                    help="switch on a hidden effect (repeatable); --list-effects shows them")
    sp.add_argument("--list-effects", action="store_true", help="list the hidden effects and their parameters")
    sp.add_argument("--friction-scale", action="append", default=[], metavar="[JOINT=]K",
                    help="scale the true arm's friction of JOINT (every joint without JOINT=) by K: a worn joint "
                    "(2), or friction that drifts between runs; repeatable (docs/simulation.md#the-true-robot)")
    sp.add_argument("--rate", type=positive_float, default=1000.0, metavar="HZ", help="sample rate (default 1000)")
    sp.add_argument("--tilt", type=tilt_degrees, default=0.0, metavar="DEG",
                    help="a base that tilts by up to DEG degrees about the root's x and y (periods 17 s and 23 s), "
                    "as a balancing humanoid's; the run records an accelerometer at the root (imu.ax, imu.ay, imu.az, "
                    "m/s²) for a configuration with 'gravity: {imu: FRAME}' (default 0: a fixed base)")
    sp.add_argument("--trajectory", metavar="TRAJ.csv",
                    help="follow this reference instead of the reaching moves: a CSV of t (from 0), q and dq of every "
                    "joint, dq the rate of q (0.9-1.1 times, else refused), e.g. from `dynid excite`; the arm starts "
                    "at its first sample, at rest; the duration defaults to the trajectory's")
    sp.add_argument("--out", metavar="DIR", help="the directory to write: new, empty, or an earlier simulated run's "
                    "(its four files are replaced); a directory holding anything else is refused")
    json_arg(sp)
    sp.set_defaults(func=cmd_simulate)
