"""`dynid fleet`: runs of many robots of one kind → one model per robot, compared, the one that stands out named."""

from __future__ import annotations

import argparse
import re
from collections import Counter, OrderedDict
from pathlib import Path
from typing import Any

from ..cluster import executor
from ..config.robot_config import load_config
from ..errors import InputError
from ..identify.fit import DEFAULT_ESTIMATOR, ESTIMATORS, FitSettings
from ..identify.runs import RunRef, check_distinct_runs, for_workers, stream_run
from ..io.dataset import atomic_write
from ..io.file_set import holds_file_set
from ..io.run_paths import expand_named
from ..outputs import output_dir
from ..pipeline import IdentifySettings, check_scale, identify
from ..report.fleet import SCALE_WHY, compare, page
from ..robot.model import RobotModel
from .commands import COMMANDS
from .common import json_arg, min_speed_arg, plural, positive_int, robot_arg, scheduler_address

LAYOUT_KINDS = {"joint_friction": "friction", "motor_friction": "friction", "motor_gain": "gain",
                "ft_offset": "ft_offset"}
MIN_ROBOTS = 3


def _file_name(robot: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", robot) or "robot"


def cmd_fleet(args: argparse.Namespace) -> dict[str, Any]:
    config = load_config(args.robot, args.urdf)
    if args.scheduler:  # workers open the files in their own directory
        config = for_workers(config, [])[0]
    model = RobotModel(config)
    named = expand_named(args.data, (lambda p: holds_file_set(p, config)) if config.files else None)
    fleet: OrderedDict[str, list[str]] = OrderedDict()
    for run in named:
        fleet.setdefault(run.name, []).append(run.path)
    if len(fleet) < MIN_ROBOTS:
        raise InputError(f"--data names {plural(len(fleet), 'robot')} ({', '.join(fleet)}): a fleet needs at least "
                         f"{MIN_ROBOTS} to have a spread (name each run's robot: --data NAME=RUN, or one folder per "
                         "robot)")
    files = {r: _file_name(r) for r in fleet}
    uses = Counter(files.values())
    clash = [r for r in fleet if uses[files[r]] > 1]
    if clash:
        raise InputError("robots' names map to the same model file name: " + ", ".join(clash))
    out = Path(args.out)
    if not out.parent.is_dir():
        raise InputError(f"cannot write to '{args.out}' (--out): the directory {out.parent} does not exist")
    if out.is_dir() and any(out.iterdir()):  # an earlier fleet's models would stand beside this one's, unread
        raise InputError(f"cannot write to '{args.out}' (--out): it holds files already (an earlier fleet's models "
                         "would mix with this one's); give a new or empty directory")
    refs = {r: [RunRef(p) for p in paths] for r, paths in fleet.items()}
    if args.scheduler:
        refs = {r: for_workers(config, rr)[1] for r, rr in refs.items()}
    runs = {r: [stream_run(ref, model) for ref in rr] for r, rr in refs.items()}  # all checked before any fit
    check_distinct_runs([p for paths in fleet.values() for p in paths], [x for rr in runs.values() for x in rr])
    # before any fit; fleet takes no --payload (a walkthrough was told to add one, then refused it)
    check_scale(model, [x for rr in runs.values() for x in rr], payload_possible=False,
                without_payload="dynid fleet takes no --payload: its robots' runs must fix the scale without one")
    settings = IdentifySettings(FitSettings(estimator=args.estimator, min_speed=args.min_speed, blocks=args.blocks))
    cluster = executor(args.workers, args.scheduler)
    models = {}
    try:
        for i, (robot, robot_runs) in enumerate(runs.items()):
            print(f"  [{i + 1}/{len(runs)}] {robot}: {plural(len(robot_runs), 'run')}", flush=True)
            done = identify(model, robot_runs, fleet[robot], settings, cluster=cluster, refs=refs[robot])
            models[robot] = done.model
    finally:
        if cluster is not None:
            cluster.close()
    kinds = {name: LAYOUT_KINDS[b.kind] for b in model.layout.blocks if b.kind in LAYOUT_KINDS for name in b.names}
    result = compare(models, kinds)
    # DIR, DIR/models/ROBOT.json and DIR/fleet.html appear together, with --json, when the command succeeds: a
    # Ctrl-C or a model refused on saving left the models written before it, without the page (dynid.outputs)
    output_dir(out / "models")
    for robot, m in models.items():
        m.save(out / "models" / f"{files[robot]}.json")
    text = page(result, config.name)
    atomic_write(out / "fleet.html", lambda f: f.write(text.encode()))
    result["models"] = {r: str(out / "models" / f"{files[r]}.json") for r in fleet}
    result["runs"] = dict(fleet)
    result["report"] = str(out / "fleet.html")
    print(f"fleet of {len(fleet)} {config.name} robots, {plural(len(named), 'run')} -> {out} (fleet.html, models/)")
    kinds = ", ".join(dict.fromkeys(g["kind"] for g in result["groups"])) or "none"
    print(f"  {len(result['parameters'])} shared base parameters compared; {len(result['groups'])} groups tested "
          f"({kinds}), bound |S| > {result['bound']:.2f}")
    if not result["outliers"]:
        print("  no robot stands out beyond the fleet's spread")
    for o in result["outliers"]:
        for g in o["groups"]:
            ratios = ", ".join(f"{x:.2f}" for x in g["ratio_to_median"])
            print(f"  STANDS OUT: {o['robot']}: {g['group']} (S = {g['statistic']:.1f}; × {ratios} the others' median)"
                  + (f": every torque of its fit scaled (its gravity torques), {SCALE_WHY}" if g["group"] == "scale"
                     else ""))
    return result


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("fleet", help=COMMANDS["fleet"].help,
                        description="Runs of many robots of one kind: one model per robot (dynid fit on its runs), "
                        "the robots compared parameter by parameter with their standard errors, and the robot whose "
                        "friction, gains or F/T offsets stand out beyond the fleet's spread named "
                        "(docs/validation.md#a-fleet). Writes DIR/fleet.html (the robots side by side, in figures) "
                        "and DIR/models/ROBOT.json.")
    robot_arg(sp)
    sp.add_argument("--data", action="append", required=True, metavar="[NAME=]RUN",
                    help="a run of robot NAME (a file, `dynid simulate` directory, glob, folder or @LIST); without "
                    "NAME= a run belongs to the folder that holds it (one folder per robot); repeatable")
    sp.add_argument("--out", required=True, metavar="DIR", help="the directory to write (created)")
    where = sp.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, metavar="N", help="fit on a Dask LocalCluster of N workers")
    where.add_argument("--scheduler", type=scheduler_address, metavar="ADDRESS",
                       help="fit on the running Dask cluster at ADDRESS")
    sp.add_argument("--estimator", choices=ESTIMATORS, default=DEFAULT_ESTIMATOR,
                    help=f"the estimator each robot's model keeps (default {DEFAULT_ESTIMATOR})")
    sp.add_argument("--blocks", type=positive_int, default=10, help="time blocks per run (default 10)")
    min_speed_arg(sp)
    json_arg(sp)
    sp.set_defaults(func=cmd_fleet)
