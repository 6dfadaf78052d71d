"""α out of sample (issue 30): false positives at α = 0.99 on contact-free data the fit and the calibration never saw.

For each robot: fit on part of its data, then `dynid detect` on contact-free data left out; print the FPR of the
detectors calibrated on cross-validated residuals (today's default) beside the FPR the in-sample calibration gives
on the same samples (`in_sample_calibration_fpr`). Reproduce (docs/detection.md#out-of-sample):

    PYTHONPATH=tools OMP_NUM_THREADS=1 python tools/benchmarks/out_of_sample.py --sim /tmp/sim \
        --realdata ../shared/realdata --work /tmp/oos

--sim DIR holds `identification` (seed 0) and held-out contact-free runs `validation*` (`dynid simulate --kind
validation --seed N`); a run missing is skipped, as is a robot whose real data are not at hand.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def dynid(*args: str) -> dict:
    done = subprocess.run([sys.executable, "-m", "dynid.cli", *args, "--json", "-"], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT / "tools")})
    if done.returncode != 0:
        raise SystemExit(f"dynid {' '.join(args)}: {done.stderr.strip()}")
    return json.loads(done.stdout)


def row(robot: str, run: str, result: dict) -> dict:
    out = {"robot": robot, "run": run, "outside": result["out_of_sample"]["data_outside_fit_and_calibration"]}
    for name, v in result["out_of_sample"]["variants"].items():
        out[name] = (v["fpr"], v["in_sample_calibration_fpr"])
    print(f"| {robot} | {run} | " + " | ".join(
        f"{100 * out[n][0]:.2f} % / " + ("-" if out[n][1] is None else f"{100 * out[n][1]:.2f} %")
        for n in ("combined", "momentum", "calibrated") if n in out) + f" | {'yes' if out['outside'] else 'NO'} |", flush=True)
    return out


def sim(sim_dir: Path, work: Path) -> list[dict]:
    model = work / "arm.json"
    if not model.is_file():
        dynid("fit", "--data", str(sim_dir / "identification"), "--out", str(model))
    return [row("sim arm", v.name, dynid("detect", "--model", str(model), "--data", str(v)))
            for v in sorted(sim_dir.glob("validation*")) if v.is_dir()]


def ur10e(real: Path, work: Path) -> list[dict]:
    ur = real / "ur10e_mamedov"
    model = work / "ur.json"
    robot = ("--robot", "ur10e_known_gains", "--urdf", str(ur / "ur10e.urdf"))
    fitted = ur / "identification" / "ur-20_02_19_14harm50sec.csv"
    if not model.is_file():
        dynid("fit", *robot, "--data", str(fitted), "--out", str(model))
    out = []
    for run in sorted((ur / "identification").glob("*.csv")) + sorted((ur / "validation").glob("*.csv")):
        if run == fitted or "Load" in run.name:  # the loaded run carries a payload the model does not know
            continue
        out.append(row("UR10e", run.name, dynid("detect", "--model", str(model), "--data", str(run))))
    for name in ("collision_3link", "ur-20_01_22-push_pose_1"):
        run = ur / "contact" / f"{name}.csv"
        out.append(row("UR10e", f"{name} outside its episodes", dynid(
            "detect", "--model", str(model), "--data", str(run), "--episodes",
            str(ur / "contact" / f"{name}.episodes.csv"), "--label-widening", "0.1")))
    return out


def panda(work: Path) -> list[dict]:
    from tests.realdata import convert

    conversion = convert.convert_panda()
    full = work / "panda_full.csv"
    conversion.write(full)
    lines = full.read_text().splitlines()
    n = len(lines) - 1
    train, test = work / "panda_train.csv", work / "panda_test.csv"
    train.write_text("\n".join([lines[0], *lines[1 : 1 + 2 * n // 3]]) + "\n")
    test.write_text("\n".join([lines[0], *lines[1 + 2 * n // 3 :]]) + "\n")
    model = work / "panda.json"
    dynid("fit", "--robot", "panda", "--data", str(train), "--out", str(model))
    return [row("Panda", "last third (fit on the first two)", dynid("detect", "--model", str(model), "--data",
                                                                      str(test)))]


def icub_leg(real: Path, work: Path) -> list[dict]:
    leg_root = real / "icub_leg_insitu"
    leg = leg_root / "dumperLeftLegNoIMU"
    robot = ("--robot", "icub_right_leg_standing", "--urdf", str(leg_root / "iCubGenova02.urdf"))
    out = []
    # Two folds of the swing on one foot: from 14 s (after the lift-off transient) to where the stance foot starts to
    # unload (62.4 s, the right foot touching down: tests/realdata/leg_support.py); fit on one half, detect on the other
    from tests.realdata.leg_support import put_down_onset

    end = f"{put_down_onset(leg)[0]:.2f}"
    for fit_window, test_window in ((("14", "39.5"), ("39.5", end)), (("39.5", end), ("14", "39.5"))):
        model = work / f"leg_{fit_window[0]}.json"
        dynid("fit", *robot, "--data", str(leg), "--from", fit_window[0], "--to", fit_window[1], "--consistent", "off",
              "--out", str(model))
        result = dynid("detect", "--model", str(model), "--data", str(leg), "--from", test_window[0], "--to",
                       test_window[1])
        out.append(row("iCub leg", f"swing {test_window[0]}-{test_window[1]} s (fit on {fit_window[0]}-"
                                   f"{fit_window[1]} s)", result))
    # Five time blocks of the swing, each left out of the fit in turn (the fit on the rest: two windows of the run)
    edges = [float(x) for x in np.linspace(14.0, float(end), 6)]
    for k in range(5):
        windows = [(a, b) for a, b in ((edges[0], edges[k]), (edges[k + 1], edges[-1])) if b > a]
        model = work / f"leg_block{k}.json"
        dynid("fit", *robot, *(x for a, b in windows for x in ("--data", f"{leg}@{a!r}:{b!r}")), "--consistent",
              "off", "--out", str(model))
        result = dynid("detect", "--model", str(model), "--data", str(leg), "--from", repr(edges[k]), "--to",
                       repr(edges[k + 1]))
        outside = result["out_of_sample"].get("postures_outside_fit") or []
        out.append(row("iCub leg", f"block {k + 1} of 5, {edges[k]:.2f}-{edges[k + 1]:.2f} s (postures beyond the "
                                   f"fit's: {max((o['outside_share'] for o in outside), default=0):.0%})", result))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sim", type=Path)
    ap.add_argument("--realdata", type=Path)
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--only", nargs="*", default=["sim", "ur10e", "panda", "icub_leg"])
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    print("| robot | contact-free run | combined (the default): FPR cross-validated / - | momentum: FPR cross-validated / "
          "in-sample calibration | calibrated: the same | outside the fit |\n|---|---|---|---|---|---|", flush=True)
    rows = []
    if args.sim and "sim" in args.only:
        rows += sim(args.sim, args.work)
    real = args.realdata
    if real and (real / "ur10e_mamedov").is_dir() and "ur10e" in args.only:
        rows += ur10e(real, args.work)
    if real and (real / "panda_gaz2019").is_dir() and "panda" in args.only:
        rows += panda(args.work)
    if real and (real / "icub_leg_insitu").is_dir() and "icub_leg" in args.only:
        rows += icub_leg(real, args.work)
    (args.work / "out_of_sample.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
