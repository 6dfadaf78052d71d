"""Where a held-out window's false alarms come from, channel by channel: the model's error against its Λ, and
against the spread of its own prediction over the fit's jackknife folds (the Φ fitted without each time block, which
the model file keeps). An error many times that spread is the model's form at data unlike the fit's, which no
calibration of Λ can foresee; an error within it is the parameters' uncertainty (docs/detection.md#out-of-sample).

    PYTHONPATH=tools python tools/benchmarks/held_out_channels.py MODEL.json RUN FROM TO [FROM TO ...]

RUN is read with the model's robot (a dumper folder, CSV, dataset); each FROM TO (s, the data's own) is one row.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dynid.api import DynamicsModel
from dynid.identify.validation import evaluate, load_run
from dynid.robot.outputs import residuals_many


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", type=Path)
    ap.add_argument("run")
    ap.add_argument("windows", nargs="+", type=float, metavar="FROM TO")
    a = ap.parse_args()
    if len(a.windows) % 2:
        ap.error("windows come in pairs: FROM TO")
    fitted = DynamicsModel.load(a.model)
    identified = fitted.model_
    if identified.folds is None:
        ap.error(f"{a.model} keeps no jackknife folds (an older file, or a gap run's refit): fit it again")
    ds = load_run(a.run, identified.robot_model)
    ev = evaluate(str(a.model), a.run, identified, ds)
    e, *folds = residuals_many(ev.model, [identified.phi, *identified.folds.parameters], ev.signals)
    E = np.stack(folds)
    B = E.shape[0]
    spread = np.sqrt((B - 1) / B * ((E - E.mean(axis=0)) ** 2).sum(axis=0))  # the jackknife's std of ŷ per sample
    if identified.calibrated is None:
        ap.error(f"{a.model} has no calibrated detector")
    variance = identified.calibrated.variance  # Λ of the calibrated detector (the combined one's acceleration half)
    print("| window (s) | channel | mean e²/Λ | rms error | √Λ | jackknife spread of ŷ | error / spread |\n"
          "|---|---|---|---|---|---|---|")
    for lo, hi in zip(a.windows[::2], a.windows[1::2]):
        w = (ds.t >= lo) & (ds.t < hi)
        if not w.any():
            ap.error(f"{lo:g}–{hi:g} s holds no sample of {a.run} ({ds.t[0]:g}–{ds.t[-1]:g} s)")
        for i, name in enumerate(identified.output_channels):
            rms, jk = float(np.sqrt(np.mean(e[w, i] ** 2))), float(np.mean(spread[w, i]))
            print(f"| {lo:g}–{hi:g} | {name} | {np.mean(e[w, i] ** 2) / variance[i]:.3g} | {rms:.3g} | "
                  f"{np.sqrt(variance[i]):.3g} | {jk:.3g} | {rms / jk:.3g} |")


if __name__ == "__main__":
    main()
