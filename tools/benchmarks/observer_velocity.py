"""The observer's q̇ on the UR10e (docs/detection.md#the-monitor): the robot's measured velocity against the causal
estimate from q, offline, on the same fit and the same out-of-sample calibration; collisions and pushes found, and the
per-sample false-positive rate outside the labelled episodes (widened by −0.1 s / +0.5 s, as the monitor test).

    PYTHONPATH=tools .venv/bin/python tools/benchmarks/observer_velocity.py --realdata ../shared/realdata [--work DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from dynid.detect.momentum import friction_band
from dynid.detect.momentum_t2 import BAND_SIGMAS, calibrate_momentum, run_residuals
from dynid.identify.model_file import load_model
from dynid.identify.validation import load_run
from dynid.io.load import load_data

RUNS = ("contact/collision_3link.csv", "contact/ur-20_01_22-push_pose_1.csv")


def measure(model_path: Path, root: Path) -> list[dict]:
    m = load_model(model_path)
    model = m.robot_model
    fitted = [load_run(e.path, model) for e in m.data]
    rows = []
    for measured in (True, False):
        det = calibrate_momentum(model, m.phi, m.base, fitted, m.alpha, m.calibration_min_speed,
                                 tracking=m.supply_tracking, measured=measured, folds=m.folds)
        band = friction_band(model, m.phi, m.base, BAND_SIGMAS)
        for run in RUNS:
            ds = load_data(root / run, model.config, bad_rows="skip")
            res = run_residuals(model, m.phi, ds, det.bandwidth_hz, det.min_speed, band, m.supply_tracking,
                                det.velocity_window_s, measured)
            above = det.t2(res.e) > np.where(res.at_rest.all(axis=1), det.rest_threshold, det.threshold)
            episodes = np.loadtxt(root / run.replace(".csv", ".episodes.csv"), delimiter=",", skiprows=1, ndmin=2)
            inside = np.zeros(res.t.size, dtype=bool)
            found = 0
            for a, b in episodes[:, :2]:
                window = (res.t >= a - 0.1) & (res.t <= b + 0.5)
                inside |= window
                found += bool(above[window].any())
            rows.append({"q̇": "measured" if measured else "estimated", "run": Path(run).stem, "found": found,
                         "episodes": len(episodes), "fpr": float(above[~inside].mean())})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--realdata", type=Path, required=True, help="the shared/realdata folder")
    ap.add_argument("--work", type=Path, default=None, help="where the fit is written (default: a temporary folder)")
    args = ap.parse_args(argv)
    root = args.realdata / "ur10e_mamedov"
    if not root.is_dir():
        ap.error(f"no UR10e data at {root}")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        model = work / "model.json"
        subprocess.run([sys.executable, "-m", "dynid.cli", "fit", "--robot", "ur10e_known_gains", "--urdf",
                        str(root / "ur10e.urdf"), "--data", str(root / "identification/ur-20_02_19_14harm50sec.csv"),
                        "--bad-rows", "skip", "--consistent", "off", "--out", str(model)], check=True,
                       capture_output=True)
        print("| observer q̇ | run | episodes found | FPR outside them |\n|---|---|---|---|")
        for r in measure(model, root):
            print(f"| {r['q̇']} | {r['run']} | {r['found']} of {r['episodes']} | {100 * r['fpr']:.2f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
