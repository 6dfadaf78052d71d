"""Benchmark: `dynid fit` on long logs, streamed, against the same fit with the log held in memory (issue 33).

For each --data: `dynid fit --data LOG` as a user runs it (the log is a dataset file, read a window at a time),
its wall time and its peak memory, both sampled every 0.1 s with psutil: the largest resident set of any one
process (the fit or one of its forked workers), and the largest sum over the process tree (forked workers share
pages with the fit, so the sum counts those twice: an upper bound).

The reference, in the same run, on the first --data: the same fit through the Python API with the log loaded whole
(`load_data`), as `dynid fit` read every log before issue 33.

    .venv/bin/python tools/benchmarks/bench_long.py --data ONE_HOUR [--data TEN_HOURS ...] [--no-reference]
        [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import psutil

IN_MEMORY = textwrap.dedent("""
    import sys
    from dynid.config.robot_config import load_config
    from dynid.io.load import load_data
    from dynid.pipeline import identify
    from dynid.robot.model import RobotModel
    model = RobotModel(load_config("icub_right_arm"))
    data = sys.argv[1]
    done = identify(model, [load_data(data, model.config, model.joint_limits)], [data])
    done.model.save(sys.argv[2])
""")


def measured(cmd: list[str]) -> dict:
    """Wall time, the largest single-process peak and the largest sampled tree sum (MB) of one command."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    top = psutil.Process(proc.pid)
    tree_peak = single_peak = 0
    while proc.poll() is None:
        sizes = []
        try:
            for p in [top, *top.children(recursive=True)]:
                try:
                    sizes.append(p.memory_info().rss)
                except psutil.Error:
                    pass
        except psutil.Error:
            pass
        tree_peak, single_peak = max(tree_peak, sum(sizes)), max([single_peak, *sizes])
        time.sleep(0.1)
    out, err = proc.communicate()
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"bench_long: {' '.join(cmd[:6])} … failed: {err.strip()[-600:]}")
    return {"wall_s": wall, "tree_peak_mb": tree_peak / 2**20, "process_peak_mb": single_peak / 2**20,
            "stdout": out.strip().splitlines()[:1]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", action="append", required=True)
    p.add_argument("--no-reference", action="store_true")
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    out = Path(tempfile.mkdtemp(prefix="dynid-bench-long-"))
    results: dict = {"runs": []}
    for i, data in enumerate(a.data):
        cmd = [sys.executable, "-m", "dynid.cli", "fit", "--data", data, "--out", str(out / f"m{i}.json")]
        r = measured(cmd)
        r.update(data=data, command=" ".join(["dynid", *cmd[3:]]))
        results["runs"].append(r)
        print(f"{data}: {r['wall_s']:.0f} s, process tree peak {r['tree_peak_mb']:.0f} MB; {r['stdout']}", flush=True)
    if not a.no_reference:
        r = measured([sys.executable, "-c", IN_MEMORY, a.data[0], str(out / "reference.json")])
        r.update(data=a.data[0], command="identify(load_data(...)) in memory")
        results["reference"] = r
        print(f"reference, in memory, {a.data[0]}: {r['wall_s']:.0f} s, process tree peak {r['tree_peak_mb']:.0f} MB",
              flush=True)
        first = results["runs"][0]
        results["ratios"] = {"time": first["wall_s"] / r["wall_s"], "memory": first["tree_peak_mb"] / r["tree_peak_mb"]}
        print(f"streamed / in memory: time {results['ratios']['time']:.2f}×, memory {results['ratios']['memory']:.2f}×")
    if a.json:
        a.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
