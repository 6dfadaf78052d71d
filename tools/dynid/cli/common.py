"""What every `dynid` command shares: the parser that turns a usage error into one line and exit 2, argument
types, the common options, and the JSON writer."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from ..config.robot_config import DEFAULT_ROBOT
from ..errors import EXIT_BAD_INPUT
from ..io.dataset import atomic_write
from ..robot.regressors.stack import DEFAULT_MIN_SPEED


class Parser(argparse.ArgumentParser):
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




def robot_arg(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--robot", default=DEFAULT_ROBOT, metavar="CFG",
                    help=f"robot configuration: a YAML file or a bundled name (default {DEFAULT_ROBOT})")


def min_speed_arg(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--min-speed", type=non_negative_float, default=DEFAULT_MIN_SPEED, metavar="RAD_S",
                    help="leave out motor rows whose joint or motor is slower than this: static friction, "
                    f"which the model lacks, holds them (default {DEFAULT_MIN_SPEED:g}; 0 keeps every row)")


def json_arg(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--json", metavar="FILE", help="also write the result as JSON ('-' for stdout)")
