"""CSV import and export of experiment data (docs/design.md §4).

Format: comma-separated, UTF-8, one header line naming the columns, then one line per sample; every cell is a
decimal number (``nan``/``inf`` are refused). Columns may come in any order:

=========================================  ====================================================================
``t``                                      s, strictly increasing (required)
``q.<joint>``                              rad (m for prismatic joints); required for every configured joint
``dq.<joint>``, ``ddq.<joint>``            optional; each kind is all-or-nothing over the joints. ``dq``
                                           without ``ddq`` is fine: the missing kind is estimated from q
                                           (`Dataset.with_derivatives`), the recorded one is kept
``pwm.<motor>``                            duty fraction in [-1, 1]
``current.<motor>``                        A (an extension of docs/design.md §4, for current-driven motors)
``tau.<joint>``                            Nm, measured joint torque
``ft.<sensor>.fx .fy .fz .tx .ty .tz``     N and Nm; all six or none for each sensor
``contact``                                ground truth; any non-zero value is contact
anything else                              kept verbatim in `Dataset.extra` (e.g. ``contact_side``,
                                           ``effort.arm_1_joint``), so that nothing is lost
=========================================  ====================================================================

A column with a known prefix (``q dq ddq tau pwm current ft``) must name a joint, motor or sensor of the
robot configuration: ``q.r_elbw`` is an error (a typo must not silently become an extra column). With
``require_all`` (the default), every input the configuration declares must be present: ``pwm.<m>`` for every
motor of a PWM-driven actuation group, ``current.<m>`` for a current-driven one, ``tau.<j>`` for every joint
of a torque-driven one, and the six channels of every F/T sensor.

Every problem raises `DataError` with one line that names the file, the column and the row. Rows are 1-based
data rows (the header is not a row); blank lines between rows are refused, so row R is file line R + 1.

Exported CSVs write every float with Python's shortest round-trip representation (``repr``), so that
CSV -> Dataset -> CSV is exact.
"""

from __future__ import annotations

import difflib
import hashlib
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError, PathError
from ..kernels import native
from .bad_rows import DEFAULT_POLICY, Malformed, apply_policy, find_bad_rows
from .dataset import FT_CHANNELS, Dataset, atomic_write, check_units

JOINT_KINDS: tuple[str, ...] = ("q", "dq", "ddq", "tau")
MOTOR_KINDS: tuple[str, ...] = ("pwm", "current")
KNOWN_PREFIXES: tuple[str, ...] = JOINT_KINDS + MOTOR_KINDS + ("ft",)

_NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*(e[+-]?\d+)?|\.\d+(e[+-]?\d+)?|nan|inf|infinity)\s*", re.IGNORECASE)
_WRITE_BLOCK = 20_000  # rows formatted at a time when writing: bounded memory for long runs


@dataclass(frozen=True)
class Column:
    """What one CSV column holds."""

    name: str  # as in the header
    kind: str  # t, q, dq, ddq, tau, pwm, current, ft, contact or extra
    key: str = ""  # joint, motor or sensor name ("" for t and contact, the full name for extra)
    channel: int = -1  # index into FT_CHANNELS for ft columns


def _row(i: int) -> str:
    """A 0-based data index as the user sees it in the file."""
    return f"row {i + 1} (line {i + 2})"


