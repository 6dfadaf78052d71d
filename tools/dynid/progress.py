"""Progress for long steps: a live line on a terminal, nothing in CI or when output is piped."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")


def enabled() -> bool:
    return sys.stderr.isatty() and not os.environ.get("CI") and not os.environ.get("DYNID_NO_PROGRESS")


def track(items: Iterable[T], total: int, label: str, every_s: float = 0.2) -> Iterator[T]:
    """Yield `items`, redrawing '<label> 42 % (1.3 s)' on stderr at most every `every_s` seconds."""
    if not enabled() or total <= 0:
        yield from items
        return
    start = last = time.monotonic()
    for i, item in enumerate(items):
        now = time.monotonic()
        if now - last >= every_s:
            sys.stderr.write(f"\r{label} {100 * i // total:3d} % ({now - start:.1f} s)")
            sys.stderr.flush()
            last = now
        yield item
    sys.stderr.write(f"\r{label} done ({time.monotonic() - start:.1f} s)\n")
