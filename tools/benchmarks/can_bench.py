"""The CAN/LCM figures of the README's "CAN and LCM" section, measured here:

    .venv/bin/python tools/benchmarks/can_bench.py WORKDIR [--passes N] [--no-fifo]

WORKDIR holds (or receives) the default identification and contact runs, `dynid fit` and `dynid export` of them
(model.dcoef), and a 300 s contact run (contact300). Then:
- latency: frame-in to LCM-publish of contact onsets through the loopback transport. The boards play, in real
  time, clips of the contact run (1.5 s before to 0.5 s after each contact the F/T sensor sees, back to back;
  the arm's jump at each join raises an onset too, through the same code path), N passes; rt_monitor
  --latency-out records, per onset, CLOCK_MONOTONIC from the return of the read of the frame that completed the
  onset sample to the return of lcm.publish (LCM file:// provider). p50, p99, max.
- throughput: `rt_monitor --replay` of the 300 s contact run's candump log (written by `boards`), frames →
  samples → core → LCM file://, three runs: × real time.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from dynid.config.robot_config import load_config
from dynid.export.mission import BOARDS, RT_MONITOR, fifo_allowed, fifo_args, play
from dynid.export.monitor_config import monitor_config_text


def dynid(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "dynid.cli", *args], check=True, stdout=subprocess.DEVNULL)


def prepare(work: Path) -> Path:
    work.mkdir(parents=True, exist_ok=True)
    for kind, extra in (("identification", ()), ("contact", ()), ("contact300", ("--duration", "300"))):
        if not (work / kind / "data.csv").exists():
            dynid("simulate", "--kind", kind.rstrip("0123456789"), *extra, "--out", str(work / kind))
    coef = work / "model.dcoef"
    if not coef.exists():
        dynid("fit", "--data", str(work / "identification"), "--out", str(work / "model.json"))
        dynid("export", "--model", str(work / "model.json"), "--out", str(coef))
    return coef


def clips(work: Path) -> Path:
    lines = (work / "contact" / "data.csv").read_text().splitlines()
    head = lines[0].split(",")
    side = np.array([float(l.split(",")[head.index("skin.side")]) for l in lines[1:]])
    starts = np.flatnonzero(np.diff(np.r_[0.0, side]) != 0)
    starts = [int(k) for k in starts if side[k] == 1.0 and k >= 1500]
    ti = head.index("t")
    rows, t = [], 0.0
    for a in starts:
        for l in lines[1 + a - 1500: 1 + a + 500]:
            f = l.split(",")
            f[ti] = repr(round(t, 6))
            t += 0.001
            rows.append(",".join(f))
    out = work / "onset_clips.csv"
    out.write_text("\n".join([lines[0]] + rows) + "\n")
    return out


def latency(work: Path, coef: Path, passes: int, fifo: bool) -> None:
    csv = clips(work)
    lat_file = work / "latency_us.txt"
    r = play(coef, csv, work / "latency", realtime=True, monitor_args=("--latency-out", str(lat_file)),
             boards_args=("--repeat", str(passes)) + fifo_args(fifo).get("boards_args", ()),
             monitor_prefix=fifo_args(fifo).get("monitor_prefix", ()))
    v = np.loadtxt(lat_file, ndmin=1)
    print(r["boards"].splitlines()[0])
    print(r["monitor"].strip())
    print(f"latency, frame-in to LCM publish of an onset (loopback, real time{', SCHED_FIFO' if fifo else ''}): "
          f"{v.size} onsets, p50 {np.percentile(v, 50):.1f} µs, p99 {np.percentile(v, 99):.1f} µs, "
          f"max {v.max():.1f} µs")


def throughput(work: Path, coef: Path) -> None:
    log = work / "contact300.log"
    conf = work / "replay.conf"
    conf.write_text(monitor_config_text(load_config("icub_right_arm"), f"file://{work / 'replay.lcmlog'}?mode=w"))
    done = subprocess.run([str(BOARDS), "--config", str(conf), "--data", str(work / "contact300"), "--sink",
                           f"candump:{log}"], check=True, capture_output=True, text=True)
    print(done.stdout.splitlines()[0])
    walls = []
    for _ in range(3):
        t = time.perf_counter()
        done = subprocess.run([str(RT_MONITOR), "--model", str(coef), "--config", str(conf), "--replay", str(log)],
                              check=True, capture_output=True, text=True)
        walls.append(time.perf_counter() - t)
    print(done.stdout.strip())
    print(f"replay throughput, 300 s log ({log.stat().st_size / 1e6:.0f} MB): wall "
          + ", ".join(f"{w:.2f} s" for w in walls) + " → " + ", ".join(f"{300 / w:.0f}×" for w in walls)
          + " real time")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("work", type=Path)
    p.add_argument("--passes", type=int, default=8)
    p.add_argument("--no-fifo", action="store_true")
    p.add_argument("--only", choices=("latency", "throughput"))
    a = p.parse_args()
    coef = prepare(a.work)
    if a.only != "latency":
        throughput(a.work, coef)
    if a.only != "throughput":
        latency(a.work, coef, a.passes, not a.no_fifo and fifo_allowed())


if __name__ == "__main__":
    main()
