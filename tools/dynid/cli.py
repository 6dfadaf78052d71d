"""The `dynid` command line (DESIGN.md §7).

Every command takes `--robot` (a configuration file or a bundled name; default icub_right_arm). Bad input of any
kind ends with exit code 2 and one line on stderr naming the problem. `--json FILE` writes the command's result
for machines ('-' for stdout); its fields are documented in tools/README.md.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from . import __version__, cli_export, cli_gaps, cli_spy
from .config import DEFAULT_ROBOT, bundled_configs, load_config
from .dataset import atomic_write
from .errors import EXIT_BAD_INPUT, InputError
from .regressors.stack import DEFAULT_MIN_SPEED


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit code 2, like every other bad input."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        raise SystemExit(EXIT_BAD_INPUT)


def write_json(result: dict[str, Any], target: str | None) -> None:
    """Write the result atomically (a reader sees the old file or the new one), or to stdout for '-'."""
    if not target:
        return
    text = json.dumps(result, indent=2, default=_json_default) + "\n"
    if target == "-":
        sys.stdout.write(text)
        return
    atomic_write(Path(target), lambda f: f.write(text.encode()))


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not np.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a number of 0 or more, got {text}")
    return value


def non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {value}")
    return value


seed = non_negative_int


def confidence(text: str) -> float:
    """α of a T² threshold: in [0.5, 1)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not 0.5 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must be in [0.5, 1), got {text}")
    return value


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(type(obj).__name__)


# ------------------------------------------------------------------------------------------------------------
# Commands


def cmd_import(args: argparse.Namespace) -> dict[str, Any]:
    from .dataset import load_data
    from .model import RobotModel

    config = load_config(args.robot)
    model = RobotModel(config)
    dataset = load_data(Path(args.data), config, joint_limits=model.joint_limits)
    dataset.meta.setdefault("robot", config.name)
    dataset.meta.setdefault("config_digest", config.digest)
    dataset.save(Path(args.out))
    channels = (
        [f"q.{j}" for j in dataset.joints]
        + [f"pwm.{m}" for m in dataset.pwm]
        + [f"current.{m}" for m in dataset.current]
        + [f"tau.{j}" for j in dataset.tau]
        + [f"ft.{s}" for s in dataset.ft]
    )
    print(
        f"imported {dataset.n_samples} samples ({dataset.duration:.3f} s) of {config.name} from {args.data} -> {args.out}\n"
        f"  channels: {', '.join(channels)}"
        + ("" if dataset.dq is not None else "\n  no dq/ddq columns: derivatives will be estimated from q when needed")
    )
    return {
        "robot": config.name,
        "samples": dataset.n_samples,
        "duration_s": dataset.duration,
        "channels": channels,
        "has_derivatives": dataset.dq is not None,
        "contact": dataset.contact is not None,
        "out": args.out,
    }


def cmd_structure(args: argparse.Namespace) -> dict[str, Any]:
    from .model import RobotModel
    from .regressors.base import data_base_parameters, exciting_signals
    from .regressors.stack import row_channels, rows_at_rest, signals_from_dataset

    config = load_config(args.robot)
    model = RobotModel(config)
    if args.data:
        from .dataset import load_data

        sig = signals_from_dataset(model, load_data(Path(args.data), config, joint_limits=model.joint_limits))
        source = args.data
    else:
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
    print(f"numerical rank {bp.rank} of {len(layout)}; condition number of the normalised base regressor {bp.condition_number:.4g}")
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
    }


