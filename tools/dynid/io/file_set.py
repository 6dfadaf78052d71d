"""A run written as a folder of files (the configuration's `files:` field, config/run_files.py), read as one table.

Each file is told its layout by its content, and must hold one of two:
- **a line per sample**, as many comma-separated values as the file's columns;
- **one value a line**, a sample's values on consecutive lines (the Panda's logs: seven lines a sample).

A first line that is not a number is a header and is skipped; its field count must still be the file's column
count, so a file with more or fewer columns than described is refused rather than read shifted. Row k of every file
is sample k: a file that ends before the others leaves the samples it lacks cut short (bad rows), and a t that
several files carry must be the same time in each (to 1 µs: the logger's one clock). A line that does not parse makes its sample a bad row, named by its file and
line, and the merged table then passes every rule of a CSV (dynid.io.csv_format, dynid.io.bad_rows): refused by
default, dropped and counted with ``bad_rows="skip"``. Samples in messages are 1-based.
"""

from __future__ import annotations

import glob
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..config.log_columns import SKIP
from ..config.robot_config import RobotConfig
from ..config.run_files import RunFile
from ..errors import DataError
from .bad_rows import DEFAULT_POLICY, Malformed
from .csv_format import Table, _read_bytes, check_columns, parse_table, table_dataset
from .dataset import Dataset
from .headerless import _width, looks_headerless

SAME_CLOCK_S = 1e-6  # two files' t of one sample may differ by their printing, not by more


def matched_files(folder: Path, files: tuple[RunFile, ...]) -> list[Path] | str:
    """The file each entry of `files` names in `folder`, or why they cannot be read as one run."""
    out: list[Path] = []
    for spec in files:
        found = sorted(p for p in folder.glob(glob.escape(spec.pattern) if not _is_glob(spec.pattern)
                                              else spec.pattern) if p.is_file())
        if len(found) != 1:
            held = ", ".join(sorted(p.name for p in folder.iterdir() if p.is_file())[:8]) or "no file"
            folders = sorted(p.name for p in folder.iterdir() if p.is_dir())
            if folders:  # the run may be one of them: the user named its parent
                held += f"; and the folders {', '.join(folders[:8])}"
            many = (f"matches {len(found)} files ({', '.join(p.name for p in found[:4])})" if found
                    else "matches no file")
            return f"'{spec.pattern}' of the configuration's files: field {many}; the folder holds {held}"
        out.append(found[0])
    return out


def holds_file_set(path: Path, config: RobotConfig) -> bool:
    """True for a folder that holds every file of the configuration's `files:` field (one each)."""
    return bool(config.files) and path.is_dir() and not isinstance(matched_files(path, config.files), str)


def _is_glob(pattern: str) -> bool:
    return any(c in pattern for c in "*?[")


@dataclass(frozen=True)
class _FileTable:
    path: Path
    spec: RunFile
    data: np.ndarray  # (samples, columns of the file), NaN where a line did not parse
    malformed: dict[int, Malformed]  # sample -> the first line of it that did not parse
    raw: bytes
    lines: int = 0  # a one-value-a-line file's lines (0 for a line per sample)


# A one-value-a-line file a line short (or long) inside: from there on every value sits one line early (late), in the
# next (previous) sample's column. Line l then follows line l − n + 1 (l − n − 1) as a signal follows itself a sample
# later, and line l − n as two different signals differ, over one window of lines where the loss (addition) is. The
# ratio of the two, in each column's own median step between samples, is at most 0.7 in the Panda's clean log and
# 2 500–5 700 000 with a line taken out or repeated anywhere in its positions, velocities or torques.
SHIFT_RATIO = 100.0


def _misaligned(values: np.ndarray, n: int) -> tuple[int, int] | None:
    """(the first line out of place, −1 a line missing before it or +1 one too many) in a one-value-a-line file of
    `n` values a sample, `values` its lines (NaN: a line that did not parse); None where each line is in its place."""
    if n < 2 or values.size < 4 * n:
        return None
    column = np.arange(values.size) % n
    step = np.full(values.size, np.nan)
    step[n:] = values[n:] - values[:-n]
    moving = np.where(np.abs(step) > 0, np.abs(step), np.nan)  # a logger that repeats samples: its zero steps left out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a column that never moves: no scale, judged by the others
        scale = np.array([np.nanmedian(moving[column == c]) for c in range(n)])
    found, best = None, SHIFT_RATIO
    for shift, lag in ((-1, n - 1), (1, n + 1)):
        other = np.full(values.size, np.nan)
        other[lag:] = values[lag:] - values[:-lag]
        apart = (step / scale[column]) ** 2  # two signals, where the line is out of place
        along = (other / scale[(column - shift) % n]) ** 2  # the same signal a sample later, there
        ok = np.isfinite(apart) & np.isfinite(along)
        width = min(lag, n)
        sums = [np.convolve(np.where(ok, x, 0.0), np.ones(width), "valid") for x in (apart, along)]
        ratio = sums[0] / (sums[1] + width)
        k = int(np.argmax(ratio))
        if ratio[k] > best:
            found, best = (k, shift), float(ratio[k])
    return found


