"""Benchmark: `dynid fit` on the default iCub identification run (5 min at 1 kHz; target ≤ 30 s, ≤ 2 GB).

- `dynid fit` end to end, as a user runs it (regressors, statistics, three estimators with jackknife errors,
  PLS cross-validation, T² calibration): wall time and peak resident memory of the process and its workers.
- The reference, in the same run and on the same data: scikit-learn's `PLSRegression` on the fully stacked,
  weighted matrix (with ν from the fit), its build timed apart. That is what "just stack it and call
  scikit-learn" costs; its memory grows with the run's length, the fit's does not.
- Memory against length: the fit's peak memory on the first 1, 2.5 and 5 minutes (add longer runs with
  --minutes, e.g. 60 for the one-hour log; the simulation of the run is not timed).

    .venv/bin/python tools/benchmarks/bench_fit.py [--data DIR] [--minutes 1 2.5 5] [--no-reference] [--json FILE]

The ratio the speed target is stated in (docs/benchmarks.md#compiled-kernels): `dynid fit`'s wall time over the bare
Python loop of Pinocchio's `computeJointTorqueRegressor` on the same samples, timed in the same run.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from dynid.config.robot_config import load_config
from dynid.io.load import load_data
from dynid.robot.model import RobotModel

# Runs in a fresh interpreter so that its peak memory is its own.
REFERENCE = textwrap.dedent("""
    import json, resource, sys, time
    from pathlib import Path
    from sklearn.cross_decomposition import PLSRegression
    from dynid.config.robot_config import load_config
    from dynid.io.dataset import load_data
    from dynid.robot.model import RobotModel
    from dynid.robot.regressors.stack import build_stacked, row_weights, signals_from_dataset

    data, nu = Path(sys.argv[1]), int(sys.argv[2])
    config = load_config("icub_right_arm")
    model = RobotModel(config)
    sig = signals_from_dataset(model, load_data(data, config, joint_limits=model.joint_limits), filter_outputs=True)
    start = time.perf_counter()
    system = build_stacked(model, sig)
    w = row_weights(model, sig).ravel()
    A, b = system.A * w[:, None], system.b * w
    built = time.perf_counter() - start
    start = time.perf_counter()
    PLSRegression(n_components=nu, scale=True).fit(A, b)
    fitted = time.perf_counter() - start
    print(json.dumps({"build_s": built, "pls_s": fitted, "rows": A.shape[0], "columns": A.shape[1],
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
""")


# A fresh parent per command: its RUSAGE_CHILDREN peak is that command's and its workers', nothing else's.
PEAK = ("import resource, subprocess, sys; done = subprocess.run(sys.argv[1:]); "
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); sys.exit(done.returncode)")


def measured(cmd: list[str]) -> tuple[float, float]:
    """Wall time and peak RSS (MB, the largest of the process and its workers) of one command."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", PEAK, *cmd], capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"bench_fit: {' '.join(cmd[1:5])} … failed: {done.stderr.strip().splitlines()[-2:]}")
    return wall, int(done.stderr.strip().splitlines()[-1]) / 1024


def bare_loop_on(data: Path) -> float:
    """The reference of the ratio, in this run: the bare Python loop of Pinocchio's `computeJointTorqueRegressor` on
    the run's own samples (q, q̇, q̈ as the fit derives them), as bench_regressors.py times it."""
    from bench_regressors import bare_pinocchio_loop

    from dynid.robot.regressors.stack import signals_from_dataset

    config = load_config("icub_right_arm")
    model = RobotModel(config)
    sig = signals_from_dataset(model, load_data(data, config, joint_limits=model.joint_limits), filter_outputs=True)
    start = time.perf_counter()
    bare_pinocchio_loop(model, sig)
    return time.perf_counter() - start


def simulate(out: Path, seconds: float) -> Path:
    run = out / f"identification_{seconds:g}s"
    subprocess.run([sys.executable, "-m", "dynid.cli", "simulate", "--kind", "identification", "--duration",
                    str(seconds), "--out", str(run)], check=True, capture_output=True)
    return run


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, help="a `dynid simulate` identification run (default: simulate 5 min)")
    p.add_argument("--minutes", type=float, nargs="*", default=[1.0, 2.5], help="lengths for the memory scaling")
    p.add_argument("--no-reference", action="store_true", help="skip scikit-learn on the stacked matrix")
    p.add_argument("--json", metavar="FILE")
    args = p.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scaling = []
        for minutes in sorted(args.minutes):
            run = simulate(tmp, 60 * minutes)
            wall, peak = measured([sys.executable, "-m", "dynid.cli", "fit", "--data", str(run), "--out",
                                      str(tmp / "m.json")])
            scaling.append({"minutes": minutes, "fit_s": wall, "peak_rss_mb": peak})
            print(f"fit of {minutes:g} min: {wall:.1f} s, peak {peak:.0f} MB", flush=True)
        data = args.data or simulate(tmp, 300.0)
        config = load_config("icub_right_arm")
        samples = load_data(data, config, joint_limits=RobotModel(config).joint_limits).n_samples
        wall, peak = measured([sys.executable, "-m", "dynid.cli", "fit", "--data", str(data), "--out",
                                  str(tmp / "model.json"), "--json", str(tmp / "fit.json")])
        fit = json.loads((tmp / "fit.json").read_text())
        loop = bare_loop_on(data)
        result = {"samples": samples, "fit_s": wall, "fit_internal_s": fit["fit_time_s"], "peak_rss_mb": peak,
                  "n_components": fit["n_components"], "rank": fit["rank"], "scaling": scaling,
                  "pinocchio_regressor_loop_s": loop, "ratio_to_pinocchio_loop": wall / loop}
        print(f"dynid fit, {samples} samples: {wall:.1f} s wall, peak {peak:.0f} MB (ν = {fit['n_components']}, "
              f"rank {fit['rank']})\n  bare Pinocchio regressor loop on the same samples: {loop:.2f} s; ratio "
              f"{wall / loop:.2f}", flush=True)
        if not args.no_reference:
            ref = subprocess.run([sys.executable, "-c", REFERENCE, str(data), str(fit["n_components"])],
                                 capture_output=True, text=True)
            if ref.returncode != 0:
                sys.exit(f"bench_fit: reference failed: {ref.stderr.strip().splitlines()[-1:]}")
            r = json.loads(ref.stdout)
            result["reference"] = r
            total = r["build_s"] + r["pls_s"]
            print(f"scikit-learn PLSRegression on the stacked {r['rows']}×{r['columns']} matrix: build {r['build_s']:.1f} s"
                  f" + fit {r['pls_s']:.1f} s = {total:.1f} s, peak {r['peak_rss_mb']:.0f} MB")
            print(f"ratio dynid fit / reference: time {wall / total:.2f}, memory {peak / r['peak_rss_mb']:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