def _suggest(name: str, known: Sequence[str]) -> str:
    close = difflib.get_close_matches(name, known, n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def classify_column(name: str, config: RobotConfig) -> Column:
    """The meaning of a column name for a configuration; an unknown joint, motor or sensor raises `DataError`."""
    if name in ("t", "contact"):
        return Column(name, name)
    prefix, dot, rest = name.partition(".")
    if not dot or prefix not in KNOWN_PREFIXES:
        return Column(name, "extra", name)
    if not rest:
        raise DataError(f"column '{name}' names nothing after '{prefix}.'")
    if prefix in JOINT_KINDS:
        if rest not in config.joints:
            raise DataError(
                f"unknown joint '{rest}' in column {name}{_suggest(rest, config.joints)}; "
                f"the configuration {config.name} has: {', '.join(config.joints)}"
            )
        return Column(name, prefix, rest)
    if prefix in MOTOR_KINDS:
        if rest not in config.motor_names:
            known = ", ".join(config.motor_names) or "no motors"
            raise DataError(
                f"unknown motor '{rest}' in column {name}{_suggest(rest, config.motor_names)}; "
                f"the configuration {config.name} has: {known}"
            )
        return Column(name, prefix, rest)
    sensors = tuple(s.name for s in config.ft_sensors)
    sensor, dot, channel = rest.rpartition(".")
    if not dot or channel not in FT_CHANNELS:
        if rest in sensors:
            raise DataError(f"column {name} names no channel: F/T columns are ft.{rest}.<{'|'.join(FT_CHANNELS)}>")
        if sensor in sensors:
            raise DataError(
                f"unknown F/T channel '{channel}' in column {name}; the channels are {', '.join(FT_CHANNELS)}"
            )
    if sensor not in sensors:
        what = sensor or rest
        raise DataError(
            f"unknown F/T sensor '{what}' in column {name}{_suggest(what, sensors)}; "
            f"the configuration {config.name} has: {', '.join(sensors) or 'no F/T sensor'}"
        )
    return Column(name, "ft", sensor, FT_CHANNELS.index(channel))


def required_columns(config: RobotConfig) -> list[tuple[str, str]]:
    """(column, why) for every column the configuration needs when ``require_all`` is set.

    `why` completes "the configuration <name> ...", e.g. "drives actuation group 'elbow' by pwm".
    """
    needed = [(f"q.{j}", f"has the joint {j}") for j in config.joints]
    for g in config.actuation:
        if g.input == "torque":
            needed += [(f"tau.{j}", f"drives actuation group '{g.name}' by joint torque") for j in g.joints]
        else:
            needed += [(f"{g.input}.{m}", f"drives actuation group '{g.name}' by {g.input}") for m in g.motors]
    for s in config.ft_sensors:
        needed += [(f"ft.{s.name}.{c}", f"has the F/T sensor {s.name}") for c in FT_CHANNELS]
    needed += [(c, f"takes gravity from the accelerometer at {config.gravity_imu}") for c in config.gravity_imu_columns]
    return needed


def check_columns(
    names: Sequence[str], config: RobotConfig, require_all: bool = True, source: str = ""
) -> list[Column]:
    """Classify header names and check them against the configuration (module docstring for the rules)."""
    where = f"{source}: " if source else ""
    first_seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if not name:
            raise DataError(f"{where}column {i + 1} of the header has an empty name")
        if name in first_seen:
            raise DataError(
                f"{where}column {name} appears twice in the header (columns {first_seen[name] + 1} and {i + 1})"
            )
        first_seen[name] = i
    try:
        columns = [classify_column(n, config) for n in names]
    except DataError as e:
        raise DataError(f"{where}{e}") from None
    if "t" not in first_seen:
        shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
        raise DataError(f"{where}column t (time, s) is missing; the header has: {shown}")

    present = set(names)
    for kind in ("q", "dq", "ddq"):
        have = [j for j in config.joints if f"{kind}.{j}" in present]
        lacking = [f"{kind}.{j}" for j in config.joints if f"{kind}.{j}" not in present]
        if kind == "q" and lacking:
            raise DataError(
                f"{where}column {lacking[0]} is missing: the configuration {config.name} needs q.<joint> for every "
                f"joint (missing: {', '.join(lacking)})"
            )
        if have and lacking:
            raise DataError(
                f"{where}{kind} is given for some joints only (missing: {', '.join(lacking)}): give {kind} for every "
                f"joint or for none (then it is estimated from q)"
            )
    for s in config.ft_sensors:
        lacking = [f"ft.{s.name}.{c}" for c in FT_CHANNELS if f"ft.{s.name}.{c}" not in present]
        if 0 < len(lacking) < len(FT_CHANNELS):
            raise DataError(f"{where}F/T sensor {s.name} lacks columns {', '.join(lacking)}: all six channels or none")
    if require_all:
        lacking_all = [(c, why) for c, why in required_columns(config) if c not in present]
        if lacking_all:
            column, why = lacking_all[0]
            also = f"; missing in all: {', '.join(c for c, _ in lacking_all)}" if len(lacking_all) > 1 else ""
            raise DataError(f"{where}column {column} is missing: the configuration {config.name} {why}{also}")
    return columns


# ----------------------------------------------------------------------------------------------------------
# Reading


_LONE_CR = re.compile(rb"\r(?=[^\n])")


def _read_bytes(path: Path) -> bytes:
    if not path.exists():
        raise PathError(f"CSV file not found: {path}")
    if not path.is_file():
        raise DataError(f"CSV path is not a file: {path}")
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror}") from None
    # numpy's parser ends a line at a lone CR too, and skips blank lines: a row split by a CR and a blank line
    # elsewhere kept the row count, and the file was read with its rows shifted. Lines end in LF or CRLF only.
    first = raw.split(b"\n", 1)[0]
    try:
        first.decode("utf-8-sig")
    except UnicodeDecodeError:  # not text at all: the header's own check says so, which means more than a CR
        return raw
    lone = _LONE_CR.search(raw)
    if lone:
        line = raw.count(b"\n", 0, lone.start()) + 1
        raise DataError(f"{path}: line {line} holds a carriage return inside the line: lines must end in LF or CRLF")
    return raw


