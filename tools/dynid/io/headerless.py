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
from .csv_format import _NUMBER, _read_bytes, check_columns, table_dataset
from .dataset import Dataset

_FIRST_CELL = re.compile(rb"^\s*[+-]?(\d|\.\d)")


def looks_headerless(head: bytes) -> bool:
    """True when the first line starts with a number: data, not a header."""
    return bool(_FIRST_CELL.match(head.lstrip(b"\xef\xbb\xbf")))


def _line(i: int) -> str:
    return f"line {i + 1}"


def _diagnose(raw: bytes, width: int, path: Path, fallback: str) -> DataError:
    lines = raw.decode("utf-8-sig", errors="replace").replace("\r\n", "\n").rstrip("\n").split("\n")
    for k, line in enumerate(lines):
        if not line.strip():
            return DataError(f"{path}: line {k + 1} is empty: blank lines between data rows are not allowed")
        cells = line.split(",")
        if len(cells) != width:
            return DataError(f"{path}: line {k + 1} has {len(cells)} fields, but line 1 has {width}")
        for c, cell in enumerate(cells):
            if not _NUMBER.fullmatch(cell):
                return DataError(f"{path}: line {k + 1}, column {c + 1}: {cell.strip()[:40]!r} is not a number")
    return DataError(f"{path}: cannot read the data rows: {fallback}")


def read_headerless(
    path: str | Path,
    config: RobotConfig,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    require_all: bool = True,
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
    first = raw.split(b"\n", 1)[0]
    width = first.count(b",") + 1
    if width > len(config.columns):
        raise DataError(
            f"{path}: line 1 has {width} fields, but the configuration {config.name} describes "
            f"{len(config.columns)} columns"
        )
    try:
        data = np.loadtxt(path, dtype=float, delimiter=",", comments=None, ndmin=2, encoding="utf-8-sig")
    except (ValueError, UnicodeDecodeError) as e:
        raise _diagnose(raw, width, path, str(e).splitlines()[0] if str(e) else type(e).__name__) from None
    if data.shape[1] != width or data.shape[0] != raw.rstrip().count(b"\n") + 1:
        raise _diagnose(raw, width, path, f"expected rows of {width} values, got {data.shape}")
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
    return table_dataset(path, raw, names, columns, data, config, joint_limits, "headerless csv", _line)
