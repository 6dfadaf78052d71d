"""`dynid gaps`: the model-gap workflow (dynid.gaps) on the command line."""

from __future__ import annotations

import argparse
from typing import Any

from .errors import InputError


def cmd_gaps(args: argparse.Namespace) -> dict[str, Any]:
    from .config import load_config
    from .evaluation import load_run
    from .gaps.workflow import Settings, format_report, run
    from .supply import SupplyTracking
    from .model import RobotModel

    reference, identified = None, None
    if args.model:
        from .identified import load_model

        identified = load_model(args.model)
        if identified.effects:
            raise InputError(f"{args.model} is already an augmented model (it names effects); give the standard "
                             "model it came from")
        config = identified.config
        reference = (args.model, identified.phi)
    else:
        config = load_config(args.robot)
    model = RobotModel(config)
    ds = load_run(args.data, model)
    # Supply tracking as the given model has it (a model fitted with it off keeps constant gains here too)
    supply = None if args.no_supply_tracking else (identified.supply_tracking if identified is not None else SupplyTracking())
    result = run(model, ds, Settings(supply=supply), reference=reference, log=print)
    augmented = result.pop("_augmented")
    result["data"] = args.data
    print(format_report(result))
    if args.out:
        from .gaps.refit import augmented_model

        # a payload is already in Φ (its link's inertial parameters): the model file lists only effects it predicts with
        effects = [e for e in augmented["effects"] if e.kind != "payload"]
        folded = [e for e in augmented["effects"] if e.kind == "payload"]
        aug = augmented_model(model, ds, args.data, result, augmented["phi"], effects, identified, folded=folded)
        aug.save(args.out)
        result["out"] = args.out
        kinds = ", ".join([f"{e.kind} on {e.where}" for e in effects]
                          + [f"payload on {e.where} (in its inertial parameters)" for e in folded])
        kinds = kinds or "no effect (the standard model refitted)"
        print(f"augmented model -> {args.out}: {kinds}")
    if args.figures:
        from .gaps.figures import write_figures

        result["figures"] = write_figures(result, args.figures)
        print(f"figures -> {args.figures}: {len(result['figures'])} files")
    return result


def add_commands(sub: argparse._SubParsersAction, robot_arg, json_arg) -> None:
    sp = sub.add_parser(
        "gaps", help="where model and data disagree, which missing effect explains it, and the gap after the fix",
        description="Refit the standard model on DATA, measure the residual per channel on held-out time blocks, "
        "select missing effects from a library (Stribeck, spring, cogging, PWM dead-zone, F/T drift, armature, "
        "load-dependent friction, PWM delay, coupling error, base tilt, F/T gain; a payload against a given "
        "model) by "
        "cross-validated forward selection, refit with them and print the gap before and after per channel.")
    robot_arg(sp)
    sp.add_argument("--data", required=True, metavar="DATA", help="the measured experiment (.csv, candump or .npz)")
    sp.add_argument("--model", metavar="MODEL", help="an identified model: its gap on DATA is shown too, "
                    "its inertias are held (the rest is refitted), so a payload on a link can be named; its robot "
                    "configuration is used")
    sp.add_argument("--out", metavar="AUGMENTED_MODEL", help="write the refitted model with the named effects "
                    "(a model file: validate, detect, report and export accept it; export carries Stribeck and spring)")
    sp.add_argument("--figures", metavar="DIR", help="write a figure per finding and the gap before/after (PNG + "
                    "gaps.json) to DIR; `dynid report --gaps DIR` shows them")
    sp.add_argument("--no-supply-tracking", action="store_true", help="analyse with constant motor gains (one "
                    "pass); by default a first pass's residual gives each motor's supply ratio and a second pass "
                    "analyses the run with the inputs corrected by it, as `dynid fit` tracks the supply")
    json_arg(sp)
    sp.set_defaults(func=cmd_gaps)