def _header(raw: bytes, path: Path) -> list[str]:
    if not raw.strip():
        raise DataError(f"{path}: the file is empty")
    end = raw.find(b"\n")
    line_bytes = raw if end < 0 else raw[:end]
    try:
        line = line_bytes.decode("utf-8-sig").strip()
    except UnicodeDecodeError:
        raise DataError(f"{path}: the header line is not UTF-8 text; is this a CSV file?") from None
    if not line:
        raise DataError(
            f"{path}: the first line is empty; it must be the header naming the columns (t, q.<joint>, ...)"
        )
    names = [n.strip() for n in line.split(",")]
    # Some tools quote every header cell; the names themselves never contain commas or quotes.
    names = [n[1:-1].strip() if len(n) >= 2 and n[0] == n[-1] == '"' else n for n in names]
    if _NUMBER.fullmatch(names[0]):
        raise DataError(
            f"{path}: no header: the first line is data; name the columns in a header line (t, q.<joint>, ...), "
            "or describe them in the robot configuration's 'columns' field (docs/formats.md)"
        )
    if len(names) == 1 and any(sep in names[0] for sep in (";", "\t")):
        raise DataError(f"{path}: the header is one column '{names[0][:40]}...': columns must be separated by commas")
    return names


_NUMBER_BYTES = re.compile(_NUMBER.pattern.encode(), re.IGNORECASE)


@dataclass(frozen=True)
class Table:
    """Rows of a text table: the ones that parsed, their 0-based row numbers, and the lines that did not."""

    data: np.ndarray  # (N, width) float64
    rows: np.ndarray  # (N,) 0-based row numbers in the file
    malformed: list[Malformed]
    total: int  # rows in the file


