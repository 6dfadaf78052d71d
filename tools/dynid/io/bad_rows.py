"""Real logs' bad rows: found all at once, refused in one message (the default) or dropped and counted.

A controller's log carries garbage that no reader should take as data: rows written before the clock was set
(t = −0.12 s), uninitialised values (1e150), a last row cut short when the logger stopped mid-write, a row re-sent
with an old stamp. `--bad-rows refuse` (the default) ends the command with one line that says how many rows are
bad, of which kinds, and where the first few are; `--bad-rows skip` drops them and the count travels with the
dataset (`meta["bad_rows"]`) into the command's output, its `--json` and the model file (docs/formats.md).

A row is bad, and counted under the first of these kinds that applies:

==================  ===========================================================================================
``cut_short``       the file's last line, with no line end, with fewer fields than a row has (the logger stopped; a
                    candump log's: no frame line); in a folder of files, the samples a file lacks where it ends
                    before the others, or a partial last sample of a one-value-a-line file (dynid.io.file_set); in a
                    YARP folder, the other ports' messages beyond a port that starts or ends more than `max_skew`
                    after or before them (dynid.io.yarp)
``empty``           a blank line between rows
``column_count``    another number of fields than a row has
``not_a_number``    a cell that is not a decimal number
``not_a_frame``     a candump log's line that is no frame line (dynid.io.candump)
``non_finite``      a nan or an inf
``out_of_range``    a measured value beyond ±`MAX_ABS_VALUE` (1e6: no sensor of an arm reads a million N, Nm, A,
                    rad/s), or a time beyond ±`MAX_ABS_TIME`; positions, inputs, torques, wrenches and derivatives
                    are checked, extra columns (any unit) and the contact label are not
``time_negative``   t < 0 (the data's own seconds start at or after 0: a negative stamp is a clock not yet set)
``time_not_         t out of the longest run of good rows whose t strictly increases (where several are as long,
increasing``        the earliest rows'): a stale or re-sent row drops itself only, and so does a row stamped ahead
                    of its neighbours (dynid.io.align.keep_increasing)
==================  ===========================================================================================
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DataError
from .align import keep_increasing

POLICIES: tuple[str, ...] = ("refuse", "skip")
DEFAULT_POLICY = "refuse"
# Beyond these, a value is garbage (1e150 in a UR10e log's first rows), never a reading: see the module docstring.
MAX_ABS_VALUE = 1e6
MAX_ABS_TIME = 1e19  # s: a Unix time in nanoseconds (1.7e18) is still a time, only in the wrong unit
SHOW_LINES = 5  # the first few bad rows named in a refusal

KINDS: dict[str, str] = {  # kind -> how a refusal counts it ("9 with a value beyond ±1e+06")
    "cut_short": "cut short",
    "empty": "empty",
    "column_count": "with a wrong number of fields",
    "not_a_number": "with a cell that is not a number",
    "not_a_frame": "not a candump -L frame",
    "non_finite": "with a non-finite value",
    "out_of_range": f"with a value beyond ±{MAX_ABS_VALUE:g}",
    "time_negative": "with a negative time",
    "time_not_increasing": "whose time is out of order",
}
# Column kinds (dynid.io.csv_format.Column.kind) whose values are measurements checked against MAX_ABS_VALUE.
MEASURED_KINDS = frozenset({"q", "dq", "ddq", "pwm", "current", "tau", "ft"})


@dataclass(frozen=True)
class Malformed:
    """A line that did not parse into a row: its 0-based row number (as the reader numbers rows) and why."""

    row: int
    kind: str  # cut_short, empty, column_count, not_a_number or not_a_frame
    detail: str  # the reader's own sentence for it, e.g. "row 3 (line 4) has 2 fields, but the header has 4 columns"


@dataclass(frozen=True)
class BadRows:
    """The bad rows of one run: their row numbers (0-based, as the reader numbers them) and kinds, in file order."""

    rows: np.ndarray  # (B,) int, ascending
    kinds: tuple[str, ...]  # (B,) the first kind that applies to each
    first: str  # the first bad row's problem in the reader's words
    total: int  # rows in the file, good and bad

    @property
    def count(self) -> int:
        return int(self.rows.size)

    def counts(self) -> dict[str, int]:
        """kind -> rows, in the order of `KINDS`, only the kinds present."""
        return {k: n for k in KINDS if (n := self.kinds.count(k))}

    def as_dict(self, policy: str, label: Callable[[int], str]) -> dict[str, Any]:
        """What `meta["bad_rows"]`, `--json` and the model file record (docs/formats.md)."""
        return {"policy": policy, "count": self.count, "rows_read": self.total, "kinds": self.counts(),
                "first": [label(int(r)) for r in self.rows[:SHOW_LINES]]}

    def refusal(self, source: str, label: Callable[[int], str]) -> DataError:
        """The one line of `--bad-rows refuse`."""
        where = f"{source}: " if source else ""
        if self.count == 1:
            return DataError(f"{where}{self.first} (1 bad row of {self.total}; --bad-rows skip drops bad rows and "
                             "reports their count)")
        kinds = ", ".join(f"{n} {KINDS[k]}" for k, n in self.counts().items())
        shown = join_labels([label(int(r)) for r in self.rows[:SHOW_LINES]]) + (", ..." if self.count > SHOW_LINES else "")
        every = " (every row)" if self.count == self.total else ""
        return DataError(f"{where}{self.count} bad rows of {self.total}{every}: {kinds}; at {shown}; the first: "
                         f"{self.first} (--bad-rows skip drops them and reports the count)")


def join_labels(labels: Sequence[str]) -> str:
    """Rows named one after another, a file's name said once: "a.log line 3, line 4, b.log line 9"."""
    shown, before = [], None
    for label in labels:
        prefix, sep, rest = label.rpartition(" line ")
        shown.append(f"line {rest}" if sep and prefix == before else label)
        before = prefix if sep else None
    return ", ".join(shown)


