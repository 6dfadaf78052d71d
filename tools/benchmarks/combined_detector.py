"""No blind side (issue 30, item 6): ways to combine the momentum and the acceleration residuals, measured.

On the simulated arm: per-sample statistics of both detectors on contact-free cross-validated residuals of the fit's
own run (the first 150 s, as the momentum detector calibrates: each time block through the Φ fitted without it),
paired sample by sample; each rule's threshold set there at α; then TPR by side of the F/T sensor and FPR on the
contact run (outside its episodes) and on held-out contact-free runs. Reproduce (docs/detection.md#no-blind-side):

    PYTHONPATH=tools OMP_NUM_THREADS=1 python tools/benchmarks/combined_detector.py --model out/model.json \
        --contact out/contact --validation out/validation out/validation_s1 out/validation_s2

With `--coef FILE` (`dynid export`'s coefficient file of the same model) the runs go through the monitor's core too
(`rt_eval --stream --residual R`, R each of combined, acceleration, momentum): per-sample TPR by side and FPR,
episodes by side (an episode is found where the debounced detector is in contact during it) and the onset delays
(the core's first onset event inside an episode, from its start).

Rules: `momentum`, `calibrated` (each alone, its own T²_α); `union` (alarm where either statistic T²/T²_α exceeds a
common κ, κ the α-quantile of max(T²_m/T²_m,α, T²_c/T²_c,α) on the paired calibration samples); `bonferroni`
(each at its own (1 + α)/2 quantile, no joint calibration); `rows` (one T²: the observer's F/T channels and the
acceleration residuals' motor channels, each with its own Λ, threshold the α-quantile on the paired samples);
`sum (default)` (T²_m/T²_m,α + T²_c/T²_c,α, threshold κ its α-quantile: dynid.detect.combined); `joint` (one T² over both residual vectors
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
from dynid.detect.momentum_t2 import calibrate_momentum, calibration_runs  # noqa: E402
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
    return {"m": mom.statistic, "c": stat_c, "rest": mom.residuals.at_rest.all(axis=1), "e_m": mom.residuals.e,
            "e_c": ev.e,
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
    # the default: over the samples where a row moves; where every row rests the observer's own test (combined.py)
    moving = ~cal["rest"]
    stacked_threshold = float(np.quantile(cal["m"][moving] + cal["c"][moving], alpha))
    print(f"union κ = {kappa:.4f}; bonferroni: momentum ×{q_m:.3f}, calibrated ×{q_c:.3f}; rows T²_α "
          f"{rows_threshold:.4g}; sum κ {stacked_threshold:.4g}; {cal['m'].size} paired samples")
    return {"momentum": lambda s: s["m"] > 1, "calibrated": lambda s: s["c"] > 1,
            "union": lambda s: np.maximum(s["m"], s["c"]) > kappa,
            "bonferroni": lambda s: (s["m"] > q_m) | (s["c"] > q_c),
            "rows": lambda s: rows_t2(s) > rows_threshold,
            "sum (default)": lambda s: np.where(s["rest"], s["m"], (s["m"] + s["c"]) / stacked_threshold) > 1,
            "joint": lambda s: joint_t2(s) > joint_threshold}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", required=True)
    ap.add_argument("--contact", required=True)
    ap.add_argument("--validation", nargs="+", default=[])
    ap.add_argument("--coef", help="the coefficient file: the same runs through the monitor's core")
    args = ap.parse_args()
    if args.coef:
        monitor(Path(args.coef), Path(args.contact), [Path(v) for v in args.validation])
        return
    identified = load_model(args.model)
    det_c = detectors(identified, ALPHA, "dim")["calibrated"]
    runs, _ = calibration_runs(identified, None)
    # the fit's stored calibration where it is current, else calibrated here as `dynid detect` would (an older file)
    det_m = stored_detector(identified, "detect", ALPHA, 15.0, VELOCITY_WINDOW_S) or calibrate_momentum(
        identified.robot_model, identified.phi, identified.base, runs, ALPHA, identified.min_speed,
        tracking=identified.supply_tracking, folds=identified.folds)
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


def monitor(coef: Path, contact: Path, validation: list[Path]) -> None:
    """The runs through `rt_eval --stream` for each residual the file carries."""
    import tempfile

    from dynid.config.robot_config import load_config
    from dynid.export.coefficients import read_coefficients
    from dynid.export.rt_eval_io import detector_columns, raw_samples, run_stream
    from dynid.identify.validation import load_run
    from dynid.io.dataset import contact_episodes
    from dynid.robot.model import RobotModel

    c = read_coefficients(coef)
    model = RobotModel(load_config(c.robot_name))
    col = detector_columns(c)
    exe = ROOT / "build" / "rt_monitor" / "rt_eval"
    runs = {"contact": load_run(str(contact), model), **{v.name: load_run(str(v), model) for v in validation}}
    print(f"{coef}: κ = {c.combined_scale:.4g}, debounce on {c.debounce_on} / off {c.debounce_off} samples")
    print("| residual | TPR distal | TPR proximal | FPR contact run | episodes distal | episodes proximal | "
          "onset delay median / p90 | "
          + " | ".join(f"FPR {n}" for n in runs if n != "contact") + " |")
    with tempfile.TemporaryDirectory() as work:
        for residual in ("combined", "acceleration", "momentum"):
            cells = []
            for name, ds in runs.items():
                out = run_stream(exe, coef, raw_samples(ds, c), Path(work), "--residual", residual)
                ready, above, held = out[:, 0] > 0, out[:, col["above"]] > 0, out[:, col["in_contact"]] > 0
                onsets = np.flatnonzero(out[:, col["event"]] == 1)
                if name != "contact":
                    cells.append(f"{100 * above[ready].mean():.2f} %")
                    continue
                truth, side = ds.contact != 0, ds.extra["skin.side"]
                tpr = [f"{100 * above[ready & truth & (side == s)].mean():.2f} %" for s in (1, -1)]
                found, delays = {1: [0, 0], -1: [0, 0]}, []
                for a, b in contact_episodes(ds.contact):
                    s = int(side[a])
                    found[s][1] += 1
                    found[s][0] += bool(held[a:b].any())
                    first = onsets[(onsets >= a) & (onsets < b)]
                    if first.size:
                        delays.append(1e3 * (ds.t[first[0]] - ds.t[a]))
                cells = tpr + [f"{100 * above[ready & ~truth].mean():.2f} %",
                               f"{found[1][0]}/{found[1][1]}", f"{found[-1][0]}/{found[-1][1]}",
                               f"{np.median(delays):.0f} / {np.percentile(delays, 90):.0f} ms"] + cells
            print(f"| {residual} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