def parse_table(path: Path, raw: bytes, skip: int, width: int, names: Sequence[str] | None,
                label: Callable[[int], str], width_is: str) -> Table:
    """The data rows of a comma-separated file after `skip` header lines, each of `width` cells.

    numpy's C parser reads a clean file at once; a file it refuses is read line by line, and every line that is
    not `width` decimal numbers becomes a `Malformed` (dynid.io.bad_rows) instead of ending the read. `names`
    name the columns in messages (None: by number); `width_is` completes "has 3 fields, but ..."."""
    lines = raw.split(b"\n")
    ends_with_newline = raw.endswith(b"\n")
    while lines and not lines[-1].strip():  # trailing blank lines are no rows
        lines.pop()
    lines = lines[skip:]
    total = len(lines)
    try:
        data = np.loadtxt(path, dtype=float, delimiter=",", skiprows=skip, comments=None, ndmin=2,
                          encoding="utf-8-sig")
        if data.shape == (total, width):
            return Table(data, np.arange(total), [], total)
    except (ValueError, UnicodeDecodeError):
        pass
    good: list[str] = []
    rows: list[int] = []
    malformed: list[Malformed] = []
    for k, line in enumerate(lines):
        if k == 0 and skip == 0:
            line = line.removeprefix(b"\xef\xbb\xbf")
        line = line.removesuffix(b"\r")
        if not line.strip():
            malformed.append(Malformed(k, "empty", f"line {k + skip + 1} is empty: blank lines between data rows "
                                                   "are not allowed"))
            continue
        cells = line.split(b",")
        if len(cells) != width:
            cut = k == total - 1 and not ends_with_newline and len(cells) < width
            malformed.append(Malformed(k, "cut_short" if cut else "column_count",
                                       f"{label(k)} has {len(cells)} fields, but {width_is}"
                                       + (": the last line, cut short" if cut else "")))
            continue
        bad = next((c for c, cell in enumerate(cells) if not _NUMBER_BYTES.fullmatch(cell)), None)
        if bad is not None:
            shown = cells[bad].decode("utf-8", errors="replace").strip()
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            column = names[bad] if names is not None else str(bad + 1)
            malformed.append(Malformed(k, "not_a_number", f"{label(k)}, column {column}: {shown!r} is not a number"))
            continue
        good.append(line.decode("ascii"))
        rows.append(k)
    data = (np.loadtxt(good, dtype=float, delimiter=",", comments=None, ndmin=2) if good
            else np.empty((0, width)))
    return Table(data.reshape(-1, width), np.asarray(rows, dtype=np.int64), malformed, total)


def read_csv(
    path: str | Path,
    config: RobotConfig,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    require_all: bool = True,
    bad_rows: str = DEFAULT_POLICY,
) -> Dataset:
    """Import a CSV of docs/design.md §4 (rules in the module docstring) as a `Dataset` of the configuration.

    Parameters
    ----------
    path
        The CSV file.
    config
        The robot configuration: it names the joints (and their order), motors and F/T sensors.
    joint_limits
        joint -> (lower, upper); when given, positions far outside the limits are refused as degrees.
    require_all
        Require every input and sensor channel the configuration declares (q is always required).
    bad_rows
        ``"refuse"`` (the default) or ``"skip"`` the bad rows of dynid.io.bad_rows.

    Raises
    ------
    DataError
        With one line naming the file, the column and the row of the first problem.
    """
    path = Path(path)
    raw = _read_bytes(path)
    names = _header(raw, path)
    n_rows = raw.rstrip().count(b"\n")
    if n_rows == 0:
        raise DataError(f"{path}: the file has a header but no data rows")
    columns = check_columns(names, config, require_all=require_all, source=str(path))
    table = parse_table(path, raw, 1, len(names), names, _row, f"the header has {len(names)} columns")
    return table_dataset(path, raw, names, columns, table.data, config, joint_limits, "csv", _row, table=table,
                         bad_rows=bad_rows)