def find_bad_rows(data: np.ndarray, rows: np.ndarray, names: Sequence[str], kinds: Sequence[str], total: int,
                  malformed: Sequence[Malformed] = (), label: Callable[[int], str] = lambda i: f"row {i + 1}",
                  time_column: int = 0) -> tuple[BadRows | None, np.ndarray]:
    """The bad rows of a parsed table, and the mask of the rows of `data` to keep.

    `data` (N, columns) holds the rows that parsed, `rows` (N,) their 0-based row numbers in the file, `names` and
    `kinds` each column's name and kind, `malformed` the lines that did not parse, `total` the rows in the file.
    `label` names a row in messages ("row 3 (line 4)").
    """
    n = data.shape[0]
    kind_of = np.full(n, "", dtype=object)
    detail: dict[int, str] = {}  # row number -> what is wrong, for the first bad row's sentence

    def mark(mask: np.ndarray, kind: str, say: Callable[[int], str]) -> None:
        fresh = np.flatnonzero(mask & (kind_of == ""))
        if fresh.size:
            kind_of[fresh] = kind
            detail.setdefault(int(rows[fresh[0]]), say(int(fresh[0])))

    finite = np.isfinite(data)
    if not finite.all():
        bad = ~finite.all(axis=1)

        def say_finite(i: int) -> str:
            c = int(np.argmax(~finite[i]))
            return f"column {names[c]} is {data[i, c]} at {label(int(rows[i]))}: every value must be a finite number"

        mark(bad, "non_finite", say_finite)
    measured = [c for c, k in enumerate(kinds) if k in MEASURED_KINDS]
    with np.errstate(invalid="ignore"):
        big = np.zeros(n, bool) if not measured else (np.abs(data[:, measured]) > MAX_ABS_VALUE).any(axis=1)
        t = data[:, time_column]
        big |= np.abs(t) > MAX_ABS_TIME

    def say_range(i: int) -> str:
        if abs(t[i]) > MAX_ABS_TIME:
            return f"t is {t[i]:g} at {label(int(rows[i]))}: beyond ±{MAX_ABS_TIME:g} s, not a time"
        c = measured[int(np.argmax(np.abs(data[i, measured]) > MAX_ABS_VALUE))]
        return (f"{names[c]} is {data[i, c]:g} at {label(int(rows[i]))}: beyond ±{MAX_ABS_VALUE:g}, which no sensor "
                "of an arm reads (N, Nm, A, rad/s, rad/s²): a wrong unit or a corrupt value")

    mark(big, "out_of_range", say_range)
    with np.errstate(invalid="ignore"):
        mark(t < 0, "time_negative", lambda i: f"t is {t[i]!r} s at {label(int(rows[i]))}: a negative time")
    good = np.flatnonzero(kind_of == "")
    if good.size > 1:
        tg = t[good]
        kept = keep_increasing(tg)
        stale = np.zeros(n, bool)
        stale[good[~kept]] = True
        if stale.any():
            # the kept rows' times just before and just after each dropped one (−inf, +inf at the ends)
            kept_t = tg[kept]
            at = np.searchsorted(np.flatnonzero(kept), np.arange(tg.size))  # kept rows before each good row
            before, after = np.full(n, -np.inf), np.full(n, np.inf)
            before[good] = np.where(at > 0, kept_t[np.maximum(at - 1, 0)], -np.inf)
            after[good] = np.where(at < kept_t.size, kept_t[np.minimum(at, kept_t.size - 1)], np.inf)

            def say_order(i: int) -> str:
                where = label(int(rows[i]))
                if t[i] <= before[i]:
                    return f"t is not strictly increasing at {where}: {float(t[i])!r} s follows {float(before[i])!r} s"
                return f"t is out of order at {where}: {float(t[i])!r} s, ahead of the next row kept ({float(after[i])!r} s)"

            mark(stale, "time_not_increasing", say_order)
    bad_in_table = kind_of != ""
    all_rows = np.concatenate([rows[bad_in_table], np.array([m.row for m in malformed], dtype=np.int64)])
    if not all_rows.size:
        return None, np.ones(n, bool)
    all_kinds = [str(k) for k in kind_of[bad_in_table]] + [m.kind for m in malformed]
    for m in malformed:
        detail.setdefault(m.row, m.detail)
    order = np.argsort(all_rows, kind="stable")
    rows_sorted = all_rows[order].astype(np.int64)
    found = BadRows(rows_sorted, tuple(all_kinds[i] for i in order), detail[int(rows_sorted[0])], total)
    return found, ~bad_in_table


def apply_policy(found: BadRows | None, keep: np.ndarray, policy: str, source: str,
                 label: Callable[[int], str]) -> dict[str, Any] | None:
    """Refuse (`refuse`) or accept the drop (`skip`); what `meta["bad_rows"]` records, None when no row is bad."""
    if policy not in POLICIES:
        raise ValueError(f"bad-rows policy {policy!r} is not one of {POLICIES}")
    if found is None:
        return None
    if policy == "refuse" or not keep.any():
        raise found.refusal(source, label)
    return found.as_dict(policy, label)
