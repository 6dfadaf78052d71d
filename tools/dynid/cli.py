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

from . import __version__
from .config import DEFAULT_ROBOT, bundled_configs, load_config
from .dataset import atomic_write
from .errors import EXIT_BAD_INPUT, InputError


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
    from .regressors.stack import row_channels, signals_from_dataset

    config = load_config(args.robot)
    model = RobotModel(config)
    if args.data:
        from .dataset import load_data

        sig = signals_from_dataset(model, load_data(Path(args.data), config, joint_limits=model.joint_limits))
        source = args.data
    else:
        sig = exciting_signals(model, args.samples, args.seed)
        source = f"{args.samples} random states within the joint limits (seed {args.seed})"
    bp = data_base_parameters(model, sig)
    layout = model.layout
    print(f"robot {config.name}: {model.n_joints} joints, {len(model.bodies)} bodies, {len(layout)} parameters")
    print(f"  bodies: {', '.join(b.name for b in model.bodies)}")
    for kind in ("ft_offset", "joint_friction", "motor_friction", "motor_gain"):
        owners = layout.owners(kind)  # type: ignore[arg-type]
        if owners:
            print(f"  {kind.replace('_', ' ')}: {', '.join(owners)}")
    print(f"  rows per sample: {', '.join(c.name for c in row_channels(model))}")
    print(f"excitation: {source}")
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
    json_arg(sp)
    sp.set_defaults(func=cmd_structure)
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
