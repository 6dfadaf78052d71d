"""Sources with clocks of their own (YARP ports, ROS 2 topics) put on one uniform time base.

The rule of a YARP folder (dynid.io.yarp) and of a ROS 2 bag read with `ros2.rate` (dynid.io.rosbag), one code for
both so that the two give the same samples from the same messages:

- a source's message out of the longest run of strictly increasing stamps is dropped and counted (`keep_increasing`);
- time 0 is the `origin` the reader chooses (the earliest stamp of any source it sees); the common span is where
  every source read has messages; a silence longer than `max_gap` inside it is refused, naming the source;
- each channel is interpolated linearly onto a grid at `rate` over that span, in seconds from the origin (float64
  Unix stamps keep only ~0.2 µs, so the subtraction comes first).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from ..errors import DataError


@dataclass
class Stream:
    """One source's messages: stamps (s, strictly increasing) and values (M, K) in the project's units."""

    name: str  # the port or topic, for messages
    stamps: np.ndarray
    values: np.ndarray


def keep_increasing(stamps: np.ndarray) -> np.ndarray:
    """The mask of the longest run of messages (or rows) whose stamps strictly increase, in their order; where several
    are as long, the one of the earliest messages. A message re-sent with an old stamp drops itself, and so does one
    stamped ahead of its neighbours, where keeping each stamp that beats every earlier one would drop everything up
    to the next later stamp instead. After a clock that restarts, the run may take from both stretches: the first's
    stamps below the second's end, then the second's above them (the longer stretch where one holds the other's
    span)."""
    t = np.asarray(stamps, dtype=float)
    n = t.size
    if n < 2 or bool(np.all(t[1:] > t[:-1])):
        return np.ones(n, bool)
    # ahead[i]: the length of the longest increasing run that starts at message i, from the right: the longest run
    # of increasing −t ending at i in reversed order (patience sorting, strict, O(n log n)).
    ahead = np.empty(n, np.int64)
    tails: list[float] = []
    for i in range(n - 1, -1, -1):
        x = -t[i]
        k = bisect.bisect_left(tails, x)
        if k == len(tails):
            tails.append(x)
        else:
            tails[k] = x
        ahead[i] = k + 1
    # The earliest messages first: take each one that can still start a run as long as what is left to take.
    keep = np.zeros(n, bool)
    need, last = len(tails), -np.inf
    for i in range(n):
        if need and ahead[i] == need and t[i] > last:
            keep[i] = True
            need -= 1
            last = t[i]
    return keep


def uniform_grid(source: str, streams: list[Stream], origin: float, rate: float, max_gap: float, what: str,
                 setting: str) -> np.ndarray:
    """The grid (s from `origin`) at `rate` over the span every stream covers; a silence inside it is refused.
    `what` names a stream in messages ("port", "topic"), `setting` the configuration's max_gap field."""
    start = max(s.stamps[0] for s in streams)
    stop = min(s.stamps[-1] for s in streams)
    if stop - start < 2.0 / rate:
        raise DataError(f"{source}: the configured {what}s share no common time span (each {what}'s first and last "
                        "stamps)")
    for s in streams:  # a silence inside the common span is refused, not interpolated over
        t = s.stamps
        inside = (t[1:] > start) & (t[:-1] < stop)
        gaps = np.diff(t)[inside]
        if gaps.size and gaps.max() > max_gap:
            i = int(np.flatnonzero(inside)[np.argmax(gaps)])
            raise DataError(f"{source}: {what} {s.name} is silent for {gaps.max():.3f} s from t = {t[i] - origin:.3f} s "
                            f"(the configuration's {setting} is {max_gap:g} s)")
    return (start - origin) + np.arange(int(np.floor((stop - start) * rate)) + 1) / rate


def on_grid(grid: np.ndarray, stream: Stream, origin: float) -> np.ndarray:
    """(len(grid), K): each channel of `stream` interpolated linearly at the grid's times (s from `origin`)."""
    stamps = stream.stamps - origin
    return np.column_stack([np.interp(grid, stamps, stream.values[:, k]) for k in range(stream.values.shape[1])])
