"""The `files:` field of a robot configuration: a run that a logger writes as a folder of files, not one table.

Some loggers write a file per signal: the Panda's excitation script writes `exciting_traj_time.txt`,
`exciting_traj_positions.txt`, ... with one value a line (a sample's seven positions on seven lines); PAL's
statistics write `tiago_position.csv`, `tiago_wrist_ft.csv`, ..., each with a header line and its own copy of t.
The field maps each file of the run's folder to its columns, as `columns:` describes one headerless log:

```yaml
files:
  "*_time.txt": [t s]
  "*_positions.txt": [q.panda_joint1 rad, q.panda_joint2 rad, ...]
```

A key is a file name in the run's folder, or a glob that must match exactly one file there (`*_time.txt` reads any
run the script wrote, whatever it named it). A value is a list of "NAME UNIT" entries (config/log_columns.py). One
file at least names t; any other column is named once over all the files. How the files are read and put together:
dynid.io.file_set.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError
from .log_columns import SKIP, LogColumn, parse_columns


@dataclass(frozen=True)
class RunFile:
    pattern: str  # a file name in the run's folder, or a glob matching exactly one
    columns: tuple[LogColumn, ...]  # in file order, "_" for a skipped column


def parse_files(robot: str, value: object) -> tuple[RunFile, ...]:
    """Validate the `files:` mapping; every problem is a `ConfigError` naming the entry."""
    if value is None:
        return ()
    if not isinstance(value, dict) or not value:
        raise ConfigError(f"{robot}: field 'files' must be a mapping of file name (or glob) to its columns, "
                          f"e.g. {{\"*_time.txt\": [\"t s\"]}}; got {value!r}")
    out: list[RunFile] = []
    owner: dict[str, str] = {}  # column name -> the file that names it
    for pattern, columns in value.items():
        if not isinstance(pattern, str) or not pattern.strip() or "/" in pattern or "\\" in pattern \
                or pattern in (".", ".."):
            raise ConfigError(f"{robot}: field 'files' has the key {pattern!r}: a key must be a file name in the "
                              "run's folder (or a glob), without a folder")
        field = f"files.{pattern}"
        parsed = parse_columns(robot, columns, field=field, need_time=False)
        named = [c.name for c in parsed if c.name != SKIP]
        if not named:
            raise ConfigError(f"{robot}: field '{field}' skips every column: leave the file out instead")
        for name in named:
            if name != "t" and name in owner:
                raise ConfigError(f"{robot}: field '{field}' names the column '{name}', which "
                                  f"'files.{owner[name]}' names too")
            owner.setdefault(name, pattern)
        out.append(RunFile(pattern, parsed))
    if "t" not in owner:
        raise ConfigError(f"{robot}: field 'files' must name the time column 't' in one of its files (with its "
                          "unit, e.g. \"t s\")")
    return tuple(out)
