"""What every `dynid` command shares: the parser that turns a usage error into one line and exit 2, argument
types, the common options, and the JSON writer."""

from __future__ import annotations

import argparse
import functools
import json
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
from threadpoolctl import threadpool_limits

from ..config.robot_config import DEFAULT_ROBOT, RobotConfig, load_config
from ..errors import EXIT_BAD_INPUT, InputError
from ..io.bad_rows import DEFAULT_POLICY, KINDS, join_labels
from ..io.bad_rows import POLICIES as BAD_ROW_POLICIES
from ..io.run_paths import expand
from ..outputs import atomic_write, label, probe
from ..robot.regressors.stack import DEFAULT_MIN_SPEED


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit code 2, like every other bad input; and a flag is named in
    full (argparse takes any unambiguous prefix: `fit --dat` read as --data, and a typo that is the prefix of one
    flag today is another's once a flag is added)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        raise SystemExit(EXIT_BAD_INPUT)


def plural(n: int, noun: str, nouns: str | None = None) -> str:
    """'1 episode', '2 episodes' (`nouns`: the plural where it is not noun + s)."""
    return f"{n} {noun if n == 1 else nouns or noun + 's'}"


def write_json(result: dict[str, Any], target: str | None) -> None:
    """Write the result atomically (a reader sees the old file or the new one), or to stdout for '-'."""
    if not target:
        return
    text = json.dumps(result, indent=2, default=_json_default) + "\n"
    if target == "-":
        sys.stdout.write(text)
        return
    atomic_write(Path(target), lambda f: f.write(text.encode()))


# Where a command writes: files (atomically, by dynid.outputs.atomic_write) and the directories.
OUTPUT_OPTIONS: tuple[str, ...] = ("out", "json", "figures")
DIRECTORY_OUTPUTS: frozenset[tuple[str, str]] = frozenset({("simulate", "out"), ("gaps", "figures"), ("fleet", "out")})
INPUT_OPTIONS: tuple[str, ...] = ("data", "model", "validation", "contact", "truth", "trajectory")
# Inputs of some commands that may name a bundled configuration or an output of another (export's --urdf): an input
# where they name a file that exists, and the command does not write them. (The configuration and URDF a command
# reaches through a model file are refused at the write: dynid.outputs.note_input.)
FILE_INPUT_OPTIONS: tuple[str, ...] = ("robot", "urdf", "episodes", "calibration", "steps_from")


def check_outputs(args: argparse.Namespace, extra: dict[str, str] | None = None) -> None:
    """Refuse, before any work, an output the command could not write or should not: a missing or unwritable
    directory (a read-only file system), an existing directory (or, for an output directory, an existing file), two
    outputs on one file, an output on one of the command's inputs. Without this a fit ran a minute before its --out
    was refused (or wrote its model and then failed on --json into a read-only folder), an import wrote its
    dataset and then failed on --json (exit 2 with the dataset left behind), and `import --data x.csv --out x.csv`
    replaced the CSV by the dataset. Writable means a file can be created there: one is (dynid.outputs.probe), as the
    output's temporary file will be; os.access says yes for root anywhere (/proc, a read-only mount), and `fit --json
    /proc/r.json` was found only after the fit. Each output is named for the messages of a write that fails later
    all the same (a full disk), which leaves none of the command's outputs behind (dynid.outputs.staged). `extra`
    names outputs of a command's own (option or description -> path), checked the same way."""
    command = getattr(args, "command", "")
    seen: dict[str, str] = {}
    inputs: dict[str, str] = {}
    for option in INPUT_OPTIONS + FILE_INPUT_OPTIONS:
        if option in (extra or {}):  # written by this command
            continue
        given = getattr(args, option, None)
        for value in given if isinstance(given, list) else [given]:
            if isinstance(value, (str, Path)) and str(value) and (option in INPUT_OPTIONS or os.path.isfile(value)):
                inputs.setdefault(os.path.realpath(value), option.replace("_", "-"))
    outputs = [(option, getattr(args, option, None)) for option in OUTPUT_OPTIONS] + list((extra or {}).items())
    for option, value in outputs:
        if not isinstance(value, str) or (option == "json" and value == "-"):
            continue
        path = Path(value)
        if (command, option) in DIRECTORY_OUTPUTS:
            if path.exists() and not path.is_dir():
                raise InputError(f"cannot write to '{value}' (--{option}): it exists and is not a directory")
            # the directory itself, or the nearest that exists, in which it (and its missing parents) will be made
            where = next((p for p in (path, *path.parents) if p.exists()), Path("."))
            if not where.is_dir():  # a file where a parent directory must be made
                raise InputError(f"cannot write to '{value}' (--{option}): {where} is not a directory")
            if not os.access(where, os.W_OK | os.X_OK):
                raise InputError(f"cannot write to '{value}' (--{option}): {where} is not writable")
            if why := probe(where, as_directory=where != path):
                raise InputError(f"cannot write to '{value}' (--{option}): nothing can be created in {where} ({why})")
        elif not path.name:
            raise InputError(f"cannot write '{value}' (--{option}): not a file name")
        elif not path.parent.is_dir():
            raise InputError(f"cannot write '{value}' (--{option}): the directory {path.parent} does not exist")
        elif path.exists() and not path.is_file():
            raise InputError(f"cannot write '{value}' (--{option}): it exists and is not a regular file")
        elif not os.access(path.parent, os.W_OK | os.X_OK):  # outputs are written beside, then renamed into place
            raise InputError(f"cannot write '{value}' (--{option}): the directory {path.parent} is not writable")
        elif why := probe(path.parent):
            raise InputError(f"cannot write '{value}' (--{option}): no file can be created in {path.parent} ({why})")
        label(value, f"--{option}")
        real = os.path.realpath(value)
        if real in inputs:
            raise InputError(f"cannot write '{value}' (--{option}): it is the input --{inputs[real]}")
        if real in seen:
            raise InputError(f"--{seen[real]} and --{option} name the same file '{value}'")
        seen[real] = option


def scheduler_address(text: str) -> str:
    """An argument type: a Dask scheduler's address, refused at once where none can have it (dynid.cluster)."""
    from ..cluster import scheduler_problem

    if why := scheduler_problem(text):
        raise argparse.ArgumentTypeError(f"'{text}' is {why}" if why.startswith("not") else f"'{text}': {why}")
    return text


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


def int_in(lo: int, hi: int) -> Callable[[str], int]:
    """An argument type: an integer from lo to hi (a value too large for what stores it is refused here, in one
    line, not deep inside as a traceback)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be {lo} to {hi}, got {value}")
        return value

    return parse


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




def robot_arg(sp: argparse.ArgumentParser, with_model: bool = False) -> None:
    """--robot and --urdf; `with_model`: the command also takes --model, whose robot --robot must then be (the
    default applies later, where there is no model: `model_robot`)."""
    sp.add_argument("--robot", default=None if with_model else DEFAULT_ROBOT, metavar="CFG",
                    help=f"robot configuration: a YAML file or a bundled name (default {DEFAULT_ROBOT}"
                    + ("; with --model, the model's" if with_model else "") + ")")
    sp.add_argument("--urdf", metavar="FILE", help="the robot's URDF, replacing the configuration's (needed by a "
                    "bundled configuration whose URDF you supply, e.g. ur10e; or set DYNID_URDF_PATH)")


def min_speed_arg(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--min-speed", type=non_negative_float, default=DEFAULT_MIN_SPEED, metavar="RAD_S",
                    help="leave out motor rows whose joint or motor is slower than this: static friction, "
                    f"which the model lacks, holds them (default {DEFAULT_MIN_SPEED:g}; 0 keeps every row)")


def json_arg(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--json", metavar="FILE", help="also write the result as JSON ('-' for stdout)")


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def window_args(sp: argparse.ArgumentParser) -> None:
    """--from S --to S: a time window of the data, in its own seconds, for every --data without a window of its own
    (--data RUN@FROM:TO); --bad-rows: what to do with a log's bad rows (docs/design.md §7)."""
    sp.add_argument("--from", dest="t_from", type=finite_float, metavar="S",
                    help="use the data from this time on (the data's own seconds, as in its t column); applies to "
                    "every --data that gives no window of its own: --data RUN@FROM:TO (either may be left out, e.g. "
                    "RUN@12.5: or RUN@:80) cuts that run alone")
    sp.add_argument("--to", dest="t_to", type=finite_float, metavar="S", help="use the data up to this time (s)")
    sp.add_argument("--bad-rows", choices=BAD_ROW_POLICIES, default=DEFAULT_POLICY,
                    help="a log's bad rows (cut short, wrong field count, not a number, non-finite, beyond ±1e6, "
                    "time negative or not increasing; a candump line that is no frame; a YARP port's bad line): "
                    "refuse the run naming them (default), or skip them and report how many were dropped (in the "
                    "output, --json and the model file)")


Window = tuple[float | None, float | None]
# --data RUN@FROM:TO: a window of one run; FROM or TO may be empty (from the start, to the end).
_RUN_WINDOW = re.compile(r"^(?P<path>.+)@(?P<start>[^:@]*):(?P<stop>[^:@]*)$")


def split_data_window(text: str) -> tuple[str, Window | None]:
    """`--data RUN@FROM:TO` as (RUN, (FROM, TO)); a path that exists as given, '@' and all, is a path."""
    match = _RUN_WINDOW.match(text)
    if match is None or os.path.exists(text):
        return text, None
    bounds: list[float | None] = []
    for part in (match["start"], match["stop"]):
        if not part.strip():
            bounds.append(None)
            continue
        try:
            bounds.append(finite_float(part))
        except argparse.ArgumentTypeError as e:
            raise InputError(f"--data {text}: the window @FROM:TO is in seconds; {part!r}: {e}") from None
    if bounds == [None, None]:
        raise InputError(f"--data {text}: the window @FROM:TO names neither FROM nor TO (leave out '@:' for the "
                         "whole run)")
    return match["path"], (bounds[0], bounds[1])


def split_data_windows(args: argparse.Namespace) -> None:
    """Turn every `--data RUN@FROM:TO` of a command that takes windows into its path, the windows kept aside in
    `args.data_windows` (one per --data, None where the run gives none). Runs once, before any work."""
    given = getattr(args, "data", None)
    if not hasattr(args, "t_from") or not given:
        return
    split = [split_data_window(text) for text in (given if isinstance(given, list) else [given])]
    args.data = [path for path, _ in split] if isinstance(given, list) else split[0][0]
    args.data_windows = [own for _, own in split]


def window(args: argparse.Namespace, run: int = 0) -> Window:
    """The window of the `run`-th --data: its own (RUN@FROM:TO), else --from/--to."""
    own = getattr(args, "data_windows", [])
    if run < len(own) and own[run] is not None:
        return own[run]
    return (getattr(args, "t_from", None), getattr(args, "t_to", None))


def expand_data(args: argparse.Namespace, config: RobotConfig | None = None) -> tuple[list[str], list[Window]]:
    """Every --data expanded (a glob, a folder, @LIST: dynid.io.run_paths) with its window: a spec's own
    (RUN@FROM:TO) for each run it names, else --from/--to. A run named twice with the same window is refused (it
    would count twice); two windows of one run are two runs. With `config`, a folder of files its `files:` field
    describes is one run (dynid.io.file_set)."""
    from ..io.file_set import holds_file_set

    run_folder = None if config is None or not config.files else (lambda p: holds_file_set(p, config))
    paths: list[str] = []
    windows: list[Window] = []
    seen: dict[tuple[str, Window], str] = {}
    for i, spec in enumerate(args.data):
        for p in expand(spec, run_folder=run_folder):
            key = (os.path.realpath(p), window(args, i))
            if key in seen:
                raise InputError(f"--data: the run {p} is named twice" + (" with the same window" if any(key[1]) else ""))
            for (other, w), given in seen.items():
                if other == key[0] and _overlap(w, key[1]):
                    raise InputError(f"--data: {given} and {run_spec(p, key[1])} are windows of one run that overlap: the "
                                     "samples they share would count twice (give windows that do not overlap)")
            seen[key] = run_spec(p, key[1])
            paths.append(str(p))
            windows.append(key[1])
    return paths, windows


def run_spec(path: str | Path, w: Window) -> str:
    """RUN@FROM:TO as a user writes it (RUN alone for the whole run)."""
    ends = ["" if x is None else f"{x:g}" for x in w]
    return f"{path}@{ends[0]}:{ends[1]}" if any(x is not None for x in w) else str(path)


def _overlap(a: Window, b: Window) -> bool:
    """Whether two windows (FROM, TO; None open) of one run share time."""
    lo = max(-np.inf if a[0] is None else a[0], -np.inf if b[0] is None else b[0])
    hi = min(np.inf if a[1] is None else a[1], np.inf if b[1] is None else b[1])
    return lo < hi


def folder_of_runs_error(args: argparse.Namespace, config: RobotConfig, error: Exception) -> str:
    """The error a run ended in, led by why its --data folder was read as a folder of runs rather than as one run of
    the configuration's `files:` where that is so: the user most likely meant the robot's own logger folder (or gave
    another robot's), and the first file's failure is only what followed."""
    from ..io.file_set import matched_files

    if config.files:
        for spec in args.data:
            path = Path(spec)
            if (path.is_dir() and not any(p.is_dir() for p in path.iterdir())  # a parent of run folders is one
                    and isinstance(why := matched_files(path, config.files), str)):
                return f"{spec}: {why} (read instead as a folder of runs, one a file, it failed: {error})"
    return str(error)


def bad_rows(args: argparse.Namespace) -> str:
    return getattr(args, "bad_rows", DEFAULT_POLICY)


def skipped_rows(label: str, meta: dict[str, Any]) -> dict[str, Any] | None:
    """Print what `--bad-rows skip` dropped from a run, and return it for --json (None when nothing was)."""
    dropped = meta.get("bad_rows")
    if not dropped:
        return None
    kinds = ", ".join(f"{n} {KINDS[k]}" for k, n in dropped["kinds"].items())
    print(f"  {label}: skipped {plural(dropped['count'], 'bad row')} of {dropped['rows_read']} ({kinds}; first at "
          f"{join_labels(dropped['first'])})")
    return dropped


def payload(text: str) -> dict[str, Any] | None:
    """--payload MASS[@x,y,z]: kg, and the centre of mass in the configuration's payload_frame, m; 0 = none."""
    mass_text, at, com_text = text.partition("@")
    try:
        mass = float(mass_text)
        com = [float(x) for x in com_text.split(",")] if at else None
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not MASS or MASS@x,y,z (kg, m)") from None
    if not np.isfinite(mass) or mass < 0 or (com is not None and (len(com) != 3 or not np.all(np.isfinite(com)))):
        raise argparse.ArgumentTypeError(f"'{text}' is not MASS or MASS@x,y,z: a mass of 0 kg or more, three finite "
                                         "coordinates")
    return None if mass == 0 else {"mass": mass, "com": com}


def payload_arg(sp: argparse.ArgumentParser, repeatable: bool) -> None:
    sp.add_argument("--payload", type=payload, action="append" if repeatable else "store", metavar="MASS[@x,y,z]",
                    help="a known payload the run carries: kg, and where known its centre of mass (m, in the "
                    "configuration's payload_frame; default its origin); 0 = none"
                    + ("; one per --data, in the same order" if repeatable else ""))


def payloads(args: argparse.Namespace, n_data: int) -> list[dict[str, Any] | None]:
    """The payload of every --data (none when --payload is not given)."""
    given = getattr(args, "payload", None)
    if given is None:
        return [None] * n_data
    if not isinstance(given, list):
        return [given]
    if len(given) != n_data:
        expanded = len(getattr(args, "data", None) or ()) != n_data  # a glob, folder or @LIST named several runs
        runs = f"{n_data} runs (--data expanded)" if expanded else f"{n_data} --data"
        raise InputError(f"--payload is given {len(given)} times for {runs}: give one per run, in the same order (0 "
                         "for a run without payload)"
                         + ("; name the runs one --data each to pair them" if expanded else ""))
    return given


def one_blas_thread(command):  # noqa: ANN001, ANN201 - a command function, wrapped
    """Run a command with one BLAS thread: its products are long and thin ((N, 3) @ (3, 3) per run), where OpenBLAS's
    threads cost more than they give (0.1 s a product on the shared 2-core machine; docs/benchmarks.md). Every command
    that reports the same numbers (validate, detect, report) runs alike, so they agree to the last bit."""
    @functools.wraps(command)
    def run(args: argparse.Namespace) -> dict[str, Any]:
        with threadpool_limits(limits=1, user_api="blas"):
            return command(args)
    return run


def model_robot(args: argparse.Namespace) -> RobotConfig | None:
    """With --model, a --robot of another robot is a mistake, not ignored; the same robot's configuration edited since
    the fit (another file digest) is returned, for what does not depend on the fit (its bus), else None. Without
    --model, --robot's default applies."""
    if args.model and args.robot is not None:
        from ..identify.model_file import load_model

        given = load_config(args.robot, args.urdf, need_urdf=False)
        own = load_model(args.model).config
        if given.name != own.name:
            raise InputError(f"--robot {args.robot} is not {args.model}'s robot ({own.name}): leave --robot out with "
                             "--model")
        return given if given.digest != own.digest else None
    args.robot = args.robot or DEFAULT_ROBOT
    return None
