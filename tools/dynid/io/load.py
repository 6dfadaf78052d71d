"""Experiment data in any supported form → a `Dataset` checked against the robot configuration.

The one entry point of dynid.io (`load_data`): a dataset file, a `dynid simulate` directory, a yarpdatadumper
folder, a candump log or a CSV, told apart by content first, then by extension.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError, DataNote, PathError
from .candump import read_candump
from .bad_rows import DEFAULT_POLICY, MAX_ABS_VALUE, POLICIES
from .csv_format import check_columns, read_csv
from .file_set import read_file_set
from .headerless import looks_headerless, read_headerless
from .rosbag import is_bag, looks_like_bag_file, read_bag
from .wrenches import check_wrenches
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
    bad_rows: str = DEFAULT_POLICY,
) -> Dataset:
    """Load experiment data in any supported form, checked against the robot configuration.

    A directory written by `dynid simulate` stands for its dataset file; a folder with metadata.yaml, or a ``.mcap``
    or ``.db3`` file, is a ROS 2 bag (dynid.io.rosbag); a folder of YARP ports a yarpdatadumper log; any other folder
    a logger's folder of files, where the configuration has a `files:` field (dynid.io.file_set). Otherwise the
    form is told by content first, then by extension: a zip archive (or ``.npz``) is a dataset file, a
    ``.log`` or a file whose first line is a ``candump -L`` frame is a CAN log, a ``.csv`` is a CSV
    (`dynid.io.csv_format.read_csv`). Anything else raises `DataError`.
    Every form then passes `check_plausible` (enough samples, a sample period in seconds, recorded velocities that
    are q's rate, F/T wrenches in N and N·m). A table's bad rows
    (dynid.io.bad_rows) are refused, or dropped and counted with ``bad_rows="skip"``.
    """
    path = Path(path)
    if bad_rows not in POLICIES:
        raise DataError(f"--bad-rows must be one of {', '.join(POLICIES)}, got {bad_rows!r}")
    dataset = _load(path, config, joint_limits, require_all, bad_rows)
    headerless = dataset.meta.get("source_format") == "headerless csv" and dataset.meta.get("source") == str(path)
    check_plausible(dataset, str(path), headerless=headerless, config=config)
    return dataset


def _load(
    path: Path, config: RobotConfig, joint_limits: Mapping[str, tuple[float, float]] | None, require_all: bool,
    bad_rows: str,
) -> Dataset:
    if not path.exists():
        raise PathError(f"data file not found: {path}")
    if path.is_dir() and (path / SIMULATION_DATASET).is_file():  # the output directory of `dynid simulate`
        path = path / SIMULATION_DATASET
    elif is_bag(path):  # a ROS 2 bag: a rosbag2 folder, or one .mcap or .db3 file
        return read_bag(path, config, joint_limits=joint_limits, require_all=require_all, bad_rows=bad_rows)
    elif is_dumper_folder(path):  # a YARP robot's log: one folder per port
        return read_yarp(path, config, joint_limits=joint_limits, require_all=require_all, bad_rows=bad_rows)
    elif path.is_dir() and config.files:  # a logger's folder of files, one per signal group
        return read_file_set(path, config, joint_limits=joint_limits, require_all=require_all, bad_rows=bad_rows)
    if path.is_dir():  # a bag's storage file without its metadata.yaml: the file itself is a bag
        storage = sorted(p.name for p in path.iterdir() if p.suffix.lower() in (".mcap", ".db3") and p.is_file())
        if storage:
            raise DataError(f"{path}: holds the ROS 2 bag storage file {storage[0]} but no metadata.yaml: give "
                            f"{path / storage[0]} itself, or the bag's folder with its metadata.yaml")
    if not path.is_file():
        raise DataError(f"data path is not a file: {path} (a folder is a run when it is a `dynid simulate` directory, a "
                        "ROS 2 bag, a YARP dumper folder, or holds the files the configuration's 'files' field names)")
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror or e}") from None
    first_line = head.split(b"\n", 1)[0]
    suffix = path.suffix.lower()
    if looks_like_bag_file(head):
        raise DataError(f"{path}: an MCAP or SQLite file: a ROS 2 bag's storage file is named .mcap or .db3 (or give "
                        "the bag's folder, with its metadata.yaml)")
    if head.startswith(_ZIP_MAGIC) or suffix == ".npz":
        dataset = Dataset.load(path)
        check_matches_config(dataset, config, require_all=require_all, source=str(path))
        try:
            check_units(dataset, joint_limits)
        except DataError as e:
            raise DataError(f"{path}: {e}") from None
        return dataset
    if suffix == ".log" or _CANDUMP_LINE.match(first_line):
        dataset = read_candump(path, config, bad_rows=bad_rows)
        check_matches_config(dataset, config, require_all=require_all, source=str(path))
        return dataset
    if suffix in (".csv", ".txt") and config.columns and looks_headerless(head):
        return read_headerless(path, config, joint_limits=joint_limits, require_all=require_all, bad_rows=bad_rows)
    if suffix == ".csv" and not config.columns and looks_headerless(head):
        # A log without a header for a configuration that describes none: as likely another robot's as a header lost
        width = len(first_line.split(b","))
        reads = ("its runs as folders of files (its 'files' field)" if config.files else
                 "CSVs with a header line (t, q.<joint>, ...)")
        raise DataError(f"{path}: no header: the first line is data ({width} values), and the configuration "
                        f"{config.name} reads {reads}, with no 'columns' field for a headerless log: another robot's "
                        "data (give its --robot), or describe these columns in the configuration's 'columns' field "
                        "(docs/formats.md)")
    if suffix == ".csv":
        return read_csv(path, config, joint_limits=joint_limits, require_all=require_all, bad_rows=bad_rows)
    raise DataError(
        f"{path}: unknown data format: expected a .csv (docs/design.md §4), a candump log (.log), a ROS 2 bag "
        "(a folder with metadata.yaml, .mcap or .db3), a YARP dumper folder, a folder of files the configuration's "
        "'files' field describes (docs/formats.md#a-folder-of-files) or a dynid dataset (.npz)"
    )


MIN_SAMPLES = 100  # fewer samples than this, in a file or a `--from/--to` window: no filter or fit can use them
MIN_WINDOW_SAMPLES = MIN_SAMPLES
# The sample period a dataset may have: the monitor's coefficient loader accepts 10 µs to 1 s (rt_monitor's
# coefficients.cpp); one second itself is refused here, as it is t in milliseconds of a 1 kHz log.
MIN_PERIOD_S, MAX_PERIOD_S = 1e-5, 1.0
# MAX_ABS_VALUE (dynid.io.bad_rows): no arm's sensor reads a million N, Nm, A, rad/s or rad/s²: a larger value is a
# wrong unit or a corrupt cell, and near 1e154 its square overflows (a 1e308 N cell made the fit fail with a
# traceback and validate print inf). A table's rows beyond it are bad rows; other forms are refused here.
_TIME_UNITS = (("ms", "milliseconds", 1e-3), ("us", "microseconds", 1e-6), ("ns", "nanoseconds", 1e-9))


def check_plausible(dataset: Dataset, source: str = "", headerless: bool = False, n_samples: int | None = None,
                    config: RobotConfig | None = None) -> None:
    """Refuse data no command can use, before any command writes or fits anything (issue 22's sweep): fewer than
    `MIN_SAMPLES` samples (a one-row CSV was imported as a dataset of 0 s), a measured value beyond
    `MAX_ABS_VALUE`, or a median step of `t` outside `MIN_PERIOD_S` to below `MAX_PERIOD_S` (a time column in
    milliseconds was imported as 3000 s of data); then recorded velocities that are not q's rate
    (`check_velocities`) and, with the robot's `config`, F/T wrenches in another unit (dynid.io.wrenches). A
    `headerless` log is told where its unit is declared. `n_samples`: the run's count when `dataset` is its first
    rows only (a streamed run, dynid.io.stream)."""
    where = f"{source}: " if source else ""
    n = dataset.n_samples if n_samples is None else n_samples
    if n < MIN_SAMPLES:
        raise DataError(
            f"{where}only {n} sample{'s' * (n != 1)}: a run needs at least {MIN_SAMPLES} (the derivative filters, "
            "the fit and the monitor's calibration all need a stretch of samples)"
        )
    try:
        check_values(dataset)
    except DataError as e:
        raise DataError(f"{where}{e}") from None
    period = float(np.median(np.diff(dataset.t)))
    if MIN_PERIOD_S <= period < MAX_PERIOD_S:
        check_velocities(dataset, where, headerless)
        if config is not None:
            check_wrenches(dataset, config, where, headerless)
        return
    # The unit that makes it a period of 10 µs to 100 ms, if one does.
    unit = next(((short, long) for short, long, scale in _TIME_UNITS if MIN_PERIOD_S <= period * scale < 0.1), None)
    hint = f"is t in {unit[1]}? the t column must be in seconds" if unit else "is t in seconds?"
    declare = (" (a headerless log declares its unit in the configuration's 'columns:' field, e.g. \"t "
               f"{unit[0] if unit else 'ms'}\")" if headerless else "")
    raise DataError(
        f"{where}t steps by {period:.6g} s between samples (the median step), outside the sample periods a run may "
        f"have ({MIN_PERIOD_S * 1e6:g} µs to under {MAX_PERIOD_S:g} s): {hint}{declare}"
    )


# A recorded joint velocity against the recorded positions: over stretches of VELOCITY_CHECK_S, what the velocity
# integrates to (trapezoids on the stamps) against how far q moved, on a joint that moves (RMS speed at least
# MOVING_SPEED, rad/s or m/s). Integrals over tens of samples are not thrown by stamps that jitter about the instants
# the values were taken at, as a sample-to-sample derivative of q is (a synthetic log jittered by a third of its
# period correlated 0.46 that way). On the real runs (Panda, UR10e) the least-squares scale of one on the other is
# 0.999–1.000 and what it leaves unexplained (‖a − k·b‖/‖a‖, not centred, so a joint at constant speed passes) at most
# 1.6 %; in deg/s the scale is 57.3; a column of another signal (the walkthrough's UR10e log a column short, which
# shifts every column after it) leaves 96–98 % unexplained. A stretch that moves more than π is a wrapped angle.
VELOCITY_SCALE = (0.5, 2.0)
MAX_UNEXPLAINED = 0.5
MOVING_SPEED = 0.05
VELOCITY_CHECK_S = 0.05
STILL_Q_TRAVEL = 4 * MOVING_SPEED  # a log's velocity that travels this fast (RMS) is judged even where q stays still


UNIT_FACTORS = (180 / np.pi, 1000.0)  # degrees against radians, milli- against the unit


def _unit_factor(scale: float) -> bool:
    """`scale` is a unit's factor or its inverse, to 10 %."""
    return any(abs(abs(scale) / f - 1) <= 0.1 or abs(abs(scale) * f - 1) <= 0.1 for f in UNIT_FACTORS)


def _stretches(step: float, size: int) -> np.ndarray:
    """The first sample of each VELOCITY_CHECK_S stretch (at least 5 samples) of `size` samples `step` s apart."""
    return np.arange(0, size, max(5, int(round(VELOCITY_CHECK_S / step))))


class Agreement(NamedTuple):
    """A velocity column against its joint's positions, over stretches of `VELOCITY_CHECK_S`."""

    scale: float  # least-squares factor of what v integrates to on how far q moved: 1 for q's rate; inf: q still
    unexplained: float  # ‖a − scale·b‖ / ‖a‖: 0 for q's rate up to the factor, near 1 for another signal
    zero: bool  # v is zero in every stretch


def velocity_agreement(t: np.ndarray, q: np.ndarray, v: np.ndarray, rest: str = "q") -> list[Agreement | None]:
    """Per joint, how the velocities `v` follow the positions `q` (both (N, J)): None where not judged, a run of
    under 20 stretches or a joint at rest: at rest by q alone for a log (``rest="q"``: a still joint's velocity is
    noise on both sides), or by both q and v for a computed reference (``rest="both"``: it has no noise, so a still q
    under a moving v is judged too)."""
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if not step > 0:
        return [None] * q.shape[1]  # fewer than two samples, or no time between them: nothing to judge
    edges = _stretches(step, t.size)
    if edges.size < 20:
        return [None] * q.shape[1]  # too short a run to judge
    integral = np.concatenate([np.zeros((1, v.shape[1])), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], 0)])
    moved, travelled, span = np.diff(q[edges], axis=0), np.diff(integral[edges], axis=0), np.diff(t[edges])
    found: list[Agreement | None] = []
    for j in range(q.shape[1]):
        a, b = travelled[:, j], moved[:, j]
        ok = np.isfinite(a) & np.isfinite(b) & (np.abs(b) < np.pi)  # more than π in 50 ms: a wrapped angle, no motion
        a, b, dt = a[ok], b[ok], span[ok]
        q_speed = float(np.sqrt(np.mean((b / dt) ** 2))) if b.size else 0.0
        v_speed = float(np.sqrt(np.mean((a / dt) ** 2))) if a.size else 0.0
        q_moves, v_moves = q_speed >= MOVING_SPEED, v_speed >= MOVING_SPEED
        # A log's still q under a moving v is judged too. Integrated over a stretch, noise does not travel at
        # STILL_Q_TRAVEL, but a q read in the wrong unit (rad declared deg: 57 times too small) does; and below it, a q
        # whose small steps follow v's travel at a unit's factor (what a still joint's noise, or a slow one-way motion
        # under a velocity's offset, does not do) is such a q of a slow run (a walkthrough's TIAGo at 0.16 rad/s RMS,
        # its rad declared deg: taken, the model garbage)
        judged = q_moves or v_moves
        if b.size < 20 or not judged:
            found.append(None)
        elif not np.any(a):
            found.append(Agreement(0.0, 1.0, True))  # judged with v still: q moves
        elif not q_moves:  # a log's q read too small shows its factor; a reference's still q is named as still
            scale = float(a @ b / (b @ b)) if rest == "q" and np.any(b) else float("inf")
            left = float(np.linalg.norm(a - scale * b) / np.linalg.norm(a)) if np.isfinite(scale) else 1.0
            follows = left <= MAX_UNEXPLAINED and _unit_factor(scale)
            found.append(Agreement(scale, left, False) if rest == "both" or v_speed >= STILL_Q_TRAVEL or follows
                         else None)
        else:
            scale = float(a @ b / (b @ b))
            found.append(Agreement(scale, float(np.linalg.norm(a - scale * b) / np.linalg.norm(a)), False))
    return found


