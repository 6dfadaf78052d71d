"""Benchmark: simulate 5 minutes of the default iCub identification experiment at 1 kHz (target ≤ 60 s).

The reference, timed in the same run for the same number of samples, is the plant's floor: the bare loop of
the Pinocchio calls it cannot avoid per sample (one CRBA and one RNEA for the step, one RNEA for the F/T
measurement). The ratio says what the controller, motors, implicit friction and sensors cost on top of the
rigid-body algorithms, whatever the machine's load. Writing the four output files is timed apart.

    .venv/bin/python tools/benchmarks/bench_simulate.py [--seconds 300] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time

import numpy as np
import pinocchio as pin

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.simulation import SimulationSettings, simulate
from dynid.simulation.output import write_simulation
from dynid.simulation.plant import RigidBodyPlant
from dynid.simulation.true_robot import draw_true_robot


def bare_pinocchio_loop(n: int) -> float:
    model = RobotModel(load_config("icub_right_arm"))
    plant = RigidBodyPlant(model, draw_true_robot(model, 0).inertias)
    m, data = plant.model, plant.model.createData()
    rng = np.random.default_rng(0)
    q, v, a = rng.normal(size=(3, 1000, m.nv)) * 0.3
    zero = np.zeros(m.nv)
    start = time.perf_counter()
    for k in range(n):
        i = k % 1000
        pin.crba(m, data, q[i])
        pin.rnea(m, data, q[i], v[i], zero)
        pin.rnea(m, data, q[i], v[i], a[i])
    return time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=300.0)
    p.add_argument("--json", metavar="FILE")
    args = p.parse_args()

    config = load_config("icub_right_arm")
    start = time.perf_counter()
    sim = simulate(config, SimulationSettings(kind="identification", duration=args.seconds))
    t_sim = time.perf_counter() - start
    n = sim.truth["samples"]
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        write_simulation(sim, out)
        t_write = time.perf_counter() - start
    t_ref = bare_pinocchio_loop(n)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    result = {
        "samples": n,
        "simulate_s": t_sim,
        "write_s": t_write,
        "pinocchio_floor_s": t_ref,
        "ratio_to_pinocchio_floor": t_sim / t_ref,
        "us_per_sample": t_sim / n * 1e6,
        "peak_rss_mb": peak_mb,
    }
    print(
        f"simulated {args.seconds:g} s of identification at 1 kHz ({n} samples) in {t_sim:.1f} s "
        f"({t_sim / n * 1e6:.0f} us/sample); writing the files {t_write:.1f} s\n"
        f"  bare Pinocchio floor (CRBA + 2 RNEA per sample): {t_ref:.2f} s; ratio {t_sim / t_ref:.1f}\n"
        f"  peak RSS {peak_mb:.0f} MB"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=2)


if __name__ == "__main__":
    main()
