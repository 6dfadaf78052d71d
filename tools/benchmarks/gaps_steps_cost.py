"""What the F/T step candidate (dynid.gaps.steps) costs `dynid gaps`: the workflow on one run, in one process, with
the step candidates and without them (ruptures' search and the steps' pruning replaced by nothing), alternately,
REPEAT times each; prints the median CPU time of the process (wall time swings with a shared machine's load) and
wall time of each, and their ratios (docs/benchmarks.md, "Model gaps").

    .venv/bin/python tools/benchmarks/gaps_steps_cost.py --data DIR_OR_RUN [--robot CFG] [--from S --to S] [--repeat N]
"""

from __future__ import annotations

import argparse
import statistics
import time
from unittest import mock

from dynid.config.robot_config import load_config
from dynid.gaps import workflow
from dynid.identify.validation import load_run
from dynid.robot.model import RobotModel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--robot", default="icub_right_arm")
    ap.add_argument("--from", dest="t_from", type=float)
    ap.add_argument("--to", dest="t_to", type=float)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    model = RobotModel(load_config(args.robot))
    ds = load_run(args.data, model, (args.t_from, args.t_to))
    times: dict[str, list[float]] = {"with steps": [], "without": []}
    cpu: dict[str, list[float]] = {"with steps": [], "without": []}
    for _ in range(args.repeat):
        for label in times:
            started, started_cpu = time.perf_counter(), time.process_time()
            if label == "without":
                with mock.patch.object(workflow, "found_candidates", lambda ctx, resid: ([], {})):
                    workflow.run(model, ds, log=lambda _: None)
            else:
                workflow.run(model, ds, log=lambda _: None)
            times[label].append(time.perf_counter() - started)
            cpu[label].append(time.process_time() - started_cpu)
    with_steps, without = (statistics.median(cpu[k]) for k in ("with steps", "without"))
    wall_with, wall_without = (statistics.median(times[k]) for k in ("with steps", "without"))
    print(f"{ds.n_samples} samples: with the step candidates {with_steps:.2f} s CPU, without {without:.2f} s CPU "
          f"(median of {args.repeat}), ratio {with_steps / without:.2f}; wall {wall_with:.2f} s against "
          f"{wall_without:.2f} s, ratio {wall_with / wall_without:.2f}")


if __name__ == "__main__":
    main()
