"""A headerless CSV as a robot's controller logs it, read through the configuration's `columns:` field.

The configuration names every column and its unit (dynid.config.log_columns); the reader converts each column to
the project's units and then applies every rule of a CSV with a header (dynid.io.csv_format). A file may stop
before the list does (the UR's 25-column logs beside its 31-column ones, with one list): the columns it has must
still hold every channel the configuration needs. Rows are 1-based file lines (there is no header).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..config.log_columns import SKIP
from ..config.robot_config import RobotConfig
from ..errors import DataError
from .bad_rows import DEFAULT_POLICY
from .csv_format import _read_bytes, check_columns, parse_table, table_dataset
from .dataset import Dataset

_FIRST_CELL = re.compile(rb"^\s*[+-]?(\d|\.\d)")


def looks_headerless(head: bytes) -> bool:
    """True when the first line starts with a number: data, not a header."""
    return bool(_FIRST_CELL.match(head.lstrip(b"\xef\xbb\xbf")))


def _line(i: int) -> str:
    return f"line {i + 1}"


def _width(raw: bytes) -> int:
    """The number of fields of the file's rows: the most common count over its first lines (a garbage first row, as
    controller logs start with, must not set it)."""
    counts = [line.count(b",") + 1 for line in raw[:1 << 20].split(b"\n")[:_WIDTH_LINES] if line.strip()]
    values, times = np.unique(counts, return_counts=True)
    return int(values[np.argmax(times)])


_WIDTH_LINES = 200


def _groups(config: RobotConfig) -> list[str]:
    """Each listed column's group: its kind before the first dot (q, velocity, current, …), an F/T sensor's six its
    own (ft.<sensor>); a skipped column is a group of its own."""
    def group(i: int, name: str) -> str:
        if name == SKIP:
            return f"{SKIP}{i}"
        kind, _, rest = name.partition(".")
        return f"ft.{rest.partition('.')[0]}" if kind == "ft" else kind

    return [group(i, c.name) for i, c in enumerate(config.columns)]


def check_group_end(path: Path, config: RobotConfig, width: int) -> None:
    """A file that stops before the configuration's list does must stop where a group of columns ends (the UR's
    25-column logs after the desired currents, its 31-column ones after the desired torques): one that stops inside
    a group has lost or gained a column somewhere, and every column after it would be read shifted, silently where
    the channels it shifts into are still plausible."""
    groups = _groups(config)
    if width >= len(groups) or groups[width - 1] != groups[width]:
        return
    group = groups[width]
    first = width - 1
    while first > 0 and groups[first - 1] == group:
        first -= 1
    last = width
    while last + 1 < len(groups) and groups[last + 1] == group:
        last += 1
    ends = [i for i in range(1, len(groups) + 1) if i == len(groups) or groups[i - 1] != groups[i]]
    raise DataError(
        f"{path}: the rows have {width} fields, which ends inside the configuration {config.name}'s {group}.* "
        f"columns ({width - first} of {last - first + 1}): a column is missing or extra, and the columns after it "
        f"would be read shifted (the groups of its columns end at field {', '.join(map(str, ends[:-1]))} and "
        f"{ends[-1]})"
    )


def read_headerless(
    path: str | Path,
    config: RobotConfig,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    require_all: bool = True,
    bad_rows: str = DEFAULT_POLICY,
) -> Dataset:
    """Import a headerless CSV described by `config.columns` as a `Dataset` (module docstring)."""
    path = Path(path)
    if not config.columns:
        raise DataError(
            f"{path}: no header line, and the configuration {config.name} has no 'columns' field describing the "
            "columns (docs/formats.md, Robot configuration)"
        )
    raw = _read_bytes(path)
    if not raw.strip():
        raise DataError(f"{path}: the file is empty")
    width = _width(raw)
    if width > len(config.columns):
        raise DataError(
            f"{path}: the rows have {width} fields, but the configuration {config.name} describes "
            f"{len(config.columns)} columns"
        )
    check_group_end(path, config, width)
    table = parse_table(path, raw, 0, width, None, _line, f"the rows have {width}")
    data = table.data
    described = config.columns[:width]
    keep = [i for i, c in enumerate(described) if c.name != SKIP]
    names = [described[i].name for i in keep]
    data = data[:, keep] * np.array([described[i].scale for i in keep])
    try:
        columns = check_columns(names, config, require_all=require_all, source=str(path))
    except DataError as e:
        if width < len(config.columns):
            raise DataError(f"{e} (the file has {width} of the {len(config.columns)} columns described)") from None
        raise
    return table_dataset(path, raw, names, columns, data, config, joint_limits, "headerless csv", _line, table=table,
                         bad_rows=bad_rows)
