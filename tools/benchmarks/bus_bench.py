"""The bus through cantools, timed against the same run as a CSV (docs/benchmarks.md, "CAN and LCM"):

    .venv/bin/python tools/benchmarks/bus_bench.py RUN [--robot CFG] [--repeat N]

RUN is any run dynid reads (e.g. `dynid simulate --kind contact --out RUN`). Per repetition, in one process: the run
written as the robot's candump log (dynid.io.candump.write_candump: every frame encoded by cantools) and read back
(read_candump: every distinct payload decoded by cantools), and, as the reference measured beside them, the same
samples written as an experiment CSV and read back. Prints the medians and the ratios.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))

from dynid.config.robot_config import load_config  # noqa: E402
from dynid.io.candump import read_candump, write_candump  # noqa: E402
from dynid.io.csv_format import read_csv, write_csv  # noqa: E402
from dynid.io.load import load_data  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("--robot", default="icub_right_arm")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    config = load_config(a.robot)
    data = load_data(a.run, config)
    times: dict[str, list[float]] = {k: [] for k in ("candump write", "candump read", "csv write", "csv read")}
    frames = 0
    with tempfile.TemporaryDirectory() as tmp:
        log, csv = Path(tmp) / "run.log", Path(tmp) / "run.csv"
        for _ in range(a.repeat):
            for name, step in (("candump write", lambda: write_candump(data, config, log)),
                               ("candump read", lambda: read_candump(log, config)),
                               ("csv write", lambda: write_csv(data, csv)), ("csv read", lambda: read_csv(csv, config))):
                t = time.perf_counter()
                out = step()
                times[name].append(time.perf_counter() - t)
                frames = out if name == "candump write" else frames
    med = {k: float(np.median(v)) for k, v in times.items()}
    print(f"{a.robot}: {data.n_samples} samples, {frames} frames, {a.repeat} repetitions (medians)")
    for k, v in med.items():
        print(f"  {k}: {v:.3f} s")
    print(f"  candump write / csv write: {med['candump write'] / med['csv write']:.2f}; "
          f"candump read / csv read: {med['candump read'] / med['csv read']:.2f}; "
          f"{frames / med['candump read'] / 1e3:.0f} k frames/s read")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
