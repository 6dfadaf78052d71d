"""`dynid gaps`: the model-gap workflow (dynid.gaps) on the command line."""

from __future__ import annotations

import argparse
from typing import Any


def cmd_gaps(args: argparse.Namespace) -> dict[str, Any]:
    from .config import load_config
    from .evaluation import load_run
    from .gaps.workflow import format_report, run
    from .model import RobotModel

    reference = None
    if args.model:
        from .identified import load_model

        identified = load_model(args.model)
        config = identified.config
        reference = (args.model, identified.phi)
    else:
        config = load_config(args.robot)
    model = RobotModel(config)
    ds = load_run(args.data, model)
    result = run(model, ds, reference=reference, log=print)
    result["data"] = args.data
    print(format_report(result))
    return result


def add_commands(sub: argparse._SubParsersAction, robot_arg, json_arg) -> None:
    sp = sub.add_parser(
        "gaps", help="where model and data disagree, which missing effect explains it, and the gap after the fix",
        description="Refit the standard model on DATA, measure the residual per channel on held-out time blocks, "
        "select missing effects from a library (Stribeck, spring, cogging, PWM dead-zone, F/T drift, armature, "
        "load-dependent friction, PWM delay, coupling error, base tilt, F/T gain) by "
        "cross-validated forward selection, refit with them and print the gap before and after per channel.")
    robot_arg(sp)
    sp.add_argument("--data", required=True, metavar="DATA", help="the measured experiment (.csv, candump or .npz)")
    sp.add_argument("--model", metavar="MODEL", help="an identified model: its gap on DATA is shown too "
                    "(its robot configuration is used)")
    json_arg(sp)
    sp.set_defaults(func=cmd_gaps)
