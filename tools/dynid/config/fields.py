"""Typed access to a YAML mapping of a configuration, naming the offending field in every error
(``icub_right_arm: field 'actuation[0].coupling' must be ...``)."""

from __future__ import annotations

import difflib
import math
from typing import Any

import numpy as np

from ..errors import ConfigError


class Fields:
    """Typed access to a YAML mapping that names the offending field in every error."""

    def __init__(self, robot: str, path: str, data: Any) -> None:
        if not isinstance(data, dict):
            raise ConfigError(f"{robot}: {path or 'the file'} must be a mapping, got {type(data).__name__}")
        self.robot, self.path, self.data = robot, path, data

    def _where(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def fail(self, key: str, problem: str) -> ConfigError:
        return ConfigError(f"{self.robot}: field '{self._where(key)}' {problem}")

    def only(self, *allowed: str) -> Fields:
        """Refuse keys this mapping does not define: a typo must not silently drop a setting."""
        for key in self.data:
            if key not in allowed:
                near = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f" (did you mean '{near[0]}'?)" if near else f" (known: {', '.join(allowed)})"
                raise self.fail(str(key), f"is not a known setting{hint}")
        return self

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default: Any = ...) -> Any:
        if key not in self.data:
            if default is ...:
                raise self.fail(key, "is missing")
            return default
        return self.data[key]

    def sub(self, key: str, default: Any = ...) -> Fields:
        return Fields(self.robot, self._where(key), self.raw(key, default))

    def items(self, key: str, default: Any = ...) -> list[Fields]:
        value = self.raw(key, default)
        if not isinstance(value, list):
            raise self.fail(key, "must be a list")
        return [Fields(self.robot, f"{self._where(key)}[{i}]", v) for i, v in enumerate(value)]

    def string(self, key: str, default: Any = ...) -> str:
        value = self.raw(key, default)
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"must be a non-empty string, got {value!r}")
        return value

    def strings(self, key: str, default: Any = ...) -> tuple[str, ...]:
        value = self.raw(key, default)
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            raise self.fail(key, f"must be a list of names, got {value!r}")
        if len(set(value)) != len(value):
            raise self.fail(key, f"lists a name twice: {value!r}")
        return tuple(value)

    def number(self, key: str, default: Any = ..., positive: bool = False) -> float:
        value = self.raw(key, default)
        if value is None and default is None:
            return None  # type: ignore[return-value]
        # float() first: math.isfinite raised OverflowError on an integer too large for a float (1 with 400 zeros).
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(as_float(value)):
            raise self.fail(key, f"must be a finite number, got {shown(value)}")
        if positive and value <= 0:
            raise self.fail(key, f"must be positive, got {value!r}")
        return float(value)

    def matrix(self, key: str, shape: tuple[int, int]) -> np.ndarray:
        value = self.raw(key)
        try:
            m = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError):  # OverflowError: an integer too large for a float
            raise self.fail(key, f"must be a numeric matrix, got {value!r}") from None
        if m.shape != shape or not np.all(np.isfinite(m)):
            raise self.fail(key, f"must be a finite {shape[0]}x{shape[1]} matrix, got shape {m.shape}")
        return m


def as_float(value: int | float) -> float:
    """`value` as a float; inf for an integer too large for one."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def shown(value: Any) -> str:
    """A value for a message: its repr, cut to 60 characters (an integer of 400 digits, a long list)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