def check_velocities(dataset: Dataset, where: str = "", headerless: bool = False) -> None:
    """Refuse a recorded q̇ (the `velocity.<joint>` extra columns the momentum detector takes, else recorded `dq`)
    that is not the rate of q: another unit, or another signal's column."""
    columns = [dataset.extra.get(f"velocity.{j}") for j in dataset.joints]
    if all(c is not None for c in columns):
        names, v = [f"velocity.{j}" for j in dataset.joints], np.column_stack(columns)
    elif dataset.dq is not None and dataset.meta.get("derivatives", {}).get("dq", "recorded") == "recorded":
        names, v = [f"dq.{j}" for j in dataset.joints], np.asarray(dataset.dq, float)
    else:
        return
    declare = " (a headerless log declares its units in the configuration's 'columns:' field)" if headerless else ""
    for name, joint, fit in zip(names, dataset.joints, velocity_agreement(dataset.t, dataset.q, v)):
        if fit is None:
            continue
        if fit.zero:
            raise DataError(f"{where}{name} is zero throughout while q.{joint} moves: a controller that records no "
                            "velocity there? (leave the column out and dynid estimates q̇ from q)")
        if np.isinf(fit.scale):
            raise DataError(f"{where}{name} moves while q.{joint} stays still: is q.{joint} in the unit the "
                            f"configuration declares, and is {name} its velocity?{declare}")
        if fit.unexplained > MAX_UNEXPLAINED:
            raise DataError(f"{where}{name} does not follow the motion of q.{joint} (its travel, scaled, leaves "
                            f"{100 * fit.unexplained:.0f} % unexplained while the joint moves): another signal's "
                            "column? (a log a column short shifts every column after it)")
        if not VELOCITY_SCALE[0] <= fit.scale <= VELOCITY_SCALE[1]:
            raise DataError(f"{where}{name} is {fit.scale:.3g} times the rate of q.{joint}{_unit_hint(fit.scale)}: "
                            "recorded velocities must be in the positions' unit per second, each in its joint's "
                            f"column{declare}")


