"""The real-time core's figures of the README's "Real-time core" section, measured end to end:

    .venv/bin/python tools/benchmarks/rt_report.py [WORKDIR]

simulates the default identification, validation and contact runs (or reuses them in WORKDIR), fits, exports,
replays the validation and contact runs through rt_eval (the C++ core) and prints FPR, TPR, the side, and the
number of onset events; then runs rt_bench on the exported model. Needs scripts/setup's build/.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from dynid.export.rt_eval_io import raw_samples, run_stream

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "rt_monitor"


def dynid(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "dynid.cli", *args], check=True, stdout=subprocess.DEVNULL)


def replay(coef: Path, raw: np.ndarray, work: Path) -> np.ndarray:
    return run_stream(BUILD / "rt_eval", coef, raw, work)


def main() -> None:
    from dynid.config.robot_config import load_config
    from dynid.export.coefficients import read_coefficients
    from dynid.io.load import load_data

    work = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="rt_report"))
    for kind in ("identification", "validation", "contact"):
        if not (work / kind).is_dir():
            dynid("simulate", "--kind", kind, "--out", str(work / kind))
    model, coef = work / "model.json", work / "model.dcoef"
    if not model.is_file():
        dynid("fit", "--data", str(work / "identification"), "--out", str(model))
    dynid("export", "--model", str(model), "--out", str(coef))
    c = read_coefficients(coef)
    config = load_config(c.robot_name)
    print(f"coefficient file {coef}: T²_α {c.threshold:.4g} (α {c.alpha}), filter window {c.window} lag {c.lag}")
    for kind in ("validation", "contact"):
        ds = load_data(work / kind, config)
        raw = raw_samples(ds, c)
        out = replay(coef, raw, work)
        ready, above, onsets = out[:, 0] == 1, out[:, -4] == 1, out[:, -2] == 1
        truth, side = np.zeros(len(out), bool), np.zeros(len(out))
        if ds.contact is not None:
            truth[c.lag :] = ds.contact[: -c.lag] != 0  # output k is the estimate of sample k − lag
            side[c.lag :] = ds.extra["skin.side"][: -c.lag]
        line = f"  {kind}: FPR {100 * above[ready & ~truth].mean():.2f} %, {int(onsets.sum())} onset events"
        if truth.any():
            from dynid.io.dataset import contact_episodes as episodes

            delays, missed = [], 0
            for a, b in episodes(truth.astype(int)):
                k = np.flatnonzero(onsets[a:b])
                if k.size:  # from the contact's first sample to the event, the filter's lag included
                    delays.append((k[0] + c.lag) * c.sample_period)
                else:
                    missed += 1
            line += (f", episodes with an onset {len(delays)}/{len(delays) + missed}, onset delay median "
                     f"{1e3 * np.median(delays):.0f} ms")
            line += f", TPR {100 * above[ready & truth].mean():.1f} %"
            for code, name in ((1, "distal"), (-1, "proximal")):
                sel = ready & truth & (side == code)
                line += (f"; {name} TPR {100 * above[sel].mean():.1f} %, side right on "
                         f"{100 * (out[sel & above, -1] == code).mean():.1f} % of its alarms")
        print(line)
    subprocess.run(["cmake", "--build", str(ROOT / "build"), "--target", "rt_bench"], check=True,
                   capture_output=True)  # not in the default build: no test runs it
    subprocess.run([str(BUILD / "rt_bench"), str(coef)], check=True)


if __name__ == "__main__":
    main()
