"""The detection report of docs/detection.md: `dynid detect` (the momentum detector beside today's calibrated
and the paper's variant) on the simulated arm and on each real run given, with a ROC figure per run.

    PYTHONPATH=tools OMP_NUM_THREADS=1 python tools/benchmarks/detection_report.py --sim out \
        --realdata ../shared/realdata --work /tmp/detrep --figures docs/figures

Fits what it needs into --work (the simulated arm's default fit; the UR10e with known gains on the 14-harmonic
run; the iCub leg on its swing, 14-65 s), writes the `dynid detect --json` of every run there, prints one table
row per run and variant, and saves docs/figures/detection_roc_<run>.png. Either data source may be left out.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np


def dynid(*args: str) -> None:
    done = subprocess.run([sys.executable, "-m", "dynid.cli", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"dynid {' '.join(args)}: {done.stderr.strip()}")


def runs(sim: Path | None, real: Path | None, work: Path) -> list[tuple[str, list[str]]]:
    """(name, detect arguments) of every run whose data are at hand, fitting the models first."""
    out = []
    if sim is not None and (sim / "contact").is_dir():
        model = work / "arm.json"
        if not model.is_file():
            dynid("fit", "--data", str(sim / "identification"), "--out", str(model))
        out.append(("sim_arm_contact", ["--model", str(model), "--data", str(sim / "contact")]))
        out.append(("sim_arm_validation", ["--model", str(model), "--data", str(sim / "validation")]))
    ur = real / "ur10e_mamedov" if real else None
    if ur is not None and ur.is_dir():
        model = work / "ur.json"
        if not model.is_file():
            dynid("fit", "--robot", "ur10e_known_gains", "--urdf", str(ur / "ur10e.urdf"), "--data",
                  str(ur / "identification" / "ur-20_02_19_14harm50sec.csv"), "--out", str(model))
        for name in ("collision_3link", "ur-20_01_22-push_pose_1"):
            out.append((f"ur10e_{name.split('-')[-1]}", ["--model", str(model), "--data", str(ur / "contact" / f"{name}.csv"),
                        "--episodes", str(ur / "contact" / f"{name}.episodes.csv"), "--label-widening", "0.1"]))
    leg_root = real / "icub_leg_insitu" if real else None
    if leg_root is not None and leg_root.is_dir():
        leg, model = leg_root / "dumperLeftLegNoIMU", work / "leg.json"
        if not model.is_file():
            dynid("fit", "--robot", "icub_right_leg_standing", "--urdf", str(leg_root / "iCubGenova02.urdf"),
                  "--data", str(leg), "--from", "14", "--to", "65", "--consistent", "off", "--out", str(model))
        labels = work / "icub_leg.episodes.csv"  # both feet on the ground before the lift and after the put-down
        labels.write_text("t_start,t_end\n0,13.1\n65.6,1000\n")
        out.append(("icub_leg", ["--model", str(model), "--data", str(leg), "--episodes", str(labels),
                                 "--calibration", str(leg), "--calibration-from", "14", "--calibration-to", "65"]))
    return out


def figure(name: str, result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.2, 4.0))
    for variant, s in result["variants"].items():
        if "roc" in s:
            ax.plot(s["roc"]["fpr"], s["roc"]["tpr"], label=f"{variant} (AUC {s['auc']:.3f})")
            ax.plot([s["fpr"]], [s["tpr"]], "o", color=ax.lines[-1].get_color())
    ax.plot([0, 1], [0, 1], ":", color="grey")
    ax.set(xlabel="false-positive rate (per sample)", ylabel="true-positive rate", title=name, xlim=(0, 1), ylim=(0, 1))
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, help="a directory holding the default identification, validation, contact runs")
    ap.add_argument("--realdata", type=Path, help="the shared real-data directory")
    ap.add_argument("--work", type=Path, required=True, help="where the models and the results go")
    ap.add_argument("--figures", type=Path, help="where the ROC figures go (PNG)")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    print("| run | variant | episodes found (held 10 ms) | onset delay median / p90 / max, ms | FPR | TPR | AUC |")
    print("|---|---|---|---|---|---|---|")
    for name, detect in runs(args.sim, args.realdata, args.work):
        out = args.work / f"{name}.detect.json"
        dynid("detect", *detect, "--json", str(out))
        result = json.loads(out.read_text())
        for variant, s in result["variants"].items():
            d = s.get("delay_s") or {}
            delays = ("/".join("-" if d.get(k) is None else f"{1e3 * d[k]:.0f}" for k in ("median", "p90", "max"))
                      if d else "-")
            tpr = "-" if s.get("tpr") is None else f"{100 * s['tpr']:.1f} %"
            held = (s.get("episodes_sustained") or {}).get("found")  # the level held as the monitor's onset
            found = f"{s['episodes_detected']}/{s['episodes']} ({held})" if s.get("episodes") else "-"
            auc = s.get("auc")
            auc = f"{auc:.3f}" if auc is not None and np.isfinite(auc) else "-"  # no contact labelled: no ROC
            print(f"| {name} | {variant} | {found} | {delays} | {100 * s['fpr']:.2f} % | {tpr} | {auc} |")
        if args.figures is not None and any("roc" in s for s in result["variants"].values()):
            args.figures.mkdir(parents=True, exist_ok=True)
            figure(name, result, args.figures / f"detection_roc_{name}.png")


if __name__ == "__main__":
    main()