def table_dataset(
    path: Path,
    raw: bytes,
    names: Sequence[str],
    columns: Sequence[Column],
    data: np.ndarray,
    config: RobotConfig,
    joint_limits: Mapping[str, tuple[float, float]] | None,
    source_format: str,
    row: Callable[[int], str],
    table: Table | None = None,
    bad_rows: str = DEFAULT_POLICY,
) -> Dataset:
    """A parsed table (N, columns) in the project's units as a checked `Dataset`; `row` names a 0-based row of the
    file. `table` is what `parse_table` read (`data` its rows); its bad rows and those found here (dynid.io.bad_rows)
    are refused or, with `bad_rows="skip"`, dropped and recorded in `meta["bad_rows"]`."""
    index = {col.name: i for i, col in enumerate(columns)}
    rows = table.rows if table is not None else np.arange(data.shape[0])
    found, keep = find_bad_rows(data, rows, names, [c.kind for c in columns],
                                table.total if table is not None else data.shape[0],
                                table.malformed if table is not None else (), row, index["t"])
    dropped = apply_policy(found, keep, bad_rows, str(path), row)
    if dropped is not None:
        data, rows = data[keep], rows[keep]

    def _row(i: int) -> str:  # a sample of the dataset, named by its row in the file
        return row(int(rows[i]))

    t = data[:, index["t"]].copy()

    def joint_matrix(kind: str) -> np.ndarray | None:
        if f"{kind}.{config.joints[0]}" not in index:
            return None
        return data[:, [index[f"{kind}.{j}"] for j in config.joints]]

    def family(kind: str, keys: Sequence[str]) -> dict[str, np.ndarray]:
        # Configuration order, not file order: datasets of one robot then list channels alike.
        return {k: data[:, index[f"{kind}.{k}"]].copy() for k in keys if f"{kind}.{k}" in index}

    ft = {}
    for s in config.ft_sensors:
        if f"ft.{s.name}.fx" in index:
            ft[s.name] = data[:, [index[f"ft.{s.name}.{c}"] for c in FT_CHANNELS]]
    dataset = Dataset(
        t=t,
        joints=config.joints,
        q=joint_matrix("q"),  # type: ignore[arg-type]  # q is always present (check_columns)
        dq=joint_matrix("dq"),
        ddq=joint_matrix("ddq"),
        pwm=family("pwm", config.motor_names),
        current=family("current", config.motor_names),
        tau=family("tau", config.joints),
        ft=ft,
        contact=data[:, index["contact"]] if "contact" in index else None,
        extra={col.name: data[:, i].copy() for i, col in enumerate(columns) if col.kind == "extra"},
        meta={
            "robot": config.name,
            "config_digest": config.digest,
            "source": str(path),
            "source_format": source_format,
            "source_sha256": hashlib.sha256(raw).hexdigest(),
            **({"bad_rows": dropped} if dropped is not None else {}),
        },
    )
    try:
        check_units(dataset, joint_limits, row=_row)
    except DataError as e:
        raise DataError(f"{path}: {e}") from None
    return dataset


# ----------------------------------------------------------------------------------------------------------
# Writing


def write_csv(dataset: Dataset, path: str | Path) -> None:
    """Write a dataset as a CSV of docs/design.md §4, atomically; floats in shortest round-trip form.

    Columns: t, q, dq, ddq, pwm, current, tau, ft, contact, then the extra columns. `meta` is not written
    (a CSV has no place for it); save the dataset file to keep it.
    """
    dataset.validate()
    columns = dataset.columns()
    for name, _ in columns:
        if any(ch in name for ch in ',"\n\r'):
            raise DataError(f"cannot write column '{name}' to CSV: names must not contain commas, quotes or newlines")
    header = ",".join(name for name, _ in columns) + "\n"
    rows = _compiled_rows(columns) or _rows_text

    def write(f: BinaryIO) -> None:
        f.write(header.encode())
        for start in range(0, dataset.n_samples, _WRITE_BLOCK):
            f.write(rows([values[start : start + _WRITE_BLOCK] for _, values in columns]))

    atomic_write(path, write)


def _rows_text(block: Sequence[np.ndarray]) -> bytes:
    """The CSV lines of one block of columns, the reference: repr of a Python float is the shortest text that reads
    back to the same float; ints stay ints."""
    text = [list(map(str if v.dtype.kind in "iub" else repr, v.tolist())) for v in block]
    return ("\n".join(map(",".join, zip(*text, strict=True))) + "\n").encode()


def _compiled_rows(columns: Sequence[tuple[str, np.ndarray]]) -> Callable[[Sequence[np.ndarray]], bytes] | None:
    """The compiled kernel that writes `_rows_text`'s bytes (dynid._kernels.csv_rows: repr's digits and layout,
    checked against it in tools/tests/test_kernels.py), where it can: no booleans (str writes True), integers
    exact as doubles; else None."""
    kernel = native()
    kinds = [v.dtype.kind for _, v in columns]
    if kernel is None or any(k not in "fiu" for k in kinds) or any(
            k in "iu" and v.size and (v.max() > 2**53 or v.min() < -(2**53))
            for k, (_, v) in zip(kinds, columns, strict=True)):
        return None
    integer = [k in "iu" for k in kinds]
    return lambda block: kernel.csv_rows(np.column_stack(block).astype(np.float64, copy=False), integer)
