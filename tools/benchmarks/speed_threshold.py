"""A speed-dependent Λ for the momentum detector, measured on the real runs whose targets it might reach (issue 20).

    PYTHONPATH=tools OMP_NUM_THREADS=1 python tools/benchmarks/speed_threshold.py --realdata ../shared/realdata \
        --work /tmp/detrep

The momentum residual's variance on a moving arm is mostly model error, which grows with speed, so a constant Λ is
too wide at rest and too narrow at speed. Here each channel's variance is a nonnegative least-squares fit of e² on
the calibration runs against [1, s] (the rows at rest left out, as dynid's calibration does), s one of:
- none: Λ constant (dynid's detector, the first row of each run);
- ‖q̇‖²: the squared norm of the joint velocity;
- q̇ᵢ²: every joint's squared velocity (one column each).
T² = Σ e²/Λ(s) and T²_α its α-quantile on the same calibration runs, so α keeps its promise there. The runs,
models, labels and calibration are detection_report.py's (the models are fitted there on first use, into --work).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import stats
from scipy.optimize import nnls

from dynid.detect.momentum import DEFAULT_BANDWIDTH_HZ
from dynid.detect.momentum_t2 import (SETTLE_TIME_CONSTANTS, calibration_runs, friction_band, run_residuals)
from dynid.detect.t2 import score_with_delays
from dynid.identify.validation import evaluate
from dynid.io.episodes import episodes_mask, read_episodes

FEATURES = {
    "none": lambda dq: np.ones((dq.shape[0], 1)),
    "‖q̇‖²": lambda dq: np.column_stack([np.ones(dq.shape[0]), np.sum(dq**2, axis=1)]),
    "q̇ᵢ²": lambda dq: np.column_stack([np.ones(dq.shape[0]), dq**2]),
}


def residuals(model_path: Path, data: Path, labels: Path, calibration: list[str] | None, window) -> tuple:
    ev = evaluate(str(model_path), str(data))
    ds = replace(ev.dataset, contact=episodes_mask(ev.dataset.t, read_episodes(labels)))
    idm = ev.identified
    model, phi = idm.robot_model, idm.phi
    runs, _ = calibration_runs(idm, calibration, window)
    band = friction_band(model, phi, idm.base, 1.0)
    settle = SETTLE_TIME_CONSTANTS / (2 * np.pi * DEFAULT_BANDWIDTH_HZ)

    def run(d):
        return run_residuals(model, phi, d, DEFAULT_BANDWIDTH_HZ, idm.min_speed, band, idm.supply_tracking)

    cal = [run(r) for r in runs]
    keep = [c.t - c.t[0] >= settle for c in cal]
    e = np.vstack([c.e[k] for c, k in zip(cal, keep)])
    dq = np.vstack([c.dq[k] for c, k in zip(cal, keep)])
    rest = np.vstack([c.at_rest[k] for c, k in zip(cal, keep)])
    return (e, dq, rest), run(ds), np.asarray(ds.contact) != 0


def score(calibrated: tuple, res, labels: np.ndarray, feature, alpha: float = 0.99) -> dict:
    e, dq, rest = calibrated
    X = feature(dq)
    coef = []
    for j in range(e.shape[1]):
        moving = ~rest[:, j]
        c = nnls(X[moving], e[moving, j] ** 2)[0] if moving.sum() > X.shape[1] else np.r_[np.mean(e[:, j] ** 2),
                                                                                            np.zeros(X.shape[1] - 1)]
        c[0] = max(c[0], 1e-9 * max(np.mean(e[:, j] ** 2), 1e-300))  # never a zero variance at rest
        coef.append(c)
    coef = np.array(coef)
    threshold = float(np.quantile(np.sum(e**2 / (X @ coef.T), axis=1), alpha))
    rest_threshold = float(stats.chi2.ppf(alpha, e.shape[1]))
    t2 = np.sum(res.e**2 / (feature(res.dq) @ coef.T), axis=1)
    stat = t2 / np.where(res.at_rest.all(axis=1), rest_threshold, threshold)  # a contact above 1, as dynid's
    scored = score_with_delays(res.t, stat, 1.0, labels.astype(np.uint8))
    d = [1e3 * x for x in scored["onset_delays_s"] if x is not None]
    return {"fpr": scored["fpr"], "tpr": scored["tpr"], "found": len(d), "episodes": len(scored["onset_delays_s"]),
            "median": float(np.median(d)), "max": float(max(d))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--realdata", type=Path, required=True)
    ap.add_argument("--work", type=Path, required=True, help="detection_report.py's --work (its models, its labels)")
    a = ap.parse_args()
    ur, leg = a.realdata / "ur10e_mamedov", a.realdata / "icub_leg_insitu" / "dumperLeftLegNoIMU"
    labels = a.work / "icub_leg.episodes.csv"
    labels.write_text("t_start,t_end\n0,13.1\n65.6,1000\n")  # detection_report.py's
    runs = [("ur10e_collision_3link", a.work / "ur.json", ur / "contact" / "collision_3link.csv",
             ur / "contact" / "collision_3link.episodes.csv", None, (None, None)),
            ("ur10e_push_pose_1", a.work / "ur.json", ur / "contact" / "ur-20_01_22-push_pose_1.csv",
             ur / "contact" / "ur-20_01_22-push_pose_1.episodes.csv", None, (None, None)),
            ("icub_leg", a.work / "leg.json", leg, labels, [str(leg)], (14.0, 65.0))]
    print("| run | Λ against | episodes found | onset delay median / max, ms | FPR | TPR |")
    print("|---|---|---|---|---|---|")
    for name, model, data, episodes, calibration, window in runs:
        if not model.is_file():
            raise SystemExit(f"{model}: run tools/benchmarks/detection_report.py with --work {a.work} first")
        calibrated, res, lab = residuals(model, data, episodes, calibration, window)
        for feature, f in FEATURES.items():
            s = score(calibrated, res, lab, f)
            print(f"| {name} | {feature} | {s['found']}/{s['episodes']} | {s['median']:.0f} / {s['max']:.0f} | "
                  f"{100 * s['fpr']:.2f} % | {100 * s['tpr']:.1f} % |")


if __name__ == "__main__":
    main()