def _read_one(path: Path, spec: RunFile) -> _FileTable:
    raw = _read_bytes(path)
    if not raw.strip():
        raise DataError(f"{path}: the file is empty")
    n = len(spec.columns)
    skip = 0 if looks_headerless(raw[:4096]) else 1
    if skip:
        header = raw.split(b"\n", 1)[0]
        fields = header.count(b",") + 1
        if fields != n:
            raise DataError(f"{path}: the header line has {fields} fields, but the configuration's "
                            f"files.'{spec.pattern}' describes {n} columns")
    body = raw.split(b"\n", skip)[skip] if skip else raw
    if not body.strip():
        raise DataError(f"{path}: the file has a header but no data lines")
    width = _width(body)

    def line(k: int) -> str:
        return f"{path.name} line {k + skip + 1}"

    if width == n:  # a line per sample
        table = parse_table(path, raw, skip, n, [c.name for c in spec.columns], line,
                            f"the configuration describes {n} columns for it")
        data = np.full((table.total, n), np.nan)
        data[table.rows] = table.data
        return _FileTable(path, spec, data, {m.row: m for m in reversed(table.malformed)}, raw)
    if width == 1:  # one value a line, a sample's values on consecutive lines
        table = parse_table(path, raw, skip, 1, None, line, "the file holds one value a line")
        samples = -(-table.total // n)  # the last one cut short where the logger stopped mid-sample
        flat = np.full(samples * n, np.nan)
        flat[table.rows] = table.data[:, 0]
        bad = {m.row // n: Malformed(m.row // n, m.kind, m.detail.replace(
            ", column 1:", f", column {spec.columns[m.row % n].name}:", 1)) for m in reversed(table.malformed)}
        if table.total % n:
            misplaced = _misaligned(flat[: table.total], n)
            if misplaced is not None:  # not a logger stopped mid-sample: every value after the line is in another column
                at, shift = misplaced
                where = (f"a line is missing just before line {at + skip + 1}" if shift < 0 else
                         f"line {at + skip} is one too many")
                raise DataError(f"{path}: {where} (from there on every value sits in the "
                                f"{'next' if shift < 0 else 'previous'} signal's place, and the file ends "
                                f"{table.total % n} of {n} lines into a sample); --bad-rows cannot mend that: mend the file")
            bad[samples - 1] = Malformed(samples - 1, "cut_short", f"{path.name} ends {table.total % n} of "
                                         f"{n} lines into sample {samples}: the last sample, cut short")
        return _FileTable(path, spec, flat.reshape(-1, n), bad, raw, table.total)
    raise DataError(f"{path}: its lines hold {width} values, but the configuration describes {n} columns for it "
                    f"(a line per sample of {n} values, or one value a line)")


def read_file_set(
    folder: str | Path,
    config: RobotConfig,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    require_all: bool = True,
    bad_rows: str = DEFAULT_POLICY,
) -> Dataset:
    """Import a folder described by `config.files` as a `Dataset` (module docstring)."""
    folder = Path(folder)
    paths = matched_files(folder, config.files)
    if isinstance(paths, str):
        raise DataError(f"{folder}: {paths}")
    tables = [_read_one(p, spec) for p, spec in zip(paths, config.files)]
    # A file that ends before the others (its logger stopped): the samples it lacks are cut short, bad rows as a CSV's
    # cut last line is, refused or dropped with the rest; the samples before are rows of every file, as ever.
    n = max(tab.data.shape[0] for tab in tables)
    longest = max(tables, key=lambda tab: tab.data.shape[0])
    # The file of the time stamps counts the run's samples: a one-value-a-line file whose lines are that many samples of
    # another width is described with a column too many or too few (not cut short, nor a logger run on)
    clock = next((tab for tab in tables if any(c.name == "t" for c in tab.spec.columns)), longest)
    for tab in tables:
        count, width = clock.data.shape[0], len(tab.spec.columns)
        if tab is not clock and tab.lines and tab.lines % count == 0 and tab.lines // count != width:
            raise DataError(f"{tab.path}: its {tab.lines} lines are {count} samples of {tab.lines // count} values, as "
                            f"many samples as {clock.path.name} holds, but the configuration's files."
                            f"'{tab.spec.pattern}' names {width} columns for it: does it describe the file's values right?")
    for i, tab in enumerate(tables):
        have = tab.data.shape[0]
        if have == n:
            continue
        lacking = {k: Malformed(k, "cut_short", f"{tab.path.name} ends after sample {have}, {longest.path.name} "
                                f"holds {n}: sample {k + 1} is cut short") for k in range(have, n)}
        tables[i] = replace(tab, data=np.vstack([tab.data, np.full((n - have, tab.data.shape[1]), np.nan)]),
                            malformed={**lacking, **tab.malformed})
    names: list[str] = []
    parts: list[np.ndarray] = []
    t_from: _FileTable | None = None
    for tab in tables:
        for j, col in enumerate(tab.spec.columns):
            if col.name == SKIP:
                continue
            values = tab.data[:, j] * col.scale
            if col.name == "t" and t_from is not None:
                t = parts[names.index("t")]
                differ = np.flatnonzero(np.abs(values - t) > SAME_CLOCK_S)  # NaN (a bad line) compares False
                if differ.size:
                    k = int(differ[0])
                    raise DataError(f"{folder}: sample {k + 1}'s t is {float(t[k])!r} s in {t_from.path.name} and "
                                    f"{float(values[k])!r} s in {tab.path.name} (they differ on {differ.size} "
                                    "samples): the files must share one clock, a row of each sample")
                continue
            if col.name == "t":
                t_from = tab
            names.append(col.name)
            parts.append(values)
    merged: dict[int, Malformed] = {}
    for tab in tables:
        for k, m in tab.malformed.items():
            merged.setdefault(k, m)
    good = np.array([k for k in range(n) if k not in merged], dtype=np.int64)
    data = np.column_stack(parts)[good]
    table = Table(data, good, [merged[k] for k in sorted(merged)], n)
    columns = check_columns(names, config, require_all=require_all, source=str(folder))
    raw = b"".join(tab.raw for tab in tables)  # the run's digest covers every file, in the configuration's order
    return table_dataset(folder, raw, names, columns, data, config, joint_limits, "file set",
                         lambda k: f"sample {k + 1}", table=table, bad_rows=bad_rows)
