"""`dynid gaps`: the model-gap workflow (dynid.gaps) on the command line."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..config.robot_config import load_config
from ..errors import InputError
from ..gaps.find import find_gaps
from ..gaps.workflow import format_report, worse_than_given
from ..identify.model_file import load_model
from ..identify.validation import load_run
from ..robot.effects import FT_STEP
from ..robot.model import RobotModel
from ..pipeline import check_scale
from .commands import COMMANDS
from .common import bad_rows, json_arg, model_robot, plural, robot_arg, skipped_rows, window, window_args


def change_points(text: str) -> tuple[float, ...]:
    """`--steps T1,T2,...`: finite seconds, strictly increasing (argparse turns the error into one line, exit 2)."""
    try:
        points = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds separated by commas (24.4,61.2), got '{text}'") from None
    if not all(np.isfinite(points)):
        raise argparse.ArgumentTypeError(f"every change point must be a finite number of seconds, got '{text}'")
    if any(b <= a for a, b in zip(points, points[1:])):
        raise argparse.ArgumentTypeError(f"change points must increase, got '{text}'")
    return points


def cmd_gaps(args: argparse.Namespace) -> dict[str, Any]:
    if model_robot(args) is not None:
        print(f"note: {args.robot} is not the configuration {args.model} was fitted with (edited since): the model's "
              "own is used (fit again to take the edit)")
    identified = load_model(args.model) if args.model else None
    config = identified.config if identified is not None else load_config(args.robot, args.urdf)
    model = RobotModel(config)
    ds = load_run(args.data, model, window(args), bad_rows=bad_rows(args))
    if identified is None:  # the workflow refits the standard model on these data alone (a given model: its inertias
        check_scale(model, [ds], payload_possible=False)  # held fix the scale)
    if identified is not None and identified.effects:  # before minutes of work
        raise InputError(f"{args.model} is already an augmented model (it names effects); give the standard "
                         "model it came from")
    tracking = not args.no_supply_tracking and bool(config.motors_with_input("pwm"))  # a PWM's supply drifts
    skipped = skipped_rows(args.data, ds.meta)
    found = find_gaps(model, ds, args.data, identified, supply_tracking=tracking, log=print,
                      keep_tentative=args.keep_tentative, steps=args.steps)
    result = found.result
    result["robot"] = config.name  # `dynid report --gaps` refuses another robot's
    if skipped is not None:
        result["bad_rows"] = skipped
    print(format_report(result))
    if args.out:
        found.augmented_model().save(args.out)
        result["out"] = args.out
        worse = worse_than_given(result)
        if worse:  # written, as asked, but not silently
            print(f"  WARNING: {args.out} is worse on {', '.join(g['channel'] for g in worse)} than {args.model}, whose "
                  "refit it is: keep the given model there")
        def named(e) -> str:  # several F/T steps on one sensor: each by its time span
            at = e.parameters.get("from_s") if e.kind == FT_STEP else None
            to = e.parameters.get("to_s") if e.kind == FT_STEP else None
            return (f"{e.kind} on {e.where}" + (f" from {at:.2f} s" if at is not None else "")
                    + (f" to {to:.2f} s" if to is not None else ""))

        kinds = ", ".join([named(e) for e in found.effects]
                          + [f"payload on {e.where} (in its inertial parameters)" for e in found.folded])
        kinds = kinds or "no effect (the standard model refitted)"
        print(f"augmented model -> {args.out}: {kinds}")
    if args.figures:
        from ..report.gaps_figures import write_figures  # matplotlib: loaded only to draw

        result["figures"] = write_figures(result, args.figures)
        print(f"figures -> {args.figures}: {plural(len(result['figures']), 'figure')}, with gaps.json and figures.json")
    return result


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("gaps", help=COMMANDS["gaps"].help,
        description="Refit the standard model on DATA, measure the residual per channel on held-out time blocks, "
        "select missing effects from a library (Stribeck, spring, cogging, PWM dead-zone, F/T drift, armature, "
        "load-dependent friction, PWM delay, coupling error, base tilt, F/T gain, a wrench at a joint limit, an F/T "
        "offset that steps between change points; a payload against a given model) by "
        "cross-validated forward selection, refit with them and print the gap before and after per channel.")
    robot_arg(sp, with_model=True)
    sp.add_argument("--data", required=True, metavar="DATA", help="the measured run, in any form `dynid import` "
                    "reads (CSV, candump log, ROS 2 bag, YARP folder, a folder of files the configuration's 'files' "
                    "describes, dataset or `dynid simulate` directory)")
    window_args(sp)
    sp.add_argument("--model", metavar="MODEL", help="an identified model: its gap on DATA is shown too, "
                    "its inertias are held (the rest is refitted), so a payload on a link can be named; its robot "
                    "configuration is used")
    sp.add_argument("--out", metavar="AUGMENTED_MODEL", help="write the refitted model with the named effects "
                    "(a model file: validate, detect, report and export accept it; export carries Stribeck and spring)")
    sp.add_argument("--keep-tentative", action="store_true", help="write the effects reported as tentative into "
                    "the augmented model too (by default it holds only the named ones)")
    sp.add_argument("--steps", type=change_points, metavar="T1,T2,...", help="known change points of the F/T "
                    "offsets, in the data's own seconds (as --from/--to): a step of every sensor's offset at each, "
                    "taken as known and not searched (default: the configuration's ft_steps; else ruptures finds "
                    "them in the residual and a step is named only if it lowers the held-out error of every channel "
                    "it keeps)")
    sp.add_argument("--figures", metavar="DIR", help="write a figure per finding and the gap before/after (PNG + "
                    "gaps.json) to DIR; `dynid report --gaps DIR` shows them")
    sp.add_argument("--no-supply-tracking", action="store_true", help="analyse with constant motor gains (one "
                    "pass); by default a first pass's residual gives each motor's supply ratio and a second pass "
                    "analyses the run with the inputs corrected by it, as `dynid fit` tracks the supply")
    json_arg(sp)
    sp.set_defaults(func=cmd_gaps)
