"""A long log without holding it: a `dynid simulate` run tiled N times into one dataset file, a chunk at a time.

    .venv/bin/python tools/benchmarks/long_log.py --data RUN --times 10 --out LONG.npz [--chunk 200000]

Each tile is the run again, its time shifted to follow the tile before by one sample period. The run should start
and end at rest in the same posture, or the joins are jumps that no filter forgives: a run of `dynid excite`'s
trajectory is (a whole number of Fourier periods, at rest at both ends; `dynid simulate --trajectory`). The
noise repeats from tile to tile; for a memory and time benchmark that does not matter, for statistics it would.

The run is read a window at a time (dynid.io.stream.DatasetFile) and written a chunk at a time
(dynid.io.stream.DatasetWriter): memory stays at one chunk, whatever N. docs/benchmarks.md#a-ten-hour-log.
"""

from __future__ import annotations

import argparse
import resource
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from dynid.config.robot_config import load_config
from dynid.io.stream import DatasetFile, DatasetWriter, open_run


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, help="the run to tile (a dataset file or a `dynid simulate` directory)")
    p.add_argument("--times", type=int, default=10)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--chunk", type=int, default=200_000, help="rows per write")
    p.add_argument("--robot", default="icub_right_arm")
    a = p.parse_args()
    run = open_run(a.data, load_config(a.robot))
    if not isinstance(run, DatasetFile):
        raise SystemExit("long_log: --data must be a dataset file (or a simulate directory) to be read in chunks")
    n, step = run.n_samples, run.median_step()
    t0, t_end = float(run.times(0, 1)[0]), float(run.times(n - 1, n)[0])
    period = t_end - t0 + step
    ends = [run.slice(0, 1), run.slice(n - 1, n)]
    jump = np.max(np.abs(ends[1].q - ends[0].q))
    print(f"tiling {a.data}: {n} samples ({period:.1f} s) × {a.times}; join: |Δq| ≤ {jump:.2e} rad")
    started = time.perf_counter()
    meta = {**run.meta, "source": f"{run.meta.get('source', '')}; tiled ×{a.times} by tools/benchmarks/long_log.py"}
    meta.pop("rows", None)
    with DatasetWriter(a.out, n * a.times, meta) as out:
        for k in range(a.times):
            for lo in range(0, n, a.chunk):
                chunk = run.slice(lo, lo + a.chunk)
                out.write(replace(chunk, t=chunk.t + k * period, meta=meta))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"wrote {a.out}: {n * a.times} samples ({a.times * period / 3600:.2f} h), "
          f"{a.out.stat().st_size / 1e9:.2f} GB in {time.perf_counter() - started:.0f} s, peak RSS {peak:.0f} MB")


if __name__ == "__main__":
    main()