INPUT_CHECK_S = 60.0  # the stretch of a run whose input levels are judged (enough to see a unit; bounded memory)


def quiet_inputs(config: RobotConfig, dataset: Dataset) -> list[str]:
    """A note for each motor input (PWM, current) or joint torque that stays within the configuration's noise for it
    while a joint it drives moves (RMS speed over 50 ms stretches at least MOVING_SPEED): an actuator that moves its
    joint reads well above its noise, so such a column is most likely in another unit than declared (mA for A reads
    1000 times too small) or not the signal named. Judged on the run's first INPUT_CHECK_S seconds."""
    t, q = dataset.t, dataset.q
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if not step > 0:
        return []
    head = int(np.searchsorted(t, t[0] + INPUT_CHECK_S))
    edges = _stretches(step, max(head, 1))
    if edges.size < 20:
        return []
    speed = np.sqrt(np.nanmean((np.diff(q[edges], axis=0) / np.diff(t[edges])[:, None]) ** 2, axis=0))
    moving = dict(zip(dataset.joints, speed >= MOVING_SPEED))
    notes = []
    for group in config.actuation:
        if not any(moving.get(j, False) for j in group.joints):
            continue
        kind = "torque" if group.input == "torque" else group.input
        values = dataset.tau if kind == "torque" else getattr(dataset, kind)
        for name in group.joints if kind == "torque" else group.motors:
            column = values.get(name)
            if column is None:
                continue
            level, noise = float(np.sqrt(np.nanmean(column[:head] ** 2))), config.noise.of(kind, name)
            if level < noise:
                label = f"{'tau' if kind == 'torque' else kind}.{name}"
                notes.append(f"{label} stays within its noise while its joint moves (RMS {level:.3g} against the "
                             f"configuration's noise {noise:.3g} over the first {INPUT_CHECK_S:g} s): is it in the unit "
                             "the configuration declares (mA for A reads it 1000 times too small), and the signal named?")
    return notes


