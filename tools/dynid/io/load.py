"""Experiment data in any supported form → a `Dataset` checked against the robot configuration.

The one entry point of dynid.io (`load_data`): a dataset file, a `dynid simulate` directory, a yarpdatadumper
folder, a candump log or a CSV, told apart by content first, then by extension.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError
from .candump import read_candump
from .csv_format import check_columns, read_csv
from .headerless import looks_headerless, read_headerless
from .yarp import is_dumper_folder, read_yarp
from .dataset import _ZIP_MAGIC, SIMULATION_DATASET, Dataset, check_units

# `(1700000000.000000) can0 123#DEADBEEF` : the `candump -L` line format.
_CANDUMP_LINE = re.compile(rb"^\s*\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]+#")


def check_matches_config(dataset: Dataset, config: RobotConfig, require_all: bool = True, source: str = "") -> None:
    """Refuse a dataset made for another robot: other joints, or channels the configuration does not know."""
    where = f"{source}: " if source else ""
    if dataset.joints != config.joints:
        missing = [j for j in config.joints if j not in dataset.joints]
        extra = [j for j in dataset.joints if j not in config.joints]
        if missing or extra:
            diff = "; ".join(
                part
                for part in (
                    f"missing {', '.join(missing)}" if missing else "",
                    f"not in the configuration: {', '.join(extra)}" if extra else "",
                )
                if part
            )
            made_for = dataset.meta.get("robot")
            origin = f" (it was imported for '{made_for}')" if made_for and made_for != config.name else ""
            raise DataError(f"{where}the dataset's joints do not match the configuration {config.name}{origin}: {diff}")
        raise DataError(
            f"{where}the dataset's joints are in another order than in the configuration {config.name}: "
            f"{', '.join(dataset.joints)} (configuration: {', '.join(config.joints)})"
        )
    check_columns(dataset.column_names(), config, require_all=require_all, source=source)


def load_data(
    path: str | Path,
    config: RobotConfig,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    require_all: bool = True,
) -> Dataset:
    """Load experiment data in any supported form, checked against the robot configuration.

    A directory written by `dynid simulate` stands for its dataset file. The form is told by content first, then by extension: a zip archive (or ``.npz``) is a dataset file, a
    ``.log`` or a file whose first line is a ``candump -L`` frame is a CAN log, a ``.csv`` is a CSV
    (`dynid.io.csv_format.read_csv`). Anything else raises `DataError`.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"data file not found: {path}")
    if path.is_dir() and (path / SIMULATION_DATASET).is_file():  # the output directory of `dynid simulate`
        path = path / SIMULATION_DATASET
    elif is_dumper_folder(path):  # a YARP robot's log: one folder per port
        return read_yarp(path, config, joint_limits=joint_limits, require_all=require_all)
    if not path.is_file():
        raise DataError(f"data path is not a file: {path}")
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror or e}") from None
    first_line = head.split(b"\n", 1)[0]
    suffix = path.suffix.lower()
    if head.startswith(_ZIP_MAGIC) or suffix == ".npz":
        dataset = Dataset.load(path)
        check_matches_config(dataset, config, require_all=require_all, source=str(path))
        try:
            check_units(dataset, joint_limits)
        except DataError as e:
            raise DataError(f"{path}: {e}") from None
        return dataset
    if suffix == ".log" or _CANDUMP_LINE.match(first_line):
        dataset = read_candump(path, config)
        check_matches_config(dataset, config, require_all=require_all, source=str(path))
        return dataset
    if suffix in (".csv", ".txt") and config.columns and looks_headerless(head):
        return read_headerless(path, config, joint_limits=joint_limits, require_all=require_all)
    if suffix == ".csv":
        return read_csv(path, config, joint_limits=joint_limits, require_all=require_all)
    raise DataError(
        f"{path}: unknown data format: expected a .csv (docs/design.md §4), a candump log (.log) "
        "or a dynid dataset (.npz)"
    )


MIN_WINDOW_SAMPLES = 100  # a `--from/--to` window with fewer samples is refused: no filter or fit can use it


def apply_window(dataset: Dataset, start: float | None, stop: float | None, source: str = "") -> Dataset:
    """The samples with start <= t <= stop, in the data's own seconds (`--from S --to S`, docs/design.md §7)."""
    if start is None and stop is None:
        return dataset
    where = f"{source}: " if source else ""
    t = dataset.t
    span = f"the data run from {t[0]:.6g} s to {t[-1]:.6g} s"
    if start is not None and stop is not None and stop <= start:
        raise DataError(f"{where}--to {stop:g} s must come after --from {start:g} s")
    lo = 0 if start is None else int(np.searchsorted(t, start, side="left"))
    hi = t.size if stop is None else int(np.searchsorted(t, stop, side="right"))
    if hi - lo < MIN_WINDOW_SAMPLES:
        what = "no sample" if hi <= lo else f"only {hi - lo} samples"
        raise DataError(
            f"{where}the window --from {'start' if start is None else f'{start:g} s'} --to "
            f"{'end' if stop is None else f'{stop:g} s'} holds {what} (at least {MIN_WINDOW_SAMPLES} needed); {span}"
        )
    return dataset.slice(lo, hi)
