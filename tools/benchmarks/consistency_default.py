"""Consistency chosen by what generalises (issue 34, item 3): `dynid fit --consistent off` against `on`, judged on
time blocks and runs the fit never saw.

Every robot is fitted twice, the same data and settings but `--consistent`, and both models are validated with
`dynid validate --blocks K` on held-out blocks only: blocks of another run (cross-run) or blocks of the same run
that share no sample with the fit (cross-block; a block partly in the fit is left out). Per robot and channel group
the table gives the worst and the median held-out block for off and on, how many blocks the consistent model
predicts better (paired: the same block), and which generalises better. Reproduce (docs/consistency.md#default):

    PYTHONPATH=tools:. .venv/bin/python tools/benchmarks/consistency_default.py --realdata ../shared/realdata \
        --work /tmp/consist --json /tmp/consist/table.json

- Simulated arm (the default true arm): identification runs of --sim-duration s, seeds 21-23, each fitted and
  validated on a validation run of seed 30 (60 s, 6 blocks): cross-run.
- iCub leg: fitted on 23-47 s, validated on 6 blocks of 14-65 s (held out: 14-22.5, 48-56.5, 56.5-65 s); and
  fitted on each half of the swing (14-39.5, 39.5-65 s), validated on 3 blocks of the other half.
- UR10e (known gains): fitted on the 14-harmonic identification run, validated on every 5 s block of the other
  unloaded identification runs (8, 12 and 12 harmonics) and on the 5 blocks of the point-to-point run: cross-run.
- Panda: fitted on the first 2/3 (t <= 13.9189 s, docs/robots/panda.md) and, the other way, on t >= 7.01 s;
  6 blocks of 3.5 s, the blocks outside each fit.
- TIAGo wrist: fitted on protocol.yaml's rows 921-6790 (docs/robots/tiago_wrist.md), 16 blocks of 5 s, those
  outside the fit.

A verdict needs more than the arithmetic's noise: worst and median within 1 % of each other is "equal"; a side
"generalises better" when neither figure is worse by more than 1 % and one is better by more than 1 %; otherwise
"mixed". A robot whose data are absent is skipped with a line saying so. Models are kept in --work and reused.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

MODES = ("off", "on")
TOLERANCE = 0.01  # relative: differences below it are not a verdict (docs/validation.md, Across CPUs)
SIM_SEEDS = (21, 22, 23)
SIM_VALIDATION_SEED = 30


def dynid(*args: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "tools"), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-m", "dynid.cli", *args, "--json", "-"], capture_output=True, text=True,
                          env=env)
    if done.returncode != 0:
        raise SystemExit(f"dynid {' '.join(args)}: {done.stderr.strip()}")
    return json.loads(done.stdout)


@dataclass
class Validation:
    """One `dynid validate --blocks K` on held-out data: its label, the data arguments and K."""

    label: str  # "cross-run: ..." or "cross-block: ..."
    data: tuple[str, ...]
    blocks: int


@dataclass
class Case:
    """One fit (its arguments without --consistent) and the validations of its two models."""

    name: str  # file stem in --work
    fit: tuple[str, ...]
    validations: list[Validation]
    robot_args: tuple[str, ...] = ()


@dataclass
class Robot:
    name: str
    cases: list[Case]
    # per figure name, per mode: one value per held-out block (the same blocks in the same order for both modes)
    values: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    where: list[str] = field(default_factory=list)  # the held-out blocks, "label block i (from-to s)"
    fit_time_s: dict[str, list[float]] = field(default_factory=lambda: {m: [] for m in MODES})


def figure_groups(names: list[str], inputs: str, channels: bool = False) -> list[tuple[str, str]]:
    """(figure name, channel-group label) of what the table compares: the relative error of the predicted inputs or
    joint torques, and each F/T sensor's identified force and torque error norms; with `channels`, each input
    channel's relative error instead."""
    if channels:
        return [(n, f"{inputs} {n.split('.', 1)[1]}, relative error") for n in names
                if n.startswith("relative_error.") and n != "relative_error.overall"]
    out = []
    if "relative_error.overall" in names:
        out.append(("relative_error.overall", f"{inputs}, relative error"))
    if "relative_torque_error" in names:
        out.append(("relative_torque_error", "joint torques, relative error (filtered)"))
    for n in names:
        if n.startswith("ft.") and n.endswith(("force_identified", "torque_identified")):
            sensor, what = n[3:].rsplit(".", 1)
            out.append((n, f"{sensor} {what.split('_')[0]}, N" if what.startswith("force") else
                        f"{sensor} {what.split('_')[0]}, Nm"))
    return out


