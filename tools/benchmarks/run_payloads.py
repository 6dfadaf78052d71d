"""The figures behind dynid.identify.run_payloads' thresholds: every run's apparent load, strongest first, on sets of
real runs with and without a load nobody declared (each run's mass at the payload frame beyond the others', its
standard error over the run's own time blocks, and the share of the pooled residual it removes).

    DYNID_URDF_PATH=../shared/realdata/ur10e_mamedov:../shared/realdata/icub_leg_insitu \\
        PYTHONPATH=tools .venv/bin/python tools/benchmarks/run_payloads.py [REALDATA]

A line is marked NAMED where `dynid fit` names the run (MIN_DROP and MIN_SIGMAS).
"""

from __future__ import annotations

import sys
from pathlib import Path

from dynid.config.robot_config import load_config
from dynid.identify.fit import FitSettings, fit
from dynid.identify.run_payloads import MIN_DROP, MIN_SIGMAS, apparent_payloads
from dynid.identify.validation import load_run
from dynid.robot.model import RobotModel


def case(title: str, robot: str, runs: list[tuple[Path, tuple[float | None, float | None]]]) -> None:
    model = RobotModel(load_config(robot))
    data = [load_run(str(p), model, w) for p, w in runs]
    result = fit(model, data, FitSettings())
    named = {a.run for a in apparent_payloads(model, result.statistics, result.base.independent, [False] * len(runs))}
    every = apparent_payloads(model, result.statistics, result.base.independent, [False] * len(runs), 0.0, 0.0)
    print(f"{title}:")
    for a in every:
        p, w = runs[a.run]
        label = p.name + ("" if w == (None, None) else f"@{w[0]}:{w[1]}")
        print(f"  {label:42s} {a.mass_kg:+7.3f} kg ± {a.standard_error_kg:.3f} ({abs(a.mass_kg) / a.standard_error_kg:5.1f} "
              f"σ), residual {100 * a.residual_drop:5.2f} % lower{'   NAMED' if a.run in named else ''}")


def main() -> None:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[3] / "shared" / "realdata"
    ur = root / "ur10e_mamedov" / "identification"
    unloaded = [ur / n for n in ("ur-20_02_05-20sec_8harm.csv", "ur-20_02_10-30sec_12harm.csv",
                                 "ur-20_02_12-50sec_12harm.csv", "ur-20_02_19_14harm50sec.csv")]
    loaded = ur / "ur-20_02_19_14harm50secLoad.csv"
    whole = (None, None)
    print(f"thresholds: residual ≥ {100 * MIN_DROP:g} % lower and ≥ {MIN_SIGMAS:g} standard errors\n"
          "(each step names the strongest run, which keeps its mass; the others are tested again beside it)")
    case("UR10e, five runs, the 2.805 kg run without --payload", "ur10e_known_gains",
         [(p, whole) for p in [*unloaded, loaded]])
    case("UR10e, the pair alone, no --payload", "ur10e_known_gains", [(unloaded[3], whole), (loaded, whole)])
    case("UR10e, the four unloaded runs", "ur10e_known_gains", [(p, whole) for p in unloaded])
    leg = root / "icub_leg_insitu" / "dumperLeftLegNoIMU"
    case("iCub leg, the swing in two windows", "icub_right_leg_standing", [(leg, (14.0, 39.5)), (leg, (39.5, 62.42))])
    case("iCub leg, the swing in three windows", "icub_right_leg_standing",
         [(leg, (14.0, 30.0)), (leg, (30.0, 46.0)), (leg, (46.0, 62.42))])
    case("iCub leg, the swing in four windows", "icub_right_leg_standing",
         [(leg, (14.0, 26.0)), (leg, (26.0, 38.0)), (leg, (38.0, 50.0)), (leg, (50.0, 62.42))])


if __name__ == "__main__":
    main()
