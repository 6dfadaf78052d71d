"""Contact labels as episodes: a CSV with the header ``t_start,t_end`` and one episode a row, in the data's own
seconds (`dynid detect --episodes`; docs/formats.md). The UR10e contact runs carry theirs beside them."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import DataError

HEADER = ("t_start", "t_end")
MAX_BYTES = 16 * 2**20


def read_episodes(path: str | Path) -> np.ndarray:
    """(n, 2) [t_start, t_end] rows, checked: finite, t_end > t_start, in time order, not overlapping."""
    path = Path(path)
    where = f"episodes file {path}"
    if not path.is_file():
        raise DataError(f"{where} does not exist or is not a file")
    if path.stat().st_size > MAX_BYTES:
        raise DataError(f"{where} is larger than {MAX_BYTES // 2**20} MiB: not an episodes file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise DataError(f"{where} is not UTF-8 text") from None
    if "\x00" in text:
        raise DataError(f"{where} holds NUL bytes: not a CSV")
    rows = [r for r in csv.reader(text.splitlines()) if r and any(c.strip() for c in r)]
    if not rows:
        raise DataError(f"{where} is empty: expected the header 't_start,t_end'")
    header = tuple(c.strip() for c in rows[0])
    if header != HEADER:
        raise DataError(f"{where}: header is {','.join(header)[:80]!r}, expected 't_start,t_end'")
    out = []
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != 2:
            raise DataError(f"{where}, line {n}: {len(row)} fields, expected 2 (t_start,t_end)")
        try:
            a, b = float(row[0]), float(row[1])
        except ValueError:
            raise DataError(f"{where}, line {n}: {','.join(row)[:60]!r} is not two numbers") from None
        if not (np.isfinite(a) and np.isfinite(b)):
            raise DataError(f"{where}, line {n}: times must be finite")
        if b <= a:
            raise DataError(f"{where}, line {n}: t_end {b:g} is not after t_start {a:g}")
        if out and a < out[-1][1]:
            raise DataError(f"{where}, line {n}: the episode starting at {a:g} s overlaps or precedes the one before "
                            f"(ending at {out[-1][1]:g} s); list episodes in time order, without overlaps")
        out.append((a, b))
    return np.array(out, float).reshape(-1, 2)


def episodes_mask(t: np.ndarray, episodes: np.ndarray) -> np.ndarray:
    """(N,) uint8: 1 on the samples inside an episode (t_start ≤ t ≤ t_end)."""
    t = np.asarray(t, float)
    mask = np.zeros(t.size, dtype=np.uint8)
    for a, b in episodes:
        mask[(t >= a) & (t <= b)] = 1
    return mask


def episodes_in_data(t: np.ndarray, episodes: np.ndarray, where: str) -> int:
    """How many `episodes` overlap the data's span; none of several is refused: such labels are in another clock
    (the data's own seconds are expected: `dynid import` prints the span)."""
    t = np.asarray(t, float)
    inside = int(sum(1 for a, b in episodes if b >= t[0] and a <= t[-1]))
    if len(episodes) and not inside:
        raise DataError(f"{where}: the data ({t[0]:g}–{t[-1]:g} s) hold none of its episodes ({episodes[0, 0]:g}–"
                        f"{episodes[-1, 1]:g} s); the episodes are in the data's own seconds")
    return inside


def check_widening(episodes: np.ndarray, widening_s: float, where: str) -> None:
    """A label widened by S on each side lasts more than 2 S: a larger S leaves no episode to measure from."""
    if widening_s > 0 and len(episodes):
        shortest = float(np.min(episodes[:, 1] - episodes[:, 0]))
        if 2 * widening_s >= shortest:
            raise DataError(f"--label-widening {widening_s:g} s: the shortest episode of {where} lasts {shortest:g} s, "
                            "and a label widened by S on each side lasts more than 2 S")
