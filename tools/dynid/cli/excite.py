"""`dynid excite`: an excitation trajectory designed for the fit (docs/excitation.md), written as an experiment CSV
of t, q, q̇, q̈ that `dynid simulate --trajectory` runs and a position controller follows."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import load_config
from ..errors import InputError
from ..excite import ConditionObjective, design, joint_limits, margins, whole_periods
from ..excite.design import DEFAULT_HARMONICS, DEFAULT_MAX_TIME_S, DEFAULT_PERIOD_S, MAX_HARMONIC_HZ
from ..io.csv_format import write_csv
from ..io.dataset import Dataset
from ..io.load import MIN_SAMPLES
from ..progress import enabled
from ..robot.model import RobotModel
from ..simulation.experiment import identification_reference
from .commands import COMMANDS
from .common import int_in, json_arg, positive_float, robot_arg, seed

MAX_DURATION_S = 3600.0
COMPARE_RATE_HZ = 20.0  # the grid both condition numbers are reported on, over the whole duration
MIN_RATE_HZ, MAX_RATE_HZ = 10.0, 10_000.0


def _check(args: argparse.Namespace) -> tuple[int, float]:
    """Refuse bad numbers in one line, before any work: (periods, base frequency)."""
    if args.duration > MAX_DURATION_S:
        raise InputError(f"--duration {args.duration:g} s: at most {MAX_DURATION_S:g} s (design a shorter period, "
                         "it repeats)")
    if not MIN_RATE_HZ <= args.rate <= MAX_RATE_HZ:
        raise InputError(f"--rate {args.rate:g} Hz is outside {MIN_RATE_HZ:g}..{MAX_RATE_HZ:g} Hz")
    if args.duration * args.rate + 1 < MIN_SAMPLES:
        raise InputError(f"--duration {args.duration:g} s at --rate {args.rate:g} Hz is fewer than {MIN_SAMPLES} "
                         "samples: a run needs at least that many")
    f = args.base_frequency
    if f is not None and f * args.duration < 0.5:
        raise InputError(f"--base-frequency {f:g} Hz: its period ({1 / f:g} s) is longer than the duration "
                         f"({args.duration:g} s); the trajectory repeats whole periods (at least {0.5 / args.duration:.3g} Hz)")
    periods, f_used = whole_periods(args.duration, f)
    if args.harmonics * f_used > MAX_HARMONIC_HZ:
        raise InputError(f"--base-frequency {f_used:g} Hz with {args.harmonics} harmonics reaches "
                         f"{args.harmonics * f_used:g} Hz, above the {MAX_HARMONIC_HZ:g} Hz a position controller follows "
                         "(give a lower --base-frequency, fewer --harmonics or a longer --duration)")
    return periods, f_used


def _finite(x: float) -> float | None:
    """JSON has no infinity: null stands for a condition number that is infinite (a direction not excited)."""
    return float(x) if np.isfinite(x) else None


def _say(text: str) -> None:
    if enabled():
        sys.stderr.write(f"  {text}\n")


def cmd_excite(args: argparse.Namespace) -> dict[str, Any]:
    periods, f = _check(args)
    config = load_config(args.robot, args.urdf)
    model = RobotModel(config)
    limits = joint_limits(model)
    objective = ConditionObjective.of(model)
    result = design(model, args.duration, f, args.harmonics, args.max_time, args.seed, objective, _say,
                    args.max_evaluations)
    traj = result.trajectory

    # The file: t from 0 to the duration inclusive (at rest at both ends), at --rate.
    n = int(round(args.duration * args.rate)) + 1
    t = np.linspace(0.0, args.duration, n)
    q, dq, ddq = traj.evaluate(t)
    q[-1], dq[[0, -1]], ddq[[0, -1]] = q[0], 0.0, 0.0  # exact rest, not 1e-15
    dataset = Dataset(t=t, joints=config.joints, q=q, dq=dq, ddq=ddq,
                      meta={"robot": config.name, "source": "dynid excite"})

    # The condition numbers, both on the same grid (COMPARE_RATE_HZ) over the whole duration, rows at rest left out.
    grid = np.arange(0.0, args.duration, 1.0 / COMPARE_RATE_HZ)
    designed = objective.report_condition(*traj.evaluate(grid))
    started = time.perf_counter()
    t_ref, q_ref, dq_ref, ddq_ref = identification_reference(config, args.duration)
    step = max(1, int(round((t_ref[1] - t_ref[0]) ** -1 / COMPARE_RATE_HZ)))
    today = objective.report_condition(q_ref[::step], dq_ref[::step], ddq_ref[::step])
    ratio = designed / today if np.isfinite(today) else None  # today's leaves a base direction unexcited (inf)
    reached = margins(traj, limits)
    write_csv(dataset, Path(args.out))  # last: a failure before leaves nothing behind
    joints = config.joints
    print(f"designed an excitation trajectory for {config.name}: {args.duration:g} s = {periods} period(s) of "
          f"{1 / f:g} s, {args.harmonics} harmonics of {f:g} Hz, in {result.seconds:.1f} s "
          f"({result.evaluations} evaluations, {result.starts} SLSQP run(s)"
          f"{', stopped by its budget' if result.stopped_by_time else ''}) -> {args.out}")
    if args.base_frequency is not None and not np.isclose(f, args.base_frequency, rtol=1e-9):
        print(f"  --base-frequency {args.base_frequency:g} Hz rounded to {f:g} Hz: {periods} whole period(s) in "
              f"{args.duration:g} s (the trajectory ends where it starts, at rest)")
    print(f"  condition number of the weighted, column-scaled regressor on its rank ({objective.rank}; what `dynid "
          f"structure --data` prints for a run, here with predicted inputs): designed "
          f"{designed:.4g}, today's identification trajectory over the same {args.duration:g} s "
          + (f"{today:.4g} (ratio {ratio:.3f})" if np.isfinite(today) else "inf (it leaves a base direction unexcited)"))
    print("  joint: peak |dq| / limit, peak |ddq| / limit, closest approach to the URDF limits (fraction of range)")
    for i, j in enumerate(joints):
        unit = "m" if model.prismatic[i] else "rad"
        print(f"    {j}: {reached['velocity'][i]:.3f} of {limits.velocity[i]:g} {unit}/s, "
              f"{reached['acceleration'][i]:.3f} of {limits.acceleration[i]:g} {unit}/s², "
              f"{reached['position_clearance'][i]:.3f} (margin {limits.margin:g})")
    return {
        "robot": config.name, "out": args.out, "duration_s": args.duration, "rate_hz": args.rate, "samples": n,
        "base_frequency_hz": f, "periods": periods, "harmonics": args.harmonics,
        "condition_number": {"designed": _finite(designed), "today": _finite(today),
                             "ratio": None if ratio is None else _finite(ratio),
                             "rank": objective.rank, "grid_hz": COMPARE_RATE_HZ,
                             "today_source": f"dynid simulate --kind identification --duration {args.duration:g} "
                                             "--seed 0 (its reference)"},
        "limits": limits.as_dict(joints),
        "margins": {j: {"velocity": float(reached["velocity"][i]), "acceleration": float(reached["acceleration"][i]),
                        "position_clearance": float(reached["position_clearance"][i]),
                        "q_min": float(reached["q_min"][i]), "q_max": float(reached["q_max"][i])}
                    for i, j in enumerate(joints)},
        "design": {"seconds": result.seconds, "evaluations": result.evaluations, "slsqp_runs": result.starts,
                   "stopped_by_time": result.stopped_by_time, "max_time_s": args.max_time,
                   "max_evaluations": args.max_evaluations, "seed": args.seed,
                   "comparison_seconds": time.perf_counter() - started},
        "fourier": traj.as_dict(joints),
    }


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("excite", help=COMMANDS["excite"].help,
                        description="Design an excitation trajectory: a finite Fourier series per joint (Swevers et "
                        "al. 1997), at rest at both ends, within the joints' position (URDF, with the configuration's "
                        "margin), velocity and acceleration limits (the configuration's 'limits'), minimising the "
                        "condition number of the fit's weighted regressor (as `dynid structure --data` computes it). "
                        "Writes a CSV of t, q, dq, ddq for `dynid simulate --trajectory` or a position controller, and "
                        "reports the condition number against today's identification trajectory of the same duration "
                        "(docs/excitation.md).")
    robot_arg(sp)
    sp.add_argument("--duration", type=positive_float, required=True, metavar="S",
                    help=f"seconds of trajectory, a whole number of periods (at most {MAX_DURATION_S:g})")
    sp.add_argument("--base-frequency", type=positive_float, metavar="HZ",
                    help=f"the series' base frequency, rounded to a whole number of periods in the duration (default: "
                    f"periods of about {DEFAULT_PERIOD_S:g} s)")
    sp.add_argument("--harmonics", type=int_in(1, 20), default=DEFAULT_HARMONICS, metavar="L",
                    help=f"harmonics per joint (default {DEFAULT_HARMONICS})")
    sp.add_argument("--max-time", type=positive_float, default=DEFAULT_MAX_TIME_S, metavar="S",
                    help=f"seconds the optimiser may take; the best trajectory found by then is kept (default "
                    f"{DEFAULT_MAX_TIME_S:g})")
    sp.add_argument("--max-evaluations", type=int_in(1, 10**7), metavar="N",
                    help="stop after N evaluations of the objective (with its gradient): the same trajectory whatever "
                    "the machine's load (default: --max-time alone)")
    sp.add_argument("--seed", type=seed, default=0, metavar="N", help="seed of the random starts (default 0)")
    sp.add_argument("--rate", type=positive_float, default=100.0, metavar="HZ",
                    help="samples per second in the CSV (default 100; `dynid simulate` interpolates)")
    sp.add_argument("--out", required=True, metavar="TRAJ.csv", help="the trajectory to write (CSV, atomically)")
    json_arg(sp)
    sp.set_defaults(func=cmd_excite)