def _unit_hint(scale: float) -> str:
    """What a velocity `scale` times the rate of its q suggests: 57.3 (or its inverse) is degrees against radians,
    on either column."""
    if 45 < scale < 70:
        return " (the velocity in deg/s, or q in rad declared deg? the two columns must agree in unit)"
    if 1 / 70 < scale < 1 / 45:
        return " (q in deg declared rad, or the velocity in rad/s declared deg/s? the two columns must agree in unit)"
    return ""


# A reference trajectory (`dynid simulate --trajectory`) is computed, not measured: its dq is its q's derivative to the
# sampling's rounding (`dynid excite`'s: scale 0.9999, 0.01 % unexplained), and the plant's cubic Hermite interpolation
# takes q and dq at their word between samples. dq scaled 1.3 leaves the same 0.01 % but is 30 % off; a dq 0.1 s
# late leaves 31–38 % unexplained. A finite difference of q one sample behind (5 ms at 100 Hz) leaves about 3 %.
REFERENCE_SCALE = (0.9, 1.1)
REFERENCE_UNEXPLAINED = 0.1


def check_reference_velocities(dataset: Dataset, where: str = "") -> None:
    """Refuse a reference trajectory whose dq is not the rate of its q (`REFERENCE_SCALE`, `REFERENCE_UNEXPLAINED`):
    another trajectory's, another unit, a column shifted, a still joint said to move."""
    if dataset.dq is None:
        return
    rule = (f"a trajectory's dq must be its q's rate (scaled {REFERENCE_SCALE[0]:g}–{REFERENCE_SCALE[1]:g}, at most "
            f"{100 * REFERENCE_UNEXPLAINED:.0f} % unexplained over {1e3 * VELOCITY_CHECK_S:.0f} ms stretches; "
            "dynid excite writes both)")
    for joint, fit in zip(dataset.joints, velocity_agreement(dataset.t, dataset.q, dataset.dq, rest="both")):
        if fit is None:
            continue
        if fit.zero or np.isinf(fit.scale):
            still, moving = ("dq", "q") if fit.zero else ("q", "dq")
            raise DataError(f"{where}{still}.{joint} stays still while {moving}.{joint} moves: {rule}")
        if fit.unexplained > REFERENCE_UNEXPLAINED or not REFERENCE_SCALE[0] <= fit.scale <= REFERENCE_SCALE[1]:
            raise DataError(f"{where}dq.{joint} is not the rate of q.{joint}: it integrates to {fit.scale:.3g} times "
                            f"how far q moves, {100 * fit.unexplained:.0f} % unexplained{_unit_hint(fit.scale)}; {rule}")


