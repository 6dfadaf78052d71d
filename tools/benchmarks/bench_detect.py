"""Benchmark: `dynid detect` on the default contact run, against the path it replaced, in the same run.

- new: `dynid detect --model MODEL --data DATA` as a user runs it (the compiled kernels; the momentum detector's
  calibration read from the model file's `observer` section).
- reference (the path before issue 32): the same command with the Python references (`DYNID_KERNELS=0`) on a copy
  of MODEL without its `observer` section, so the momentum detector is calibrated again on the identification run,
  as every `detect` did.

The two are run alternately `--repeat` times; the medians and their ratio are printed, and the outputs compared:
the printed report must be identical, the JSON results equal to 1e-9 (relative; 1e-12 absolute near zero).

    .venv/bin/python tools/benchmarks/bench_detect.py --model out/model.json --data out/contact [--repeat 3] [--json F]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run(model: Path, data: Path, out: Path, reference: bool) -> tuple[float, str]:
    env = dict(os.environ, **({"DYNID_KERNELS": "0"} if reference else {}))
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "dynid.cli", "detect", "--model", str(model), "--data", str(data),
                           "--json", str(out)], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"bench_detect: detect failed: {done.stderr.strip().splitlines()[-1:]}")
    return wall, done.stdout


def differences(a, b, path: str = "", scale: float = 0.0) -> list[str]:  # noqa: ANN001 - JSON values
    """Where two JSON results differ beyond 1e-9 relative (1e-12 absolute). A number inside a list of numbers (a
    wrench, a joint vector) is relative to the list's largest magnitude: its components near zero are rounding of the
    vector, not values of their own."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [f"{path}: keys differ"]
        return [d for k in a for d in differences(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: lengths differ"]
        numbers = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in a)
        vector = max((abs(x) for x in a), default=0.0) if numbers else 0.0
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]", vector)]
    if isinstance(a, float) and isinstance(b, (int, float)):
        return [] if abs(a - b) <= max(1e-9 * max(abs(a), scale), 1e-12) else [f"{path}: {a} vs {b}"]
    return [] if a == b else [f"{path}: {a!r} vs {b!r}"]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", type=Path, required=True, help="a model `dynid fit` wrote (with its observer section)")
    p.add_argument("--data", type=Path, required=True, help="the contact run")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--json", metavar="FILE")
    args = p.parse_args()
    record = json.loads(args.model.read_text())
    if "observer" not in record:
        sys.exit(f"bench_detect: {args.model} has no observer section: fit it with this dynid")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        older = tmp / "model_without_observer.json"
        older.write_text(json.dumps({k: v for k, v in record.items() if k != "observer"}))
        new_t, ref_t = [], []
        for _ in range(args.repeat):
            t, new_text = run(args.model, args.data, tmp / "new.json", reference=False)
            new_t.append(t)
            t, ref_text = run(older, args.data, tmp / "ref.json", reference=True)
            ref_t.append(t)
        new_json, ref_json = (json.loads((tmp / f).read_text()) for f in ("new.json", "ref.json"))
    # the two model files' paths are the only difference by construction
    ref_text = ref_text.replace(str(older), str(args.model))
    ref_json["model"] = new_json["model"]
    diff = differences(ref_json, new_json)
    result = {"detect_s": statistics.median(new_t), "reference_s": statistics.median(ref_t),
              "ratio": statistics.median(new_t) / statistics.median(ref_t), "runs": {"new": new_t, "reference": ref_t},
              "report_identical": new_text == ref_text, "json_differences": diff}
    print(f"dynid detect on {args.data}: {result['detect_s']:.2f} s (median of {args.repeat}); the path before issue "
          f"32 (Python references, recalibrating): {result['reference_s']:.2f} s; ratio {result['ratio']:.2f}\n"
          f"  printed report identical: {result['report_identical']}; JSON results equal to 1e-9: {not diff}"
          + (f" ({len(diff)} differences, first {diff[0]})" if diff else ""))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
