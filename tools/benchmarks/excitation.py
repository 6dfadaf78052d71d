"""Designed excitation against today's identification trajectory (docs/excitation.md): run once, not in CI.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 .venv/bin/python tools/benchmarks/excitation.py WORKDIR \
        [--duration 60] [--validation out/validation] [--max-evaluations N] [--seed N]

In WORKDIR (steps whose output exists are skipped): `dynid excite --duration D` (the design, timed; `--max-evaluations`
and `--seed` passed on: a budget of evaluations, the time unbounded, makes the design independent of the load), `dynid simulate
--kind identification --duration D --seed 0` (today's) and `dynid simulate --trajectory design.csv --seed 0` (the
same true arm, noise and disturbance streams), `dynid fit` of each, `dynid validate` of each on the validation run,
`dynid structure --data` of each (the condition number on the run's own data). Then the errors against the plant's
truth, on the structural base parameters (the same combinations for both fits): median relative error, the share
within 10 %, the motor gains' largest relative error, the F/T offsets' RMS error. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.robot.regressors.base import structural_base_parameters


def dynid(*args: str) -> float:
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "dynid.cli", *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def errors(model: RobotModel, fitted: dict, truth: dict) -> dict:
    base = structural_base_parameters(model)
    names = model.layout.names
    phi_hat = np.array([fitted["parameters"][n] for n in names])
    phi_true = np.array([truth["parameters"].get(n, np.nan) for n in names])
    beta_hat, beta = base.base(phi_hat), base.base(np.nan_to_num(phi_true))
    rel = np.abs(beta_hat - beta) / np.maximum(np.abs(beta), 1e-12)
    gains = [i for i, n in enumerate(names) if n.endswith(".phi_m")]
    offsets = [i for i, n in enumerate(names) if ".offset." in n]
    return {
        "median_relative_error": float(np.median(rel)),
        "within_10_percent": float(np.mean(rel <= 0.1)),
        "gain_max_relative_error": float(np.max(np.abs(phi_hat[gains] / phi_true[gains] - 1))),
        "ft_offset_rms_error": float(np.sqrt(np.mean((phi_hat[offsets] - phi_true[offsets]) ** 2))),
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("workdir", type=Path)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--validation", type=Path, help="a validation run (default: simulate one, 120 s, seed 0)")
    p.add_argument("--max-evaluations", type=int, help="dynid excite's budget of evaluations (default: its --max-time)")
    p.add_argument("--seed", type=int, default=0, help="dynid excite's seed (the runs keep seed 0)")
    args = p.parse_args()
    w = args.workdir
    w.mkdir(parents=True, exist_ok=True)
    d = f"{args.duration:g}"
    times: dict[str, float] = {}
    if not (w / "design.csv").exists():
        # A budget of evaluations alone, the time unbounded: else a loaded machine's 80 s stop first
        budget = [] if args.max_evaluations is None else ["--max-evaluations", str(args.max_evaluations),
                                                          "--max-time", "3600"]
        times["design"] = dynid("excite", "--duration", d, "--seed", str(args.seed), *budget, "--out",
                                str(w / "design.csv"), "--json", str(w / "design.json"))
    validation = args.validation or w / "validation"
    if not validation.exists():
        dynid("simulate", "--kind", "validation", "--out", str(validation))
    runs = {"today": ["--kind", "identification", "--duration", d, "--seed", "0"],
            "designed": ["--kind", "identification", "--trajectory", str(w / "design.csv"), "--seed", "0"]}
    config = load_config("icub_right_arm")
    model = RobotModel(config)
    rows = {}
    for name, sim_args in runs.items():
        run = w / name
        if not run.exists():
            dynid("simulate", *sim_args, "--out", str(run))
        if not (w / f"{name}.model.json").exists():
            times[f"fit {name}"] = dynid("fit", "--data", str(run), "--out", str(w / f"{name}.model.json"),
                                         "--json", str(w / f"{name}.fit.json"))
        if not (w / f"{name}.validate.json").exists():
            dynid("validate", "--model", str(w / f"{name}.model.json"), "--data", str(validation),
                  "--json", str(w / f"{name}.validate.json"))
        if not (w / f"{name}.structure.json").exists():
            dynid("structure", "--data", str(run), "--json", str(w / f"{name}.structure.json"))
        fitted = json.loads((w / f"{name}.model.json").read_text())
        fit = json.loads((w / f"{name}.fit.json").read_text())
        truth = json.loads((run / "truth.json").read_text())
        validate = json.loads((w / f"{name}.validate.json").read_text())
        structure = json.loads((w / f"{name}.structure.json").read_text())
        rows[name] = {**errors(model, fitted, truth), "determined": len(fit["determined"]), "validate": validate,
                      "condition_on_run": structure["condition_number"]}
    design = json.loads((w / "design.json").read_text())
    print(json.dumps({"times_s": times, "design": {k: design[k] for k in ("condition_number", "design")},
                      "rows": {k: {x: y for x, y in v.items() if x != "validate"} for k, v in rows.items()}}, indent=1))
    print(json.dumps({k: {"table_ii": v["validate"].get("table_ii"),
                          "input_relative_error": v["validate"].get("relative_error", {}).get("overall")}
                      for k, v in rows.items()}, indent=1))


if __name__ == "__main__":
    main()
