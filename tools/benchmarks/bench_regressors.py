"""Benchmark: build the stacked A Φ = b for 5 minutes of 1 kHz data of the default iCub arm.

The reference, timed in the same run on the same samples, is the bare loop of Pinocchio's
`computeJointTorqueRegressor` (the floor: dynid makes exactly one such call per sample), so the ratio says what
the friction, coupling, offset and stacking work costs on top, whatever the machine's load.

    .venv/bin/python tools/benchmarks/bench_regressors.py [--seconds 300] [--rate 1000] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time

import numpy as np
import pinocchio as pin

from dynid import kernels
from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.robot.regressors import Signals, build_stacked


def sinusoidal_experiment(model: RobotModel, seconds: float, rate: float, seed: int = 0) -> Signals:
    """Smooth multi-sine joint motion inside the limits, with analytic derivatives, and random PWMs."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate)) / rate
    lo = np.array([model.joint_limits[j][0] for j in model.config.joints])
    hi = np.array([model.joint_limits[j][1] for j in model.config.joints])
    mid, amp = (lo + hi) / 2, (hi - lo) / 2 * 0.8 / 3
    f = rng.uniform(0.05, 0.5, (3, len(lo)))
    ph = rng.uniform(0, 2 * np.pi, (3, len(lo)))
    w = 2 * np.pi * f
    arg = w[None] * t[:, None, None] + ph[None]
    q = mid + amp * np.sin(arg).sum(1)
    dq = amp * (w * np.cos(arg)).sum(1)
    ddq = -amp * (w**2 * np.sin(arg)).sum(1)
    inputs = {m: rng.uniform(-0.3, 0.3, t.size) for m in model.config.motor_names}
    return Signals(q, dq, ddq, inputs, {}, {s: rng.normal(0, 1, (t.size, 6)) for s in model.sensor_v_index})


def bare_pinocchio_loop(model: RobotModel, sig: Signals) -> None:
    pm, data = model.pin_model, model.pin_model.createData()
    Q, V, A = model.pinocchio_configuration(sig.q), model.pinocchio_velocity(sig.dq), model.pinocchio_velocity(sig.ddq)
    for k in range(Q.shape[0]):
        pin.computeJointTorqueRegressor(pm, data, Q[k], V[k], A[k])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=300.0)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--json", metavar="FILE")
    args = p.parse_args()

    model = RobotModel(load_config("icub_right_arm"))
    sig = sinusoidal_experiment(model, args.seconds, args.rate)
    n = sig.q.shape[0]

    t0 = time.perf_counter()
    bare_pinocchio_loop(model, sig)
    t_ref = time.perf_counter() - t0

    # Twice: the first build's 2.8 GB come fresh from the OS (on this VM the hypervisor backs never-touched guest
    # pages at first touch: seconds for gigabytes); the second reuses memory the first one freed, as a process that
    # builds regressors more than once does. Both are reported.
    t0 = time.perf_counter()
    system = build_stacked(model, sig)
    t_first = time.perf_counter() - t0
    shape, nbytes = system.A.shape, system.A.nbytes
    del system
    t0 = time.perf_counter()
    system = build_stacked(model, sig)
    t_build = time.perf_counter() - t0
    assert system.A.shape == shape and system.A.nbytes == nbytes

    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    result = {
        "samples": n,
        "rows": system.A.shape[0],
        "columns": system.A.shape[1],
        "A_bytes": system.A.nbytes,
        "build_s": t_build,
        "first_build_s": t_first,
        "first_ratio_to_pinocchio_loop": t_first / t_ref,
        "threads": os.cpu_count(),
        "kernels": kernels.native() is not None,
        "pinocchio_regressor_loop_s": t_ref,
        "ratio_to_pinocchio_loop": t_build / t_ref,
        "us_per_sample": t_build / n * 1e6,
        "peak_rss_mb": peak_mb,
    }
    print(
        f"stacked A for {n} samples ({args.seconds:g} s at {args.rate:g} Hz): {system.A.shape[0]} x {system.A.shape[1]} "
        f"({system.A.nbytes / 1e9:.2f} GB)\n"
        f"  build: {t_build:.2f} s ({t_build / n * 1e6:.1f} us/sample; the first build, in memory fresh from the OS, "
        f"{t_first:.2f} s, ratio {t_first / t_ref:.2f}); bare Pinocchio regressor loop: {t_ref:.2f} s; "
        f"ratio {t_build / t_ref:.2f}\n  kernels: {'compiled' if kernels.native() else 'Python reference'}, "
        f"{os.cpu_count()} threads; peak RSS {peak_mb:.0f} MB"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=2)


if __name__ == "__main__":
    main()
