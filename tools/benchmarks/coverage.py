"""Benchmark: do the fit's 95 % intervals contain the truth when runs differ the way real runs do?

Over `--repetitions` simulated repetitions (each a different true arm, robot seed 100 + i), `--runs` runs each of
`--duration` s (each its own trajectory, noise and contacts-free identification experiment), the runs differ:

- **friction that drifts** between runs (temperature): every joint's friction scaled by its own factor, uniform in
  [1 − d, 1 + d] (`dynid simulate --friction-scale JOINT=K`, d = `--friction-drift`, default 0.15), new per run;
- **a payload mounted slightly differently**: a `--payload-mass` kg point mass in the hand (the `payload` hidden
  effect, not given to the fit), its centre of mass at p0 = (0, 0, 0.05) m in the hand's frame moved by up to
  `--payload-jitter` m (default 0.03) per axis, uniform, new per run.

The truth a repetition's fit is held to is the arm's average over those draws: friction scale 1 (the factors' mean),
and the hand with the payload's mean inertial parameters (mass m at p0, plus (2/3)·m·a² on each diagonal moment
about the frame, the mean of m(|c|²I − ccᵀ) over the jitter). β_true = Φ_true[independent] + K Φ_true[dependent],
with the fit's own base.

Today's interval is the one the fit reported before issue 33: β̂ ± 1.96 · SE_blocks (the delete-one-time-block
jackknife, blocks of all runs pooled). After: β̂ ± 1.96 · SE, SE = max(SE_blocks, SE_runs) with SE_runs the
delete-one-run jackknife. Coverage is counted over every (repetition, base combination) the fit determines (by its
own rule: today's, blocks alone; after, both), and over all combinations.

    .venv/bin/python tools/benchmarks/coverage.py [--repetitions 20] [--runs 5] [--duration 40] [--jobs 2]
        [--out DIR] [--json FILE] [--start K]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pinocchio as pin

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.simulation.true_robot import draw_true_robot

P0 = np.array([0.0, 0.0, 0.05])
Z95 = 1.959963984540054


def dynid(*args: str) -> None:
    done = subprocess.run([sys.executable, "-m", "dynid.cli", *args], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"coverage: dynid {' '.join(args[:6])} … failed: {done.stderr.strip()[-400:]}")


def run_spec(i: int, r: int, joints: tuple[str, ...], drift: float, jitter: float, mass: float) -> dict:
    rng = np.random.default_rng([i, r, 0xC0F])
    scales = {j: float(rng.uniform(1 - drift, 1 + drift)) for j in joints}
    com = P0 + rng.uniform(-jitter, jitter, 3)
    return {"seed": 1000 * i + r, "scales": scales, "com": com.tolist()}


def simulate(run_dir: Path, robot_seed: int, spec: dict, duration: float, mass: float) -> None:
    x, y, z = spec["com"]
    args = ["simulate", "--kind", "identification", "--duration", f"{duration:g}", "--seed", str(spec["seed"]),
            "--robot-seed", str(robot_seed), "--out", str(run_dir),
            "--effect", f"payload:link=r_hand,mass={mass:g},x={x:.6f},y={y:.6f},z={z:.6f}"]
    for j, k in spec["scales"].items():
        args += ["--friction-scale", f"{j}={k:.6f}"]
    dynid(*args)


def true_phi(model: RobotModel, robot_seed: int, mass: float, jitter: float) -> np.ndarray:
    """The arm's average over the runs' draws (module docstring), in layout order."""
    truth = draw_true_robot(model, robot_seed).parameters(model)
    phi = np.array([truth[n] for n in model.layout.names])
    mean_payload = pin.Inertia(mass, P0, np.eye(3) * (2.0 / 3.0) * mass * jitter**2).toDynamicParameters()
    phi[model.layout.block("inertial", "r_hand").slice] += mean_payload
    return phi


def kind_of(name: str) -> str:
    if name.endswith((".fc_pos", ".fc_neg", ".fv_pos", ".fv_neg")):
        return "friction"
    if name.endswith(".phi_m"):
        return "gain"
    if ".offset." in name:
        return "ft_offset"
    return "inertial"


def covered(record: dict, phi: np.ndarray, names: list[str]) -> dict:
    base = record["base"]
    index = {n: k for k, n in enumerate(names)}
    ind = np.array([index[n] for n in base["independent"]])
    dep = np.array([index[n] for n in base["dependent"]], dtype=int)
    K = np.asarray(base["K"], float).reshape(ind.size, dep.size)
    beta_true = phi[ind] + (K @ phi[dep] if dep.size else 0.0)
    beta = np.asarray(base["values"])
    se_after = np.asarray(base["standard_errors"])
    se_today = np.asarray(base.get("standard_errors_blocks", base["standard_errors"]))
    err = np.abs(beta - beta_true)
    determined_after = np.asarray(base["identified"], bool)
    cad = np.abs(np.asarray(record.get("_cad_beta", np.zeros_like(beta))))
    determined_today = (se_today <= 0.1 * np.abs(beta)) | (se_today <= 0.05 * cad)
    kinds = np.array([kind_of(n) for n in base["independent"]])
    return {"today": (err <= Z95 * se_today), "after": (err <= Z95 * se_after), "kind": kinds,
            "determined_today": determined_today, "determined_after": determined_after,
            "z_today": (err / se_today), "z_after": (err / se_after)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repetitions", type=int, default=20)
    p.add_argument("--start", type=int, default=0, help="first repetition to run (several processes may share --out: "
                   "a repetition already done there is read, not redone)")
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--duration", type=float, default=40.0)
    p.add_argument("--friction-drift", type=float, default=0.15)
    p.add_argument("--payload-mass", type=float, default=0.3)
    p.add_argument("--payload-jitter", type=float, default=0.03)
    p.add_argument("--jobs", type=int, default=2, help="simulations at once")
    p.add_argument("--out", type=Path, help="keep the runs and models here (default: a temporary directory)")
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    config = load_config("icub_right_arm")
    model = RobotModel(config)
    names = list(model.layout.names)
    cad = np.nan_to_num(model.cad_parameters(), nan=0.0)
    root = a.out or Path(tempfile.mkdtemp(prefix="dynid-coverage-"))
    root.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    per_rep = []
    for i in range(a.start, a.repetitions):
        robot_seed = 100 + i
        rep = root / f"rep{i:02d}"
        specs = [run_spec(i, r, config.joints, a.friction_drift, a.payload_jitter, a.payload_mass) for r in range(a.runs)]
        dirs = [rep / f"run{r}" for r in range(a.runs)]
        with ThreadPoolExecutor(a.jobs) as pool:
            list(pool.map(lambda x: x[0].exists() or simulate(x[0], robot_seed, x[1], a.duration, a.payload_mass),
                          zip(dirs, specs)))
        model_file = rep / "model.json"
        if not model_file.exists():
            dynid("fit", *[arg for d in dirs for arg in ("--data", str(d))], "--out", str(model_file))
        record = json.loads(model_file.read_text())
        base = record["base"]
        index = {n: k for k, n in enumerate(names)}
        ind = np.array([index[n] for n in base["independent"]])
        dep = np.array([index[n] for n in base["dependent"]], dtype=int)
        K = np.asarray(base["K"], float).reshape(ind.size, dep.size)
        record["_cad_beta"] = (cad[ind] + (K @ cad[dep] if dep.size else 0.0)).tolist()
        c = covered(record, true_phi(model, robot_seed, a.payload_mass, a.payload_jitter), names)
        per_rep.append(c)
        print(f"rep {i + 1}/{a.repetitions}: determined today {int(c['determined_today'].sum())}, covered "
              f"{int((c['today'] & c['determined_today']).sum())}; after {int(c['determined_after'].sum())}, covered "
              f"{int((c['after'] & c['determined_after']).sum())} ({time.perf_counter() - started:.0f} s)", flush=True)

    def rate(hit: str, among: str | None, kind: str | None = None) -> dict:
        mask = [(c[among] if among else np.ones(c[hit].size, bool)) & (c["kind"] == kind if kind else True)
                for c in per_rep]
        num = sum(int((c[hit] & m).sum()) for c, m in zip(per_rep, mask))
        den = sum(int(m.sum()) for m in mask)
        return {"covered": num, "of": den, "coverage": num / den if den else None}

    def table(hit: str, determined: str) -> dict:
        return {"determined": rate(hit, determined), "all": rate(hit, None),
                "by_kind": {k: rate(hit, determined, k) for k in ("friction", "gain", "ft_offset", "inertial")}}

    result = {
        "settings": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()},
        "today": table("today", "determined_today"),
        "after": table("after", "determined_after"),
        "median_abs_z": {"today": float(np.median(np.concatenate([c["z_today"] for c in per_rep]))),
                         "after": float(np.median(np.concatenate([c["z_after"] for c in per_rep])))},
        "wall_time_s": time.perf_counter() - started, "runs_dir": str(root),
    }
    print(json.dumps({k: result[k] for k in ("today", "after", "median_abs_z")}, indent=1))
    if a.json:
        a.json.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