def check_values(dataset: Dataset, row_offset: int = 0) -> None:
    """Refuse a measured value beyond `MAX_ABS_VALUE` (rows named from `row_offset`, for a window of a run)."""
    for name, values in dataset.columns():
        if name == "t" or name == "contact" or name.startswith(("q.", "pwm.")) or name in dataset.extra:
            continue  # time, labels, positions and duties have checks of their own; extra columns are not used
        big = np.flatnonzero(np.abs(values) > MAX_ABS_VALUE)
        if big.size:
            i = int(big[0])
            raise DataError(
                f"{name} is {values[i]:g} at row {row_offset + i + 1}: beyond ±{MAX_ABS_VALUE:g}, which no sensor of "
                "an arm reads (N, Nm, A, rad/s, rad/s²): a wrong unit or a corrupt value"
            )


def apply_window(dataset: Dataset, start: float | None, stop: float | None, source: str = "") -> Dataset:
    """The samples with start <= t <= stop, in the data's own seconds (`--from S --to S`, docs/design.md §7)."""
    if start is None and stop is None:
        return dataset
    where = f"{source}: " if source else ""
    t = dataset.t
    span = f"the data run from {t[0]:.6g} s to {t[-1]:.6g} s"
    if start is not None and stop is not None and stop <= start:
        raise DataError(f"{where}the window's end, {stop:g} s, must come after its start, {start:g} s (--to after "
                        "--from, or RUN@FROM:TO)")
    lo = 0 if start is None else int(np.searchsorted(t, start, side="left"))
    hi = t.size if stop is None else int(np.searchsorted(t, stop, side="right"))
    if hi - lo < MIN_WINDOW_SAMPLES:
        what = "no sample" if hi <= lo else f"only {hi - lo} samples"
        raise DataError(
            f"{where}the window from {'the start' if start is None else f'{start:g} s'} to "
            f"{'the end' if stop is None else f'{stop:g} s'} holds {what} (at least {MIN_WINDOW_SAMPLES} needed); {span}"
        )
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if (start is not None and start < t[0] - step) or (stop is not None and stop > t[-1] + step):
        warnings.warn(DataNote(
            f"{where}the window from {'the start' if start is None else f'{start:g} s'} to "
            f"{'the end' if stop is None else f'{stop:g} s'} reaches past the data, which run from {t[0]:.6g} s to "
            f"{t[-1]:.6g} s: it takes {hi - lo} samples, {float(t[lo]):.6g} s to {float(t[hi - 1]):.6g} s"),
            stacklevel=2)
    window = dataset.slice(lo, hi)
    window.meta["window"] = [start, stop]  # what the model file records, so a reload cuts the same samples
    return window
