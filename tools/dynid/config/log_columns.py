"""The `columns:` field of a robot configuration: a headerless log as the robot's controller writes it.

Each entry is ``"NAME UNIT"``: NAME is the column's name in docs/design.md §4 terms (``t``, ``q.<joint>``,
``dq.<joint>``, ``ddq.<joint>``, ``current.<motor>``, ``pwm.<motor>``, ``tau.<joint>``,
``ft.<sensor>.<fx..tz>``, ``contact``, or any other name, kept verbatim as an extra column; ``_`` skips the
column) and UNIT the unit the file uses, converted to the project's units on reading (degrees to radians,
milliseconds to seconds, ...). An extra column's unit is only recorded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import ConfigError

_DEG = math.pi / 180.0
# Per column kind: accepted unit -> factor to the project's unit (docs/design.md §4).
UNITS: dict[str, dict[str, float]] = {
    "t": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9},
    "q": {"rad": 1.0, "deg": _DEG, "m": 1.0, "mm": 1e-3},
    "dq": {"rad/s": 1.0, "deg/s": _DEG, "m/s": 1.0, "mm/s": 1e-3},
    "ddq": {"rad/s^2": 1.0, "deg/s^2": _DEG, "m/s^2": 1.0, "mm/s^2": 1e-3},
    "current": {"A": 1.0, "mA": 1e-3},
    "pwm": {"duty": 1.0, "percent": 1e-2},
    "tau": {"Nm": 1.0, "Nmm": 1e-3},
    "ft_force": {"N": 1.0},
    "ft_torque": {"Nm": 1.0, "Nmm": 1e-3},
    "contact": {"1": 1.0},
}
SKIP = "_"


@dataclass(frozen=True)
class LogColumn:
    name: str  # a column name of docs/design.md §4, or "_" (skipped)
    unit: str
    scale: float  # value in the file × scale = value in the project's unit


def _kind(name: str) -> str | None:
    """The unit table's key for a column name, or None for an extra (or skipped) column."""
    if name in ("t", "contact"):
        return name
    prefix, dot, rest = name.partition(".")
    if not dot or prefix not in ("q", "dq", "ddq", "current", "pwm", "tau", "ft"):
        return None
    if prefix == "ft":
        return "ft_torque" if rest.endswith((".tx", ".ty", ".tz")) else "ft_force"
    return prefix


def parse_columns(robot: str, value: object, field: str = "columns", need_time: bool = True
                  ) -> tuple[LogColumn, ...]:
    """Validate a `columns:` list (`field` names it in messages; `need_time` False: it may leave out t, as one file
    of a `files:` run may); every problem is a `ConfigError` naming the entry."""
    if value is None:
        return ()
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{robot}: field '{field}' must be a list of \"NAME UNIT\" entries, got {value!r}")
    out: list[LogColumn] = []
    seen: set[str] = set()
    for i, entry in enumerate(value):
        where = f"{robot}: field '{field}[{i}]'"
        if not isinstance(entry, str) or not entry.split():
            raise ConfigError(f"{where} must be a string \"NAME UNIT\" (e.g. \"q.elbow rad\"), got {entry!r}")
        parts = entry.split()
        if len(parts) > 2:
            raise ConfigError(f"{where} must be \"NAME UNIT\", got {entry!r}")
        name, unit = parts[0], (parts[1] if len(parts) == 2 else "")
        if name != SKIP and name in seen:
            raise ConfigError(f"{where} names the column '{name}' a second time")
        seen.add(name)
        kind = _kind(name)
        if kind is None:
            out.append(LogColumn(name, unit, 1.0))
            continue
        units = UNITS[kind]
        if not unit and kind == "contact":
            unit = "1"
        if unit not in units:
            raise ConfigError(f"{where}: '{name}' must give its unit, one of {', '.join(units)}; got '{unit or 'none'}'")
        out.append(LogColumn(name, unit, units[unit]))
    if need_time and "t" not in seen:
        raise ConfigError(f"{robot}: field '{field}' must name the time column 't' (with its unit, e.g. \"t s\")")
    return tuple(out)
