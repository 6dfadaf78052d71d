"""Convert the real-robot recordings of shared/realdata to the project CSV (docs/design.md §4).

Usage::

    python tests/realdata/convert.py panda OUT.csv [--source DIR]
    python tests/realdata/convert.py tiago OUT.csv [--source DIR] [--run dynamic]

Both converters keep every recorded value (what is not a docs/design.md §4 signal goes to an extra column) and say
what they changed: a sample whose time stamp does not come after the previous one is dropped, counted and
reported, never silently (the README beside this file lists what happened on the shipped runs).
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynid.io.csv_format import write_csv
from dynid.io.dataset import Dataset

# CI clones the repository with shared/ beside it: <parent>/main/tests/realdata/convert.py, <parent>/shared.
# DYNID_REALDATA=DIR points elsewhere (a git worktree that does not sit beside shared/).
REALDATA = Path(os.environ.get("DYNID_REALDATA") or Path(__file__).resolve().parents[2].parent / "shared" / "realdata")
# The URDFs of the bundled configurations that the user supplies (`--urdf`): they live beside the runs.
TIAGO_URDF = REALDATA / "tiago_wrist_ft" / "urdf" / "tiago_48_hey5.urdf"
UR10E_URDF = REALDATA / "ur10e_mamedov" / "ur10e.urdf"

PANDA_JOINTS: tuple[str, ...] = tuple(f"panda_joint{i}" for i in range(1, 8))  # as in example-robot-data's URDF
TIAGO_JOINTS: tuple[str, ...] = ("torso_lift_joint", *(f"arm_{i}_joint" for i in range(1, 8)))


@dataclass
class Conversion:
    """A converted run and the account of what the converter did to it."""

    dataset: Dataset
    rows_read: int  # samples in the raw files
    dropped: np.ndarray  # 0-based raw indices of the samples dropped
    notes: list[str] = field(default_factory=list)  # one line per decision, printed by main()

    def write(self, path: str | Path) -> None:
        write_csv(self.dataset, path)


def keep_increasing(t: np.ndarray) -> tuple[np.ndarray, str]:
    """Mask of the samples whose stamp comes strictly after every earlier one, and a note saying what it did.

    A stamp that repeats or goes back is a logging artefact (the sample was re-sent, or the clock stepped);
    keeping it would break the strictly increasing time of docs/design.md §4, and reordering would invent an order.
    """
    keep = np.ones(t.shape, dtype=bool)
    if t.size > 1:
        keep[1:] = t[1:] > np.maximum.accumulate(t)[:-1]
    steps = np.diff(t[keep])
    span = ""
    if steps.size:
        median = np.median(steps)
        gaps = int((steps > 3 * median).sum())
        span = (
            f"steps {steps.min() * 1e3:.3g}..{steps.max() * 1e3:.3g} ms, median {median * 1e3:.4g} ms, "
            f"{gaps} gaps over 3x the median"
        )
    n_bad = int((~keep).sum())
    if n_bad == 0:
        return keep, f"t is strictly increasing ({span}): nothing dropped"
    first = np.flatnonzero(~keep)[:5]
    shown = ", ".join(f"{i} (t={float(t[i])!r})" for i in first) + (", ..." if n_bad > first.size else "")
    return (
        keep,
        f"dropped {n_bad} samples whose stamp does not follow the previous one, "
        f"at raw samples (0-based) {shown}; kept: {span}",
    )


def _column(path: Path) -> np.ndarray:
    return np.loadtxt(path, dtype=float, ndmin=1)


def convert_panda(source: str | Path = REALDATA / "panda_gaz2019") -> Conversion:
    """The Panda excitation run (Gaz et al. 2019): q, dq and measured joint torques of 7 joints."""
    log = Path(source) / "rbt_log"
    t = _column(log / "exciting_traj_time.txt")
    signals = {}
    for name in ("positions", "velocity", "torques"):
        path = log / f"exciting_traj_{name}.txt"
        flat = _column(path)
        if flat.size != 7 * t.size:  # 7 values a sample, flattened row by row
            raise ValueError(f"{path}: {flat.size} values, expected 7 per time stamp ({7 * t.size})")
        signals[name] = flat.reshape(-1, 7)
    keep, note = keep_increasing(t)
    q, dq, tau = (signals[k][keep] for k in ("positions", "velocity", "torques"))
    dataset = Dataset(
        t=t[keep],
        joints=PANDA_JOINTS,
        q=q,
        dq=dq,
        tau={j: tau[:, i].copy() for i, j in enumerate(PANDA_JOINTS)},
        meta={
            "robot": "panda",
            "source": "shared/realdata/panda_gaz2019/rbt_log "
            "(marcocognetti/FrankaEmikaPandaDynModel @ 24d85ce, GPL-3.0)",
            "notes": [note, "dq is the robot's recorded joint velocity"],
        },
    )
    return Conversion(dataset, int(t.size), np.flatnonzero(~keep), [note])


def _pal_csv(path: Path, suffix: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A PAL statistics CSV: `t` then `- <joint><suffix>` columns, as (t, joint -> values)."""
    with open(path, encoding="utf-8") as f:
        header = [h.strip() for h in f.readline().split(",")]
    data = np.loadtxt(path, dtype=float, delimiter=",", skiprows=1, ndmin=2)
    if header[0] != "t":
        raise ValueError(f"{path}: the first column is '{header[0]}', expected t")
    names = [h.removeprefix("- ").removesuffix(suffix) for h in header[1:]]
    return data[:, 0], {n: data[:, i + 1] for i, n in enumerate(names)}