def run_robot(robot: Robot, work: Path, inputs: str) -> None:
    for case in robot.cases:
        models = {}
        for mode in MODES:
            models[mode] = work / f"{case.name}-{mode}.json"
            if not models[mode].is_file():
                t0 = time.perf_counter()
                dynid("fit", *case.fit, "--consistent", mode, "--out", str(models[mode]))
                robot.fit_time_s[mode].append(time.perf_counter() - t0)
                print(f"  fitted {case.name} --consistent {mode} ({robot.fit_time_s[mode][-1]:.0f} s)", flush=True)
        for v in case.validations:
            results = {m: dynid("validate", "--model", str(models[m]), *v.data, "--blocks", str(v.blocks))["blocks"]
                       for m in MODES}
            rows = {m: results[m]["blocks"] for m in MODES}
            held = [i for i, b in enumerate(rows["off"]) if b["fit_overlap"] == 0]
            if not held:
                raise SystemExit(f"{case.name}, {v.label}: no block outside the fit")
            for i in held:
                b = rows["off"][i]
                robot.where.append(f"{case.name}: {v.label} block {i + 1} ({b['from']:.2f}-{b['to']:.2f} s)")
            names = list(rows["off"][0]["figures"])
            for name, _ in figure_groups(names, inputs) + figure_groups(names, inputs, channels=True):
                for m in MODES:
                    robot.values.setdefault(name, {k: [] for k in MODES})[m] += [
                        float(rows[m][i]["figures"][name]) for i in held]
            print(f"  validated {case.name} on {v.label}: {len(held)} held-out blocks", flush=True)


def verdict(worst: dict[str, float], median: dict[str, float]) -> str:
    changes = [on / off - 1 if off > 0 else 0.0 for off, on in ((worst["off"], worst["on"]),
                                                                 (median["off"], median["on"]))]
    if all(abs(c) <= TOLERANCE for c in changes):
        return "equal"
    if all(c <= TOLERANCE for c in changes):
        return "on"
    if all(c >= -TOLERANCE for c in changes):
        return "off"
    return "mixed"


def table(robot: Robot, inputs: str, channels: bool = False) -> list[dict]:
    rows = []
    for name, label in figure_groups(list(robot.values), inputs, channels):
        v = {m: np.array(robot.values[name][m]) for m in MODES}
        ok = np.isfinite(v["off"]) & np.isfinite(v["on"])
        if not ok.any():
            continue
        worst = {m: float(v[m][ok].max()) for m in MODES}
        median = {m: float(np.median(v[m][ok])) for m in MODES}
        better = int(np.sum(v["on"][ok] < v["off"][ok] * (1 - TOLERANCE)))
        worse = int(np.sum(v["on"][ok] > v["off"][ok] * (1 + TOLERANCE)))
        rows.append({"robot": robot.name, "figure": name, "group": label, "blocks": int(ok.sum()),
                     "worst": worst, "median": median, "on_better_blocks": better, "on_worse_blocks": worse,
                     "generalises_better": verdict(worst, median)})
    return rows


def fmt(x: float, relative: bool) -> str:
    return f"{100 * x:.2f} %" if relative else f"{x:.4g}"


def print_rows(rows: list[dict]) -> None:
    for r in rows:
        rel = "relative" in r["figure"]
        w, m = r["worst"], r["median"]
        print(f"| {r['robot']} | {r['group']} | {r['blocks']} | {fmt(w['off'], rel)} | {fmt(w['on'], rel)} | "
              f"{fmt(m['off'], rel)} | {fmt(m['on'], rel)} | {r['on_better_blocks']} / {r['on_worse_blocks']} | "
              f"**{r['generalises_better']}** |", flush=True)


# ---------------------------------------------------------------------------------------------------------------
# The robots


def sim_arm(work: Path, duration: float) -> Robot:
    validation = work / f"sim-validation-{SIM_VALIDATION_SEED}"
    if not (validation / "dataset.npz").is_file():
        dynid("simulate", "--kind", "validation", "--duration", "60", "--seed", str(SIM_VALIDATION_SEED),
              "--out", str(validation))
    cases = []
    for seed in SIM_SEEDS:
        run = work / f"sim-identification-{seed}-{duration:g}s"
        if not (run / "dataset.npz").is_file():
            dynid("simulate", "--kind", "identification", "--duration", f"{duration:g}", "--seed", str(seed),
                  "--out", str(run))
        cases.append(Case(f"sim{seed}-{duration:g}s", ("--data", str(run)), [
            Validation(f"cross-run: validation seed {SIM_VALIDATION_SEED}", ("--data", str(validation)), 6)]))
    return Robot("simulated arm", cases)


def icub_leg(real: Path) -> Robot | None:
    leg = real / "icub_leg_insitu"
    if not (leg / "dumperLeftLegNoIMU").is_dir():
        return None
    dump = str(leg / "dumperLeftLegNoIMU")
    robot = ("--robot", "icub_right_leg_standing", "--urdf", str(leg / "iCubGenova02.urdf"))
    # the documented window, then the swing's two halves (tools/benchmarks/out_of_sample.py's folds), each
    # validated on the other's blocks
    return Robot("iCub leg", [
        Case("leg-23-47", (*robot, "--data", dump, "--from", "23", "--to", "47"), [
            Validation("cross-block: 14-65 s", ("--data", dump, "--from", "14", "--to", "65"), 6)]),
        Case("leg-14-39.5", (*robot, "--data", dump, "--from", "14", "--to", "39.5"), [
            Validation("cross-block: 39.5-65 s", ("--data", dump, "--from", "39.6", "--to", "65"), 3)]),
        Case("leg-39.5-65", (*robot, "--data", dump, "--from", "39.5", "--to", "65"), [
            Validation("cross-block: 14-39.5 s", ("--data", dump, "--from", "14", "--to", "39.4"), 3)]),
    ])


