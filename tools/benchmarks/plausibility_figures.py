"""The figures behind `dynid fit`'s gravity and free-mass checks (dynid.identify.plausibility): each bundled robot's fit
as its docs/robots page runs it, unconstrained and consistent, and the UR10e and the Panda with gravity given +z.

Per fit: the fitted gravity torques' least-squares slope and correlation against the CAD's over 256 postures within
the joints' limits (`gravity_torques`' statistic), and the bodies whose mass is over 5 times their CAD's
(`masses_far_from_cad`). Reproduce (docs/formats.md, docs/consistency.md):

    PYTHONPATH=tools OMP_NUM_THREADS=1 .venv/bin/python tools/benchmarks/plausibility_figures.py \\
        --sim out/identification --realdata ../shared/realdata --work /tmp/plaus
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from dynid.identify.model_file import load_model  # noqa: E402
from dynid.identify.plausibility import gravity_agreement, masses_far_from_cad  # noqa: E402


def fit(work: Path, name: str, *args: str) -> Path | None:
    out = work / f"{name}.json"
    done = subprocess.run([sys.executable, "-m", "dynid.cli", "fit", *args, "--out", str(out)], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(ROOT / "tools")})
    if done.returncode != 0:
        print(f"{name}: dynid fit failed: {done.stderr.strip()}")
        return None
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sim", type=Path, required=True, help="the default arm's identification run")
    ap.add_argument("--realdata", type=Path, required=True)
    ap.add_argument("--work", type=Path, required=True)
    args = ap.parse_args()
    work, real = args.work, args.realdata
    work.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("DYNID_URDF_PATH", str(real / "icub_leg_insitu"))
    ur = ("--urdf", str(real / "ur10e_mamedov/ur10e.urdf"))
    ur_run = str(real / "ur10e_mamedov/identification/ur-20_02_19_14harm50sec.csv")
    panda = str(real / "panda_gaz2019/rbt_log") + "@:13.9189"
    up = {}
    for name in ("ur10e_known_gains", "panda"):  # the bundled configuration with gravity +z, as a user could write it
        text = (ROOT / "tools/dynid/config/robots" / f"{name}.yaml").read_text()
        up[name] = work / f"{name}_up.yaml"
        up[name].write_text(text.replace("gravity: [0.0, 0.0, -9.81]", "gravity: [0.0, 0.0, 9.81]"))
    runs = {
        "arm": ("--data", str(args.sim)),
        "ur10e_known_gains": ("--robot", "ur10e_known_gains", *ur, "--data", ur_run),
        "ur10e pair": ("--robot", "ur10e", *ur, "--data", ur_run, "--data", ur_run.replace(".csv", "Load.csv"),
                       "--payload", "0", "--payload", "2.805"),
        "panda": ("--robot", "panda", "--data", panda),
        "tiago_wrist": ("--robot", "tiago_wrist", "--urdf", str(real / "tiago_wrist_ft/urdf/tiago_48_hey5.urdf"),
                        "--data", str(real / "tiago_wrist_ft/dynamic") + "@9.2106:67.9006"),
        "icub leg": ("--robot", "icub_right_leg_standing", "--data", str(real / "icub_leg_insitu/dumperLeftLegNoIMU"),
                     "--from", "23", "--to", "47"),
        "ur10e_known_gains, gravity +z": ("--robot", str(up["ur10e_known_gains"]), *ur, "--data", ur_run),
        "panda, gravity +z": ("--robot", str(up["panda"]), "--data", panda),
    }
    print("| fit | consistent | gravity slope | correlation | masses over 5 times CAD |\n|---|---|---|---|---|")
    for name, run in runs.items():
        for consistent in ("off", "on"):
            if "+z" in name and consistent == "on":
                continue
            path = fit(work, f"{name.replace(' ', '_').replace(',', '')}_{consistent}", *run, "--consistent",
                       consistent)
            if path is None:
                continue
            m = load_model(path)
            phi = np.array([m.parameters[n] for n in m.robot_model.layout.names])
            slope, correlation = gravity_agreement(m.robot_model, phi)
            far = "; ".join(w["text"] for w in masses_far_from_cad(m.robot_model, phi)) or "none"
            print(f"| {name} | {consistent} | {slope:.2f} | {correlation:.2f} | {far} |", flush=True)


if __name__ == "__main__":
    main()
