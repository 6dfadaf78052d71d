"""When the iCub leg run is on one foot, measured without any dynamics model: from the stance foot's own F/T sensor.

The run's README gives the right foot lifted at about 13.1 s and put down at about 65.6 s. The stance (left) foot's
vertical force says more: on one foot it carries the robot's weight, steady to a fraction of a newton once the swing's
dynamics are smoothed out (its 0.5 s rolling median: robust σ 0.38 N over 14–58 s), and it unloads, steadily, once the
right foot takes part of the weight. That starts well before the put-down's impact: 23 N are off the stance foot
between 62.42 s and 65.3 s, while the right foot's own sensor moves by about as much. The swing without ground contact
ends there (docs/detection.md#out-of-sample).

    python tests/realdata/leg_support.py [RUN_FOLDER]

(the folder's time origin is dynid's: the earliest first stamp of its logs, dynid.io.yarp.first_stamps_origin)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from dynid.io.yarp import first_stamps_origin

STANCE_PORT = Path("icub") / "left_foot" / "analog:o" / "data.log"  # sequence, stamp, fx fy fz tx ty tz
SMOOTHING_S = 0.5
SIGMAS = 6.0  # as the UR10e's model-free episode labels (shared/realdata/ur10e_mamedov/README.md)
QUIET = (14.0, 58.0)  # s: where the baseline and its spread are taken, single support by any account
DOUBLE_SUPPORT_S = 65.6  # the README's put-down


def stance_load(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(t in dynid's seconds, the stance foot's fz smoothed by a rolling median of SMOOTHING_S)."""
    stamp, fz = np.loadtxt(folder / STANCE_PORT, usecols=(1, 4), unpack=True)
    t = stamp - first_stamps_origin(folder)
    half = max(1, int(round(SMOOTHING_S / np.median(np.diff(t)) / 2)))
    padded = np.pad(fz, half, mode="edge")
    smooth = np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)
    return t, smooth


def put_down_onset(folder: Path) -> tuple[float, float]:
    """(onset s, robust σ N): the last time before the double support that the stance foot's smoothed load was within
    SIGMAS robust standard deviations of its single-support level; from there on it unloads for good."""
    t, load = stance_load(folder)
    quiet = (t >= QUIET[0]) & (t <= QUIET[1])
    level = np.median(load[quiet])
    sigma = 1.4826 * float(np.median(np.abs(load[quiet] - level)))
    within = np.abs(load - level) <= SIGMAS * sigma
    before = np.flatnonzero(within & (t < DOUBLE_SUPPORT_S))
    return float(t[before[-1]]), sigma


if __name__ == "__main__":
    from convert import REALDATA

    run = Path(sys.argv[1]) if len(sys.argv) > 1 else REALDATA / "icub_leg_insitu" / "dumperLeftLegNoIMU"
    onset, sigma = put_down_onset(run)
    print(f"the stance foot unloads for good from {onset:.2f} s (robust σ of its smoothed load {sigma:.2f} N)")