def ur10e(real: Path) -> Robot | None:
    ur = real / "ur10e_mamedov"
    if not ur.is_dir():
        return None
    robot = ("--robot", "ur10e_known_gains", "--urdf", str(ur / "ur10e.urdf"))
    fitted = ur / "identification" / "ur-20_02_19_14harm50sec.csv"
    others = [("ur-20_02_05-20sec_8harm.csv", 4), ("ur-20_02_10-30sec_12harm.csv", 6),
              ("ur-20_02_12-50sec_12harm.csv", 10)]
    validations = [Validation(f"cross-run: {name}", ("--data", str(ur / "identification" / name)), k)
                   for name, k in others]
    validations.append(Validation("cross-run: ptp_10_points", (
        "--data", str(ur / "validation" / "ur-20_01_17-ptp_10_points.csv")), 5))
    return Robot("UR10e", [Case("ur10e-14harm", (*robot, "--data", str(fitted)), validations)])


def panda(real: Path, work: Path) -> Robot | None:
    if not (real / "panda_gaz2019").is_dir():
        return None
    from tests.realdata import convert

    data = work / "panda.csv"
    if not data.is_file():
        convert.convert_panda(real / "panda_gaz2019").write(data)
    whole = ("--data", str(data))
    return Robot("Panda", [
        Case("panda-first-2-3", ("--robot", "panda", *whole, "--to", "13.9189"),
             [Validation("cross-block: the last third", whole, 6)]),
        Case("panda-last-2-3", ("--robot", "panda", *whole, "--from", "7.01"),
             [Validation("cross-block: the first third", whole, 6)]),
    ])


def tiago(real: Path, work: Path) -> Robot | None:
    source = real / "tiago_wrist_ft"
    if not source.is_dir():
        return None
    from tests.realdata import convert

    data = work / "tiago.csv"
    if not data.is_file():
        convert.convert_tiago(source).write(data)
    robot = ("--robot", "tiago_wrist", "--urdf", str(source / "urdf" / "tiago_48_hey5.urdf"))
    return Robot("TIAGo wrist", [Case("tiago-protocol", (*robot, "--data", str(data), "--from", "9.210663557", "--to",
                                                         "67.900500059"),
                                      [Validation("cross-block: outside rows 921-6790", ("--data", str(data)), 16)])])


INPUTS = {"simulated arm": "PWM", "UR10e": "currents", "iCub leg": "inputs", "Panda": "torques",
          "TIAGo wrist": "inputs"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--realdata", type=Path, default=ROOT.parent / "shared" / "realdata")
    ap.add_argument("--work", type=Path, required=True, help="models, simulated runs and converted CSVs (reused)")
    ap.add_argument("--sim-duration", type=float, default=60.0, help="seconds of each simulated identification run")
    ap.add_argument("--only", nargs="*", default=["sim", "icub_leg", "ur10e", "panda", "tiago"])
    ap.add_argument("--json", type=Path, help="write the table and every held-out block's figures here")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("DYNID_REALDATA", str(args.realdata))
    makers = {"sim": lambda: sim_arm(args.work, args.sim_duration), "icub_leg": lambda: icub_leg(args.realdata),
              "ur10e": lambda: ur10e(args.realdata), "panda": lambda: panda(args.realdata, args.work),
              "tiago": lambda: tiago(args.realdata, args.work)}
    rows, per_channel, robots = [], [], []
    for key in args.only:
        robot = makers[key]()
        if robot is None:
            print(f"{key}: skipped, no data under {args.realdata}", flush=True)
            continue
        print(f"{robot.name}:", flush=True)
        run_robot(robot, args.work, INPUTS[robot.name])
        robots.append(robot)
        rows += table(robot, INPUTS[robot.name])
        per_channel += table(robot, INPUTS[robot.name], channels=True)
    header = ("| robot | {} | held-out blocks | worst, off | worst, on | median, off | median, on | "
              "blocks on better / worse | generalises better |\n|---|---|---|---|---|---|---|---|---|")
    print("\n" + header.format("channel group"))
    print_rows(rows)
    print("\nper input channel:\n" + header.format("channel"))
    print_rows(per_channel)
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "per_channel": per_channel, "robots": [
            {"name": r.name, "held_out_blocks": r.where, "values": r.values, "fit_time_s": r.fit_time_s}
            for r in robots]}, indent=1))


if __name__ == "__main__":
    main()
