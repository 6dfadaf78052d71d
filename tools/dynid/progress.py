"""Progress for long steps: a live line on a terminal, nothing in CI or when output is piped."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
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


class RunProgress:
    """'<label>: runs 2/5, chunks 37/120 (12.3 s)' on stderr (a terminal only), as tasks finish in any order.

    `runs[i]` is the run task i belongs to, `chunks[i]` how many chunks (time blocks) it covers; a run is done when
    all its tasks are."""

    def __init__(self, label: str, runs: Sequence[int] | None, chunks: Sequence[int] | None,
                 every_s: float = 0.2) -> None:
        self.label, self.every_s = label, every_s
        self.on = enabled()
        self.runs = list(runs) if runs is not None else []
        self.chunks = list(chunks) if chunks is not None else [1] * len(self.runs)
        self.left = {r: self.runs.count(r) for r in set(self.runs)}
        self.runs_done = self.chunks_done = 0
        self.start = self.last = time.monotonic()

    def line(self) -> str:
        return (f"{self.label}: runs {self.runs_done}/{len(self.left)}, chunks {self.chunks_done}/{sum(self.chunks)} "
                f"({time.monotonic() - self.start:.1f} s)")

    def done(self, i: int) -> None:
        if i < len(self.runs):
            self.chunks_done += self.chunks[i]
            self.left[self.runs[i]] -= 1
            self.runs_done += self.left[self.runs[i]] == 0
        now = time.monotonic()
        if self.on and now - self.last >= self.every_s:
            sys.stderr.write("\r" + self.line())
            sys.stderr.flush()
            self.last = now

    def close(self) -> None:
        if self.on:
            sys.stderr.write("\r" + self.line() + " done\n")