def cmd_simulate(args: argparse.Namespace) -> dict[str, Any]:
    import time

    from .model import RobotModel
    from .simulation import SimulationSettings, parse_effect, simulate
    from .simulation.effects import catalog_text
    from .simulation.output import write_simulation

    if args.list_effects:
        print(catalog_text())
        from .simulation.effects import CATALOG

        return {"effects": {k: {"target": e.target, "stage": e.stage, "summary": e.summary, "defaults": e.defaults,
                                "units": e.units} for k, e in CATALOG.items()}}
    if not args.out:
        raise InputError("--out DIR is required (the directory to write the experiment to)")
    config = load_config(args.robot)
    bodies = tuple(b.name for b in RobotModel(config).bodies)
    effects = tuple(parse_effect(text, config, bodies) for text in args.effect)
    settings = SimulationSettings(
        kind=args.kind, duration=args.duration, seed=args.seed, robot_seed=args.robot_seed,
        noise=args.noise == "realistic", disturbance=args.disturbance == "realistic", effects=effects,
        rate_hz=args.rate,
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
    print(
        f"  PWM within ±1: {100 * realism['pwm_within_limits']:.3f} % of samples; joint limits respected: "
        f"{100 * realism['joint_limits_respected']:.2f} %; {realism['reaching_targets']} reaching targets"
    )
    return {
        "robot": config.name, "kind": args.kind, "duration_s": settings.seconds, "rate_hz": args.rate,
        "samples": truth["samples"], "seed": args.seed, "robot_seed": args.robot_seed, "noise": args.noise,
        "disturbance": truth["disturbance"], "effects": truth["effects"], "contacts": len(truth["contacts"]),
        "realism": realism, "wall_time_s": elapsed, "files": files,
    }


# ------------------------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="dynid",
        description="Identify a robot arm's inertia, F/T offsets, friction and motor gains in one regression "
        "(Traversaro et al., Humanoids 2013), and monitor contacts.",
        epilog=f"bundled robots: {', '.join(bundled_configs())}. Bad input exits with code 2.",
    )
    p.add_argument("--version", action="version", version=f"dynid {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    def robot_arg(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--robot", default=DEFAULT_ROBOT, metavar="CFG",
                        help=f"robot configuration: a YAML file or a bundled name (default {DEFAULT_ROBOT})")

    def min_speed_arg(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--min-speed", type=non_negative_float, default=DEFAULT_MIN_SPEED, metavar="RAD_S",
                        help="leave out motor rows whose joint or motor is slower than this: static friction, "
                        f"which the model lacks, holds them (default {DEFAULT_MIN_SPEED:g}; 0 keeps every row)")

    def json_arg(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--json", metavar="FILE", help="also write the result as JSON ('-' for stdout)")

    sp = sub.add_parser("import", help="CSV (or dataset) -> dataset file, validated against the robot configuration",
                        description="Read an experiment (CSV as in DESIGN.md §4, or a dataset file), check every "
                        "column against the robot configuration, and write the dataset file (.npz).")
    robot_arg(sp)
    sp.add_argument("--data", required=True, metavar="DATA", help="the experiment: a .csv or a .npz dataset")
    sp.add_argument("--out", required=True, metavar="DATASET", help="the dataset file to write (.npz, atomically)")
    json_arg(sp)
    sp.set_defaults(func=cmd_import)

    sp = sub.add_parser("structure", help="parameter layout, numerical rank and identifiable combinations",
                        description="Print the parameter vector's layout and the base-parameter structure: the "
                        "numerical rank of the weighted stacked A and the identifiable combinations, on random "
                        "exciting states (the structural rank) or on a recorded experiment (--data).")
    robot_arg(sp)
    sp.add_argument("--data", metavar="DATA", help="measure the rank on this experiment instead of random states")
    sp.add_argument("--samples", type=positive_int, default=2000, help="random states for the structural rank (default 2000)")
    sp.add_argument("--seed", type=int, default=0, help="seed of the random states (default 0)")
    sp.add_argument("--combinations", action="store_true", help="print every base-parameter combination")
    min_speed_arg(sp)
    json_arg(sp)
    sp.set_defaults(func=cmd_structure)

    sp = sub.add_parser("simulate", help="simulate an experiment of the arm, with known truth",
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
    sp.add_argument("--rate", type=positive_float, default=1000.0, metavar="HZ", help="sample rate (default 1000)")
    sp.add_argument("--out", metavar="DIR", help="the directory to write")
    json_arg(sp)
    sp.set_defaults(func=cmd_simulate)

    from .cli_identify import add_commands as identification_commands

    identification_commands(sub, robot_arg, json_arg, min_speed_arg, positive_int)
    cli_export.add_commands(sub, json_arg, positive_int)
    cli_gaps.add_commands(sub, robot_arg, json_arg)
    cli_spy.add_commands(sub, positive_int, positive_float)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    json_target = getattr(args, "json", None)
    # With --json -, stdout carries the JSON alone: the human report goes to stderr.
    human = contextlib.redirect_stdout(sys.stderr) if json_target == "-" else contextlib.nullcontext()
    try:
        with human:
            result = args.func(args)
        write_json(result, json_target)
    except InputError as e:
        sys.stderr.write(f"dynid {args.command}: error: {e}\n")
        return e.exit_code
    except (OSError, ET.ParseError) as e:
        # A file the readers did not anticipate (unreadable, not XML, a device): still one line, exit 2.
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        sys.stderr.write(f"dynid {args.command}: error: {where}{getattr(e, 'strerror', None) or e}\n")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        sys.stderr.write(f"dynid {args.command}: interrupted\n")
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
