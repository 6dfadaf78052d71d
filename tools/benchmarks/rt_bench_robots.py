"""rt_bench on every bundled robot and on a chain at the monitor's full capacity (issue 30: the core's median per
sample ≤ 1× Pinocchio's rnea on the same robot in the same run, no allocation over 100 000 samples).

    DYNID_URDF_PATH=../shared/realdata/icub_leg_insitu:../shared/realdata/ur10e_mamedov:../shared/realdata/tiago_wrist_ft/urdf \
        .venv/bin/python tools/benchmarks/rt_bench_robots.py [--samples 100000] [--model out/model.dcoef]

Each robot's CAD model is exported (`dynid export --cad --rate HZ`) and timed by `build/rt_monitor/rt_bench`, which
interleaves the acceleration core, the momentum-observer core and the combined detector that runs both (placeholder
gains and κ where the file has none, as a CAD export: timing only; an identified `--model` carries its own), and
Pinocchio's rnea on the same chain, and counts the core's heap allocations. The full-capacity chain is
generated here: capacity.hpp's joints, one F/T sensor per group of joints up to its sensors, every joint with a
torque sensor (6 × sensors + joints outputs). Robots whose URDF is not found are listed as skipped.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RT_BENCH = ROOT / "build" / "rt_monitor" / "rt_bench"
sys.path.insert(0, str(ROOT / "tools"))

from dynid.export.capacity import capacity  # noqa: E402

# robot -> the rate its boards sample at (Hz), as tools/tests/test_rt_robots.py exports them
ROBOTS = {"icub_right_arm": 1000, "icub_right_leg_standing": 100, "ur10e": 500, "ur10e_known_gains": 500,
          "panda": 1000, "tiago_wrist": 100}


def full_capacity_robot(folder: Path) -> Path:
    """A serial chain of capacity().joints revolute joints (axes z, y, x in turn, 0.1 m links of 1 kg) with an F/T
    sensor after every len/sensors joints, each joint with a torque sensor: the configuration and its URDF."""
    cap = capacity()
    n, sensors = cap.joints, cap.sensors
    every = n // sensors
    links = ['<link name="base"/>']
    joints, ft_names = [], []
    parent = "base"
    for j in range(1, n + 1):
        axis = ("0 0 1", "0 1 0", "1 0 0")[j % 3]
        link = f"l{j}"
        joints.append(f'<joint name="j{j}" type="revolute"><parent link="{parent}"/><child link="{link}"/>'
                      f'<origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="{axis}"/>'
                      f'<limit lower="-3" upper="3" effort="100" velocity="5"/></joint>')
        links.append(f'<link name="{link}"><inertial><origin xyz="0.01 0.005 0.05"/><mass value="1.0"/>'
                     f'<inertia ixx="0.004" ixy="0.0001" ixz="0.0" iyy="0.0035" iyz="0.0" izz="0.001"/></inertial></link>')
        parent = link
        if j % every == 0 and len(ft_names) < sensors:
            ft = f"ft{len(ft_names) + 1}"
            sensor_link = f"{ft}_link"
            joints.append(f'<joint name="{ft}" type="fixed"><parent link="{parent}"/><child link="{sensor_link}"/>'
                          f'<origin xyz="0 0 0.02"/></joint>')
            links.append(f'<link name="{sensor_link}"><inertial><origin xyz="0 0 0.01"/><mass value="0.2"/>'
                         f'<inertia ixx="0.0002" ixy="0" ixz="0" iyy="0.0002" iyz="0" izz="0.0001"/></inertial></link>')
            ft_names.append(ft)
            parent = sensor_link
    urdf = folder / "full_capacity.urdf"
    urdf.write_text('<?xml version="1.0"?>\n<robot name="full_capacity">\n  ' + "\n  ".join(links + joints) +
                    "\n</robot>\n")
    names = ", ".join(f"j{j}" for j in range(1, n + 1))
    sensors_yaml = "".join(f"  - {{name: {ft}, joint: {ft}, noise: {{force: 0.1, torque: 0.01}}}}\n" for ft in ft_names)
    config = folder / "full_capacity.yaml"
    config.write_text(f"name: full_capacity\nurdf: {{supplied: {urdf.name}}}\nbase_link: base\n"
                      f"gravity: [0.0, 0.0, -9.81]\njoints: [{names}]\nft_sensors:\n{sensors_yaml}"
                      f"actuation:\n  - name: all\n    input: torque\n    joints: [{names}]\n"
                      f"noise:\n  torque: 0.1\n  encoder_step: 1.0e-5\n")
    return config


def bench(coef: Path, samples: int) -> dict[str, str]:
    done = subprocess.run([str(RT_BENCH), str(coef), "--samples", str(samples)], capture_output=True, text=True,
                          timeout=900)
    if done.returncode != 0:
        raise SystemExit(f"rt_bench {coef}: exit {done.returncode}: {done.stderr.strip() or done.stdout}")
    out = done.stdout

    def median(label: str) -> float:
        return float(re.search(rf"{re.escape(label)}\s+median\s+([\d.]+) ns", out).group(1))

    head = re.search(r"rt_bench: [^,]+, (\d+) joints, (\d+) outputs, filter window (\d+)", out)
    acc, obs, rnea = median("full core step"), median("observer core step"), median("pinocchio::rnea")
    allocs = re.search(r"heap allocations in (\d+) core steps: (\d+)", out)
    both = median("combined core step")
    return {"shape": f"{head.group(1)} joints, {head.group(2)} outputs, window {head.group(3)}",
            "core": f"{acc / 1e3:.2f} µs ({acc / rnea:.2f}×)", "observer": f"{obs / 1e3:.2f} µs ({obs / rnea:.2f}×)",
            "combined": f"{both / 1e3:.2f} µs ({both / rnea:.2f}×)",
            "rnea": f"{rnea / 1e3:.2f} µs", "allocations": f"{allocs.group(2)} in {allocs.group(1)}",
            "placeholder": "placeholder gains" in out, "worst": max(acc, obs, both) / rnea}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=100_000, help="samples timed per robot (default 100 000)")
    ap.add_argument("--model", type=Path, action="append", default=[],
                    help="an exported coefficient file to time as well (repeatable), e.g. out/model.dcoef")
    args = ap.parse_args()
    # rt_bench is not in the default build (no test runs it): built here, a no-op when it is up to date
    if subprocess.run(["cmake", "--build", str(ROOT / "build"), "--target", "rt_bench"], capture_output=True).returncode:
        raise SystemExit(f"cannot build rt_bench in {ROOT / 'build'} (run scripts/setup first)")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        full = full_capacity_robot(work)
        env = {**os.environ, "DYNID_URDF_PATH": os.pathsep.join([str(work), os.environ.get("DYNID_URDF_PATH", "")])}
        targets = [(name, ["--robot", name, "--rate", str(rate)]) for name, rate in ROBOTS.items()]
        targets.append(("full capacity (generated)", ["--robot", str(full), "--rate", "1000"]))
        for name, export_args in targets:
            coef = work / f"{len(rows)}.dcoef"
            done = subprocess.run([sys.executable, "-m", "dynid.cli", "export", "--cad", *export_args, "--out",
                                   str(coef)], capture_output=True, text=True, env=env, timeout=600)
            if done.returncode != 0:
                print(f"{name}: skipped: {done.stderr.strip()}", file=sys.stderr)
                continue
            rows.append((f"{name} (CAD)", bench(coef, args.samples)))
            print(f"{name}: done", file=sys.stderr)
        for path in args.model:
            rows.append((str(path), bench(path, args.samples)))
    print("| robot | shape | acceleration core (÷ rnea) | observer core (÷ rnea) | combined core (÷ rnea) | rnea | "
          "core allocations |")
    print("|---|---|---|---|---|---|---|")
    for name, r in rows:
        note = " ¹" if r["placeholder"] else ""
        print(f"| {name} | {r['shape']} | {r['core']} | {r['observer']}{note} | {r['combined']}{note} | {r['rnea']} | "
              f"{r['allocations']} |")
    if any(r["placeholder"] for _, r in rows):
        print("\n¹ the file carries no observer: rt_bench gives it placeholder gains and κ, for timing only")
    worst = max(rows, key=lambda r: r[1]["worst"])
    print(f"\nworst ratio to rnea: {worst[1]['worst']:.2f} ({worst[0]})")


if __name__ == "__main__":
    main()
