"""The real-time monitor's compile-time capacity and its coefficient file's format version, read from the one place
that sets them.

`rt_monitor/include/rt_monitor/capacity.hpp` holds `constexpr int kName = N;` lines; the core, the loader and the
assembler size their storage from them, and `dynid export` checks a robot against them before it writes anything
(a file the monitor would refuse at start-up is never written). No copy of the numbers lives here: they are parsed
from the header, and a test compares them with what the compiled monitor reports (`rt_eval --capacity`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

HEADER = Path(__file__).resolve().parents[3] / "rt_monitor" / "include" / "rt_monitor" / "capacity.hpp"
_LINE = re.compile(r"^\s*constexpr\s+int\s+kMax(\w+)\s*=\s*(\d+)\s*;", re.MULTILINE)
_VERSION = re.compile(r"^\s*constexpr\s+int\s+kFileVersion\s*=\s*(\d+)\s*;", re.MULTILINE)


@dataclass(frozen=True)
class Capacity:
    joints: int
    sensors: int
    bodies: int
    motors: int
    outputs: int
    window: int
    effects: int
    buses: int
    frames: int
    signals: int
    skins: int


def _snake(name: str) -> str:
    return re.sub(r"(?<!^)([A-Z])", r"_\1", name).lower()


@lru_cache(maxsize=1)
def capacity(header: Path = HEADER) -> Capacity:
    """The capacities of `header` (the repository's by default)."""
    try:
        text = header.read_text()
    except OSError as e:
        raise RuntimeError(f"the monitor's capacity header is missing ({header}: {e.strerror}): dynid runs from its "
                           "source tree (pip install -e tools)") from None
    values = {_snake(name): int(n) for name, n in _LINE.findall(text)}
    try:
        return Capacity(**{k: values[k] for k in Capacity.__dataclass_fields__})
    except KeyError as e:
        raise RuntimeError(f"{header} does not define kMax{e.args[0].title().replace('_', '')}") from None


@lru_cache(maxsize=1)
def file_version(header: Path = HEADER) -> int:
    """The coefficient file's format version the monitor reads (`kFileVersion` of `header`)."""
    try:
        found = _VERSION.search(header.read_text())
    except OSError as e:
        raise RuntimeError(f"the monitor's capacity header is missing ({header}: {e.strerror})") from None
    if found is None:
        raise RuntimeError(f"{header} does not define kFileVersion")
    return int(found.group(1))
