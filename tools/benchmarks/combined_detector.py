"""No blind side (issue 30, item 6): ways to combine the momentum and the acceleration residuals, measured.

On the simulated arm: per-sample statistics of both detectors on contact-free cross-validated residuals of the fit's
own run (the first 150 s, as the momentum detector calibrates: each time block through the Φ fitted without it),
paired sample by sample; each rule's threshold set there at α; then TPR by side of the F/T sensor and FPR on the
contact run (outside its episodes) and on held-out contact-free runs. Reproduce (docs/detection.md#no-blind-side):

    PYTHONPATH=tools OMP_NUM_THREADS=1 python tools/benchmarks/combined_detector.py --model out/model.json \
        --contact out/contact --validation out/validation out/validation_s1 out/validation_s2

Rules: `momentum`, `calibrated` (each alone, its own T²_α); `union` (alarm where either statistic T²/T²_α exceeds a
common κ, κ the α-quantile of max(T²_m/T²_m,α, T²_c/T²_c,α) on the paired calibration samples); `bonferroni`
(each at its own (1 + α)/2 quantile, no joint calibration); `rows` (one T²: the observer's F/T channels and the
acceleration residuals' motor channels, each with its own Λ, threshold the α-quantile on the paired samples);
`stacked` (T²_m/T²_m,α + T²_c/T²_c,α, threshold its α-quantile); `joint` (one T² over both residual vectors
with their joint covariance on the paired samples, the acceleration's resting motor channels set to 0).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from dynid.detect.combined import acceleration_statistic, paired_statistics  # noqa: E402
from dynid.detect.momentum_t2 import calibration_runs  # noqa: E402
from dynid.detect.evaluation import detectors  # noqa: E402
from dynid.detect.momentum_t2 import momentum_detection, stored_detector  # noqa: E402
from dynid.detect.momentum import VELOCITY_WINDOW_S  # noqa: E402
from dynid.identify.model_file import load_model  # noqa: E402
from dynid.identify.model_sections import ALPHA  # noqa: E402
from dynid.identify.validation import evaluate  # noqa: E402
from dynid.robot.outputs import output_channels  # noqa: E402


def run_statistics(identified, path: str, det_c, det_m) -> dict:
    ev = evaluate(path, path, identified=identified)
    mom = momentum_detection(identified, ev.dataset, None, ALPHA, detector=det_m)
    stat_c = acceleration_statistic(ev.model, det_c, ev.e, ev.signals.dq)
    return {"m": mom.statistic, "c": stat_c, "e_m": mom.residuals.e, "e_c": ev.e,
            "active": det_c.active(ev.model, ev.signals.dq),
            "contact": ev.dataset.contact, "side": ev.dataset.extra.get("skin.side")}


def rules(cal: dict, det_c, det_m, alpha: float, ft: np.ndarray) -> dict:
    """Each rule as a function of a run's statistics -> alarm per sample, thresholds set on the paired `cal`."""
    kappa = float(np.quantile(np.maximum(cal["m"], cal["c"]), alpha))
    q_m = det_m.quantiles.at((1 + alpha) / 2) / det_m.threshold
    q_c = cal["quantiles_c"].at((1 + alpha) / 2) / det_c.threshold

    def rows_t2(s: dict) -> np.ndarray:
        m = np.sum(s["e_m"][:, ft] ** 2 / det_m.variance[ft], axis=1)
        c = np.sum(np.where(s["active"][:, ~ft], s["e_c"][:, ~ft] ** 2 / det_c.variance[~ft], 0.0), axis=1)
        return m + c

    def joint_z(s: dict) -> np.ndarray:
        return np.hstack([s["e_m"], np.where(s["active"], s["e_c"], 0.0)])

    z = joint_z(cal)
    precision = np.linalg.pinv(z.T @ z / z.shape[0])

    def joint_t2(s: dict) -> np.ndarray:
        x = joint_z(s)
        return np.einsum("ni,ij,nj->n", x, precision, x)

    joint_threshold = float(np.quantile(joint_t2(cal), alpha))
    rows_threshold = float(np.quantile(rows_t2(cal), alpha))
    stacked_threshold = float(np.quantile(cal["m"] + cal["c"], alpha))
    print(f"union κ = {kappa:.4f}; bonferroni: momentum ×{q_m:.3f}, calibrated ×{q_c:.3f}; rows T²_α "
          f"{rows_threshold:.4g}; stacked {stacked_threshold:.4g}; {cal['m'].size} paired samples")
    return {"momentum": lambda s: s["m"] > 1, "calibrated": lambda s: s["c"] > 1,
            "union": lambda s: np.maximum(s["m"], s["c"]) > kappa,
            "bonferroni": lambda s: (s["m"] > q_m) | (s["c"] > q_c),
            "rows": lambda s: rows_t2(s) > rows_threshold,
            "stacked": lambda s: s["m"] + s["c"] > stacked_threshold,
            "joint": lambda s: joint_t2(s) > joint_threshold}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", required=True)
    ap.add_argument("--contact", required=True)
    ap.add_argument("--validation", nargs="+", default=[])
    args = ap.parse_args()
    identified = load_model(args.model)
    det_m = stored_detector(identified, "detect", ALPHA, 15.0, VELOCITY_WINDOW_S)
    det_c = detectors(identified, ALPHA, "dim")["calibrated"]
    runs, _ = calibration_runs(identified, None)
    cal = paired_statistics(identified, det_m, det_c, runs, identified.folds, with_residuals=True)
    cal["quantiles_c"] = identified.detector.calibrated_t2_quantiles
    ft = np.array([o.kind == "ft" for o in output_channels(identified.robot_model)])
    chosen = rules(cal, det_c, det_m, ALPHA, ft)
    runs = {"contact": run_statistics(identified, args.contact, det_c, det_m)}
    for v in args.validation:
        runs[Path(v).name] = run_statistics(identified, v, det_c, det_m)
    print("| rule | TPR distal | TPR proximal | TPR | FPR contact run | " +
          " | ".join(f"FPR {n}" for n in runs if n != "contact") + " |")
    for name, rule in chosen.items():
        s = runs["contact"]
        alarm = rule(s)
        truth = s["contact"] != 0
        side = s["side"]
        cells = [f"{100 * alarm[truth & (side == 1)].mean():.1f} %", f"{100 * alarm[truth & (side == -1)].mean():.1f} %",
                 f"{100 * alarm[truth].mean():.1f} %", f"{100 * alarm[~truth].mean():.2f} %"]
        cells += [f"{100 * rule(r).mean():.2f} %" for n, r in runs.items() if n != "contact"]
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