def convert_tiago(source: str | Path = REALDATA / "tiago_wrist_ft", run: str = "dynamic") -> Conversion:
    """The TIAGo run: torso + 7 arm joints (q; PAL's lagging velocity as an extra), the wrist F/T sensor, raw efforts."""
    folder = Path(source) / run
    t, q = _pal_csv(folder / "tiago_position.csv", "_position")
    columns = {"velocity": _pal_csv(folder / "tiago_velocity.csv", "_velocity")}
    columns["effort"] = _pal_csv(folder / "tiago_effort.csv", "_effort")
    t_ft, ft = _pal_csv(folder / "tiago_wrist_ft.csv", "")
    for kind, (t_other, values) in {**columns, "position": (t, q)}.items():
        # One row is one PAL statistics message in every file: the stamps must be the same bits.
        if not np.array_equal(t_other, t):
            raise ValueError(f"{folder}: the time stamps of the {kind} file differ from the position file's")
        if set(values) != set(TIAGO_JOINTS):
            raise ValueError(f"{folder}: the {kind} file has joints {sorted(values)}, expected {list(TIAGO_JOINTS)}")
    if not np.array_equal(t_ft, t):
        raise ValueError(f"{folder}: the time stamps of tiago_wrist_ft.csv differ from the position file's")
    ft_names = [f"wrist_ft_{kind}_{axis}" for kind in ("force", "torque") for axis in "XYZ"]  # FT_CHANNELS order
    if sorted(ft) != sorted(ft_names):
        raise ValueError(f"{folder}: tiago_wrist_ft.csv has columns {sorted(ft)}, expected {ft_names}")
    wrench = np.column_stack([ft[n] for n in ft_names])

    # PAL's t is a difference of float64 Unix seconds: multiples of 2^-22 s (0.24 µs), none a whole nanosecond. ROS
    # time is whole nanoseconds, so t is rounded to the nanosecond (a change under 0.12 µs): the run is then the same
    # float64 samples as a CSV and as a ROS 2 bag (to_bag.py), which the bag tests assert bit for bit.
    t = np.round(t * 1e9) / 1e9
    keep, note = keep_increasing(t)
    velocity, effort = columns["velocity"][1], columns["effort"][1]
    dataset = Dataset(
        t=t[keep],
        joints=TIAGO_JOINTS,
        q=np.column_stack([q[j] for j in TIAGO_JOINTS])[keep],
        ft={"wrist_ft": wrench[keep]},
        # PAL's velocity lags q (a first-order filter), so it is not offered as dq: the tool differentiates q
        # without lag instead. Raw efforts are controller units, not Nm. Both are kept, so nothing is lost,
        # under names that pretend to be nothing else.
        extra={
            **{f"velocity_filtered.{j}": velocity[j][keep] for j in TIAGO_JOINTS},
            **{f"effort.{j}": effort[j][keep] for j in TIAGO_JOINTS},
        },
        meta={
            "robot": "tiago_wrist_ft",
            "source": f"shared/realdata/tiago_wrist_ft/{run} (thanhndv212/figaroh-examples, Apache-2.0, "
            "Thanh Nguyen / CNRS / Toward)",
            "notes": [
                note,
                "velocity_filtered.<joint> is PAL's v[n] = 0.95 v[n-1] + 0.05 dq/dt: it lags q, so it is not dq",
                "effort.<joint> are raw controller units, not torques",
                "t is rounded to the nanosecond (PAL's float seconds step by 2^-22 s)",
                "the F/T sensor is not tared (Fz about -69 N at rest)",
            ],
        },
    )
    return Conversion(dataset, int(t.size), np.flatnonzero(~keep), [note, *dataset.meta["notes"][1:]])


CONVERTERS = {"panda": convert_panda, "tiago": convert_tiago}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("robot", choices=sorted(CONVERTERS))
    parser.add_argument("out", type=Path, help="the CSV to write")
    parser.add_argument("--source", type=Path, help="the raw run's folder (default: shared/realdata/<robot's folder>)")
    parser.add_argument("--run", default="dynamic", help="TIAGo only: the run's subfolder")
    args = parser.parse_args(argv)
    options = {"source": args.source} if args.source else {}
    if args.robot == "tiago":
        options["run"] = args.run
    conversion = CONVERTERS[args.robot](**options)
    conversion.write(args.out)
    ds = conversion.dataset
    print(
        f"{args.robot}: {conversion.rows_read} samples read, {conversion.dropped.size} dropped, "
        f"{ds.n_samples} written to {args.out}"
    )
    for line in conversion.notes:
        print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
