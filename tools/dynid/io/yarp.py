"""A `yarpdatadumper` folder as the robot writes it, read through the configuration's `yarp:` field.

Each port is a folder holding `data.log` (one message per line: `<sequence> <stamp, s> <payload>`) and
`info.log`. A `stateExt:o` payload is ten parenthesised groups, each followed by `[ok]`; the first holds the joint
positions. An `analog:o` payload is the sensor's six values. Every port has its own clock (about 100 Hz here, with
5–17 ms between messages), so the ports are put on one time base:

- the run's time origin is the earliest stamp of any port in the folder (so a window `--from/--to` means the same
  seconds whatever the configuration reads), and the common span is where every configured port has data;
- the dumpers start and stop one after another, so the ports' first stamps, and their last, differ: by up to
  `max_skew` (default 2 s; the iCub leg's run: 0.25 s and 1.24 s) the run is cut to the common span as a matter of
  course. A port that starts later or ends sooner than that (its log cut short, its dumper stopped early) would cut
  the run short, as a file that ends before the others cuts a folder of files (dynid.io.file_set): the other ports'
  messages beyond its first or last stamp are `cut_short` bad rows, refused by default in one line that names the
  port and where it starts or ends against the others, dropped with `bad_rows="skip"` (the grid then spans the
  common span, as ever) with a DataNote naming the port;
- each channel is interpolated linearly onto a uniform grid at the configured `rate` over that span. Linear
  interpolation between two messages 10 ms apart moves no value by more than their difference, and it neither
  invents nor hides a silence: a port silent for longer than `max_gap` inside the span is refused, naming the
  port, the time and the silence;
- a message whose stamp does not increase (a port re-sending) is dropped and counted; a last line cut short (the
  dumper stopped mid-write) is dropped and counted;
- any other line that is no message of the port is a bad row (dynid.io.bad_rows: `empty`, `column_count` for a
  missing field or another number of values than the port has, `not_a_number`, `non_finite`, `time_negative` for a
  negative stamp, `out_of_range` for a value beyond ±1e6 in the project's units), found in every port at once.
  `bad_rows="refuse"` (the default) refuses the folder in one line naming the port's file and line; `"skip"` drops
  the line. A line is one message of one port, so skipping it leaves that port one message fewer: its neighbours are
  interpolated across the gap, as across any interval of its clock, and every sample of the grid is kept (the other
  ports' messages are untouched); dropped lines that leave the port silent for longer than `max_gap` inside the span
  are refused as that silence. The count is in lines: `meta["bad_rows"]`'s `rows_read` is the configured ports'
  lines, its rows are named `PORT/data.log line K`.

What was done is recorded in the dataset's `meta["yarp"]`: the time origin (Unix s) and, per port, the messages
read, dropped, the median and largest interval.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..config.log_columns import SKIP
from ..config.robot_config import RobotConfig
from ..config.yarp_ports import YarpLayout, YarpPort
from ..errors import DataError, DataNote
from .align import Stream, keep_increasing, on_grid, uniform_grid
from .bad_rows import DEFAULT_POLICY, KINDS, MAX_ABS_VALUE, SHOW_LINES, BadRows, Malformed, apply_policy
from .csv_format import check_columns, table_dataset
from .dataset import FT_CHANNELS, Dataset

_GROUP = re.compile(r"\(([^()]*)\)")
RATE_SHARE = 0.5  # a grid slower than half the slowest port's message rate is noted (the leg's 10 Hz on 100 Hz)


def is_dumper_folder(path: Path) -> bool:
    """True for a directory that holds, at any depth, a port folder with `data.log` (and `info.log`)."""
    return path.is_dir() and any(p.with_name("info.log").is_file() for p in path.glob("**/data.log"))


@dataclass
class _PortLog:
    stamps: np.ndarray  # (M,) Unix s, strictly increasing
    values: np.ndarray  # (M, K) in the project's units
    dropped_stale: int
    dropped_cut: int
    bad: list[Malformed]  # its lines that are no message (0-based line numbers), refused or dropped by the policy
    lines: int  # lines in its data.log
    line_of: np.ndarray  # (M,) the 0-based line of each message kept


def _read_port(root: Path, spec: YarpPort) -> _PortLog:
    path = root / spec.port / "data.log"
    if not path.is_file():
        raise DataError(f"{root}: no port '{spec.port}' (expected {path}); the configuration's yarp.ports names it")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise DataError(f"{path}: not a text file (byte {e.start} is not UTF-8)") from None
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror or e}") from None
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    width = len(spec.joints) if spec.joints else 6
    stamps: list[float] = []
    rows: list[list[float]] = []
    line_of: list[int] = []
    bad: list[Malformed] = []
    cut = 0
    scale = np.asarray(spec.scale)
    for k, line in enumerate(lines):
        parsed = _parse_line(line, bool(spec.joints), width)
        if not isinstance(parsed[0], str) and np.any(np.abs(np.asarray(parsed[1]) * scale) > MAX_ABS_VALUE):
            parsed = ("out_of_range", f"a value beyond ±{MAX_ABS_VALUE:g} in the project's units (N, Nm, rad), which "
                                      "no sensor reads: a corrupt value")
        if isinstance(parsed[0], str):
            if k == len(lines) - 1 and not text.endswith("\n"):
                cut += 1  # the dumper stopped mid-line
                continue
            bad.append(Malformed(k, parsed[0], f"{spec.port}/data.log line {k + 1}: {parsed[1]}"))
            continue
        stamps.append(parsed[0])
        rows.append(parsed[1])
        line_of.append(k)
    t = np.asarray(stamps)
    values = np.asarray(rows, dtype=float).reshape(-1, width) * scale
    keep = keep_increasing(t)  # drop messages that do not move the port's clock forward
    return _PortLog(t[keep], values[keep], int((~keep).sum()), cut, bad, len(lines), np.asarray(line_of)[keep])


def _parse_line(line: str, state: bool, width: int) -> tuple[float, list[float]] | tuple[str, str]:
    """`(stamp, values)` of one message, or the bad-row kind (dynid.io.bad_rows) and what is wrong with it."""
    head = line.split(None, 2)
    if len(head) < 3:
        if not line.strip():
            return "empty", "a blank line between messages"
        return "column_count", "expected '<sequence> <stamp> <payload>'"
    try:
        stamp = float(head[1])
    except ValueError:
        return "not_a_number", f"the stamp {head[1][:40]!r} is not a number"
    if not np.isfinite(stamp):
        return "non_finite", f"the stamp {head[1][:40]!r} is not a time"
    if stamp < 0:
        return "time_negative", f"the stamp {head[1][:40]!r} is not a time"
    payload = head[2]
    if state:
        groups = _GROUP.findall(payload)
        if not groups:
            return "column_count", "no parenthesised group: not a stateExt:o message"
        payload = groups[0]
    cells = payload.split()
    if len(cells) != width:
        what = "joint positions" if state else "values (an F/T sensor's fx fy fz tx ty tz)"
        return "column_count", f"{len(cells)} {what}, the configuration's port has {width}"
    try:
        values = [float(c) for c in cells]
    except ValueError:
        return "not_a_number", f"{payload.strip()[:60]!r} holds a value that is not a number"
    if not all(np.isfinite(values)):
        return "non_finite", "a value is not finite"
    return stamp, values


def first_stamps_origin(root: Path) -> float | None:
    """The earliest first stamp of any data.log under a dumper folder (its time origin, before the ports' bad lines are
    read): None where no log has a readable first stamp."""
    stamps = [s for s in (_first_stamp(p) for p in Path(root).glob("**/data.log")) if s is not None]
    return min(stamps) if stamps else None


def _first_stamp(path: Path) -> float | None:
    try:
        with open(path, "rb") as f:
            parts = f.readline().split(None, 2)
        return float(parts[1])
    except (OSError, ValueError, IndexError):
        return None


def _cut_short(logs: dict[str, _PortLog], origin: float, max_skew: float) -> tuple[dict[str, list[Malformed]], list[str]]:
    """Per port, its messages before the latest first stamp or after the earliest last stamp of the ports, where the
    ports' starts or ends differ by more than `max_skew` (module docstring): `cut_short` bad rows; and what happened,
    in words, for a note."""
    cut: dict[str, list[Malformed]] = {port: [] for port in logs}
    said: list[str] = []
    firsts = {port: float(log.stamps[0]) for port, log in logs.items()}
    lasts = {port: float(log.stamps[-1]) for port, log in logs.items()}
    for end, stamps in (("start", firsts), ("end", lasts)):
        late, early = (max, min) if end == "start" else (min, max)
        short, other = late(stamps, key=stamps.get), early(stamps, key=stamps.get)
        skew = abs(stamps[short] - stamps[other])
        if skew <= max_skew:
            continue
        at = stamps[short]
        lost = {port: np.flatnonzero(log.stamps < at if end == "start" else log.stamps > at)
                for port, log in logs.items()}
        n = sum(k.size for k in lost.values())
        what = (f"{short}/data.log {'starts' if end == 'start' else 'ends'} at t = {at - origin:.3f} s, {skew:.3f} s "
                f"{'after' if end == 'start' else 'before'} {other}/data.log ({stamps[other] - origin:.3f} s), by more "
                f"than the {max_skew:g} s the ports' {end}s may differ (yarp.max_skew)")
        said.append(f"{what}: the run {'starts' if end == 'start' else 'ends'} there")
        for port, k in lost.items():
            seen = {m.row for m in cut[port]}  # ports that share no span at all: a message before one, after another
            cut[port] += [Malformed(int(line), "cut_short", f"{what}: the {n} messages the other ports hold "
                                    f"{'before' if end == 'start' else 'after'} it are cut short")
                          for line in logs[port].line_of[k] if int(line) not in seen]
    return cut, said


def _bad_lines(root: Path, layout: YarpLayout, logs: dict[str, _PortLog], cut: dict[str, list[Malformed]],
               policy: str) -> dict[str, Any] | None:
    """The ports' bad lines and messages cut short refused (one line naming the first few) or, with `skip`, what
    `meta["bad_rows"]` records; None when there are none. Lines are numbered over the ports in the configuration's
    order."""
    rows, kinds, labels, details, total = [], [], {}, {}, 0
    for spec in layout.ports:
        log = logs[spec.port]
        for m in [*log.bad, *cut[spec.port]]:
            rows.append(total + m.row)
            kinds.append(m.kind)
            labels[total + m.row] = f"{spec.port}/data.log line {m.row + 1}"
            details[total + m.row] = m.detail
        total += log.lines
    if not rows:
        return apply_policy(None, np.ones(1, bool), policy, str(root), str)
    order = np.argsort(rows, kind="stable")
    found = BadRows(np.asarray(rows, np.int64)[order], tuple(kinds[i] for i in order), details[rows[order[0]]], total)
    return apply_policy(found, np.ones(1, bool), policy, str(root), lambda i: labels[i])


def read_yarp(path: str | Path, config: RobotConfig, joint_limits=None, require_all: bool = True,
              bad_rows: str = DEFAULT_POLICY) -> Dataset:
    """Import a yarpdatadumper folder described by `config.yarp` as a `Dataset` (module docstring)."""
    root = Path(path)
    layout = config.yarp
    if layout is None:
        raise DataError(
            f"{root}: a yarpdatadumper folder, but the configuration {config.name} has no 'yarp' field naming its "
            "ports (docs/formats.md, Robot configuration)"
        )
    logs = {spec.port: _read_port(root, spec) for spec in layout.ports}
    for spec in layout.ports:
        if logs[spec.port].stamps.size < 2:
            _bad_lines(root, layout, logs, {port: [] for port in logs}, bad_rows)  # its bad lines, refused by default
            n = logs[spec.port].stamps.size
            raise DataError(f"{root / spec.port / 'data.log'}: {n} message{'s' * (n != 1)}"
                            f"{' left' if logs[spec.port].bad else ''}: a port needs at least two")
    first = first_stamps_origin(root)
    origin = min([*([] if first is None else [first]), *(log.stamps[0] for log in logs.values())])
    cut, said = _cut_short(logs, origin, layout.max_skew)
    dropped = _bad_lines(root, layout, logs, cut, bad_rows)  # bad lines and a port cut short: refused by default
    for note in said:  # skipped: the run is shorter than its ports' logs, and why
        warnings.warn(DataNote(f"{root}: {note} (--bad-rows skip)"), stacklevel=3)
    streams = [Stream(port, log.stamps, log.values) for port, log in logs.items()]
    slowest = max(float(np.median(np.diff(log.stamps))) for log in logs.values() if log.stamps.size > 1)
    if slowest > 0 and layout.rate * slowest < RATE_SHARE:  # the grid throws most of every port's messages away
        warnings.warn(DataNote(f"{root}: yarp.rate {layout.rate:g} Hz keeps fewer than half of the ports' "
                               f"messages (the slowest sends every {1e3 * slowest:.3g} ms, {1 / slowest:.3g} Hz): the "
                               "derivatives' window then spans few samples; set yarp.rate to the ports' rate"),
                      stacklevel=3)
    grid = uniform_grid(str(root), streams, origin, layout.rate, layout.max_gap, "port", "yarp.max_gap")
    for log in logs.values():
        log.stamps = log.stamps - origin

    names, columns_data = ["t"], [grid[:, None]]
    for spec, stream in zip(layout.ports, streams):
        values = on_grid(grid, stream, origin)
        if spec.joints:
            names += [f"q.{joint}" for joint in spec.joints if joint != SKIP]
            columns_data.append(values[:, [k for k, joint in enumerate(spec.joints) if joint != SKIP]])
        else:
            names += [f"ft.{spec.sensor}.{channel}" for channel in FT_CHANNELS]
            columns_data.append(values)
    data = np.hstack(columns_data)
    columns = check_columns(names, config, require_all=require_all, source=str(root))
    digest = hashlib.sha256()
    for spec in layout.ports:
        digest.update((root / spec.port / "data.log").read_bytes())
    dataset = table_dataset(
        root, b"", names, columns, data, config, joint_limits, "yarp dumper", lambda i: f"sample {i + 1}",
        bad_rows=bad_rows)
    dataset.meta["source_sha256"] = digest.hexdigest()
    if dropped is not None:  # the ports' lines skipped; the grid's own rows were checked by table_dataset
        samples = dataset.meta.get("bad_rows")
        if samples:  # grid samples dropped too (not expected: the lines' values are checked, the grid's t increases)
            kinds = {k: dropped["kinds"].get(k, 0) + samples["kinds"].get(k, 0) for k in KINDS
                     if k in dropped["kinds"] or k in samples["kinds"]}
            dropped = {**dropped, "count": dropped["count"] + samples["count"], "kinds": kinds,
                       "first": (dropped["first"] + samples["first"])[:SHOW_LINES]}
        dataset.meta["bad_rows"] = dropped
    dataset.meta["yarp"] = {
        "origin_unix_s": float(origin),
        "rate_hz": layout.rate,
        "ports": {
            spec.port: {
                "messages": int(logs[spec.port].stamps.size),
                "dropped_not_increasing": logs[spec.port].dropped_stale,
                "dropped_cut_last_line": logs[spec.port].dropped_cut,
                "dropped_bad_lines": len(logs[spec.port].bad) if dropped is not None else 0,
                "first_s": float(logs[spec.port].stamps[0]),
                "last_s": float(logs[spec.port].stamps[-1]),
                "cut_short": len(cut[spec.port]),
                "median_interval_s": float(np.median(np.diff(logs[spec.port].stamps))),
                "max_interval_s": float(np.max(np.diff(logs[spec.port].stamps))),
            }
            for spec in layout.ports
        },
    }
    return dataset
