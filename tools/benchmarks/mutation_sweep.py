"""The mutation sweep (issue 31; docs/fuzzing.md "The mutation sweep"): well-formed but wrong inputs to rt_monitor,
as an edit, an exporter bug or a wrong board address would make them, each replayed and classified.

    .venv/bin/python tools/benchmarks/mutation_sweep.py [--work DIR] [--model COEF] [--data RUN] [--every N]
        [--only config|coefficients] [--json OUT] [--append-docs]

Inputs: the monitor configuration dynid compiles for the bundled arm (`dynid export --monitor-config`), the
coefficient file of the default model (or --model), and 20 s of the default contact run (or --data) from 1 s before
its first contact, as a candump log.
- configuration: every line deleted, duplicated, swapped with the next; every number of every line set to 0, −1,
  1e-300, 1e300, NaN, a hex integer and an out-of-range integer;
- coefficient file (CRC valid: the wrapper is rebuilt around the mutated payload): every numeric field, all its
  elements at once, set to 0, negated, 1e-300, 1e300 and NaN (the integers: 0, −1, 2³¹−1).
Each mutation is replayed (`rt_monitor --replay`) and classified against the unmutated replay:
- refused: exit 2 or 10-22 at load, with one line on stderr;
- flagged: the watchdog raised a status fault (`faults_seen`, the replay's exit 7), or the run exited 6 (evaluated nothing, ended blind);
- harmless: exit 0, no fault, the same samples evaluated and the same events (kind, time, side);
- SILENT: anything else that exited normally (changed events, or fewer samples, and no word): the defect class;
- broken: a crash, a signal, or more than one line for a refusal.
Prints the counts and the silent and broken mutations; exit 1 if any is silent or broken. --every N replays every
N-th mutation only (the test's bounded subset). --append-docs adds the counts as a row of docs/fuzzing.md's table.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import re
import subprocess
import sys
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"
DOCS = ROOT / "docs" / "fuzzing.md"
TABLE_HEADER = "| date | commit | mutations | refused | flagged | harmless | silent | broken |"
CONFIG_VALUES = ("0", "-1", "1e-300", "1e300", "nan", "0x7fffffff", "99999999")
REAL_VALUES = (("0", 0.0), ("tiny", 1e-300), ("huge", 1e300), ("nan", math.nan))
INT_VALUES = (("0", 0), ("-1", -1), ("max", 2**31 - 1))
WINDOW = 20_000  # samples: 20 s of the contact run at 1 kHz, several episodes
NUMBER = re.compile(r"^[-+]?(0x[0-9a-fA-F]+|(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|nan|inf)$")


@dataclass(frozen=True)
class Mutation:
    kind: str  # config or coefficients
    name: str  # what was changed, readably
    config: str | None = None  # the mutated configuration text
    coef: bytes | None = None  # the mutated coefficient file


@dataclass(frozen=True)
class Replay:
    code: int
    stderr: str
    events: tuple
    evaluated: int
    faults: int


def replay(coef: Path, conf_text: str, log: Path, work: Path, tag: str) -> Replay:
    from dynid.export.monitor_log import read_lcm_log

    lcm = work / f"{tag}.lcmlog"
    conf = work / f"{tag}.conf"
    conf.write_text(re.sub(r"^lcm_url .*$", f"lcm_url file://{lcm}?mode=w", conf_text, flags=re.M))
    try:
        done = subprocess.run([str(RT_MONITOR), "--model", str(coef), "--config", str(conf), "--replay", str(log)],
                              capture_output=True, text=True, timeout=120)
        code, err = done.returncode, done.stderr
    except subprocess.TimeoutExpired:
        code, err = -999, "timed out"
    msgs = read_lcm_log(lcm) if lcm.exists() and lcm.stat().st_size else {}
    for p in (lcm, conf):
        p.unlink(missing_ok=True)
    status = msgs.get("DYNID_STATUS", [])
    faults = 0
    for m in status:
        faults |= m.faults_seen
    events = tuple((int(m.kind), int(m.utime), tuple(int(s) for s in m.side)) for m in msgs.get("DYNID_CONTACT", []))
    return Replay(code, err, events, status[-1].samples_evaluated if status else 0, faults)


def classify(r: Replay, base: Replay) -> str:
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    if r.code == 2 or 10 <= r.code <= 22:  # one error line (a usage error: that line, then the synopsis)
        one_line = bool(lines) and lines[0].startswith("rt_monitor: error: ")
        return "refused" if one_line and (len(lines) == 1 or r.code == 2) else "broken"
    if r.code == 6 or (r.code == 7 and r.faults):  # blind; or read to its end with a fault raised (exit 7 says so)
        return "flagged"
    if r.code != 0:
        return "broken"
    if r.events == base.events and r.evaluated == base.evaluated:
        return "harmless"
    return "silent"


# ---- the mutations --------------------------------------------------------------------------------------------


def config_mutations(text: str) -> Iterator[Mutation]:
    lines = text.splitlines()
    body = [i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")
            and not line.startswith("lcm_url")]
    for i in body:
        def edit(new: list[str], what: str, i: int = i) -> Mutation:
            return Mutation("config", f"line {i + 1} ({lines[i][:48]}): {what}", "\n".join(new) + "\n")
        yield edit(lines[:i] + lines[i + 1:], "deleted")
        yield edit(lines[:i + 1] + lines[i:], "duplicated")
        if i + 1 < len(lines):
            yield edit(lines[:i] + [lines[i + 1], lines[i]] + lines[i + 2:], "swapped with the next")
        tokens = lines[i].split()
        for k, token in enumerate(tokens[1:], 1):
            if not NUMBER.match(token):
                continue
            for value in CONFIG_VALUES:
                if value == token:
                    continue
                changed = tokens[:k] + [value] + tokens[k + 1:]
                yield edit(lines[:i] + [" ".join(changed)] + lines[i + 1:], f"field {k} {token} -> {value}")


def _flat(v) -> list:
    return [y for x in v for y in _flat(x)] if isinstance(v, (list, tuple)) else [v]


def _numeric_fields(c) -> Iterator[tuple[str, bool]]:
    for name in c.__slots__:
        flat = _flat(getattr(c, name))
        if len(flat) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in flat):
            yield name, all(isinstance(x, int) for x in flat)


def _set_all(v, f: Callable):
    return [_set_all(x, f) for x in v] if isinstance(v, (list, tuple)) else f(v)


def coefficient_mutations(path: Path) -> Iterator[Mutation]:
    from dynid.export.coefficients import unwrap, wrap
    from dynid.export.lcm_coefficients import coefficients_t

    original = coefficients_t.decode(unwrap(path.read_bytes()))
    for name, integer in _numeric_fields(original):
        values = INT_VALUES if integer else REAL_VALUES + (("negative", None),)
        for label, value in values:
            c = coefficients_t.decode(unwrap(path.read_bytes()))
            setattr(c, name, _set_all(getattr(c, name), (lambda x, value=value: -x if value is None else value)))
            try:
                payload = c.encode()
            except Exception as e:  # a count the arrays do not match cannot even be encoded: not a file to try
                yield Mutation("coefficients", f"{name} -> {label}: not encodable ({type(e).__name__})")
                continue
            yield Mutation("coefficients", f"{name} -> {label}", coef=wrap(payload))


# ---- the run --------------------------------------------------------------------------------------------------


def make_inputs(work: Path, model: Path | None, data: Path | None) -> tuple[Path, str, Path]:
    """The coefficient file, the configuration text and the candump log."""
    from dynid.config.robot_config import load_config
    from dynid.export.monitor_config import monitor_config_text
    from dynid.io.candump import write_candump
    from dynid.io.load import load_data

    config = load_config("icub_right_arm")
    dynid = [sys.executable, "-m", "dynid.cli"]
    if data is None:
        data = work / "contact"
        if not (data / "data.csv").exists():
            subprocess.run(dynid + ["simulate", "--kind", "contact", "--out", str(data)], check=True, capture_output=True)
    if model is None:
        model = work / "model.dcoef"
        if not model.exists():
            ident = work / "identification"
            if not (ident / "data.csv").exists():
                subprocess.run(dynid + ["simulate", "--kind", "identification", "--out", str(ident)], check=True,
                               capture_output=True)
            subprocess.run(dynid + ["fit", "--robot", "icub_right_arm", "--data", str(ident), "--out",
                                    str(work / "model.json")], check=True, capture_output=True)
            subprocess.run(dynid + ["export", "--model", str(work / "model.json"), "--out", str(model)], check=True,
                           capture_output=True)
    run = load_data(data, config)
    head = (Path(data) / "data.csv").open().readline().strip().split(",")
    contact = np.loadtxt(Path(data) / "data.csv", delimiter=",", skiprows=1, usecols=head.index("contact"))
    start = max(int(np.flatnonzero(contact > 0)[0]) - 1000, 0) if contact.any() else 0
    log = work / "sweep.log"
    write_candump(run.slice(start, min(start + WINDOW, run.n_samples)), config, log)
    return model, monitor_config_text(config, "file:///dev/null?mode=w"), log


def sweep(work: Path, model: Path | None = None, data: Path | None = None, every: int = 1,
          only: str | None = None, progress: bool = True) -> dict:
    coef, conf_text, log = make_inputs(work, model, data)
    base = replay(coef, conf_text, log, work, "base")
    if base.code != 0 or base.faults or not base.events:
        raise RuntimeError(f"the unmutated replay must run clean with events: exit {base.code}, faults {base.faults}, "
                           f"{len(base.events)} events, {base.stderr.strip()[-300:]}")
    mutations: list[Mutation] = []
    if only in (None, "config"):
        mutations += list(config_mutations(conf_text))
    if only in (None, "coefficients"):
        mutations += list(coefficient_mutations(coef))
    chosen = mutations[::every]

    def run(k_m: tuple[int, Mutation]) -> tuple[Mutation, str, Replay | None]:
        k, m = k_m
        if m.config is None and m.coef is None:
            return m, "not applicable", None
        path = coef
        if m.coef is not None:
            path = work / f"m{k}.dcoef"
            path.write_bytes(m.coef)
        r = replay(path, m.config if m.config is not None else conf_text, log, work, f"m{k}")
        if m.coef is not None:
            path.unlink(missing_ok=True)
        return m, classify(r, base), r

    results = []
    with ThreadPoolExecutor(max_workers=2) as pool:  # two cores; each replay is one process
        for i, done in enumerate(pool.map(run, enumerate(chosen))):
            results.append(done)
            if progress and (i + 1) % 100 == 0:
                print(f"  {i + 1}/{len(chosen)} replayed", file=sys.stderr, flush=True)
    counts = Counter(c for _, c, _ in results)
    by_kind = {k: dict(Counter(c for m, c, _ in results if m.kind == k)) for k in ("config", "coefficients")}
    bad = [{"kind": m.kind, "mutation": m.name, "class": c, "exit": r.code if r else None,
            "stderr": r.stderr.strip()[-300:] if r else "", "events": len(r.events) if r else 0,
            "base_events": len(base.events), "evaluated": r.evaluated if r else 0}
           for m, c, r in results if c in ("silent", "broken")]
    return {"mutations": len(chosen), "of": len(mutations), "every": every, "counts": dict(counts), "by_kind": by_kind,
            "silent_or_broken": bad, "base": {"events": len(base.events), "evaluated": base.evaluated}}


def append_docs(result: dict) -> None:
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip() or "?"
    c = result["counts"]
    row = (f"| {datetime.date.today()} | {commit} | {result['mutations']} of {result['of']} | {c.get('refused', 0)} | "
           f"{c.get('flagged', 0)} | {c.get('harmless', 0)} | {c.get('silent', 0)} | {c.get('broken', 0)} |")
    text = DOCS.read_text()
    if TABLE_HEADER not in text:
        raise SystemExit(f"mutation_sweep: {DOCS} has no table header '{TABLE_HEADER}'")
    head, _, rest = text.partition(TABLE_HEADER)
    sep, _, rest = rest.lstrip("\n").partition("\n")
    rows = []
    while rest.startswith("|"):
        line, _, rest = rest.partition("\n")
        rows.append(line)
    DOCS.write_text(head + TABLE_HEADER + "\n" + sep + "\n" + "\n".join(rows + [row]) + "\n" + rest)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, default=None, help="where the inputs are made and kept (default: a temporary "
                    "directory)")
    ap.add_argument("--model", type=Path, default=None, help="the coefficient file (default: the default model's)")
    ap.add_argument("--data", type=Path, default=None, help="a contact run of the bundled arm (default: simulated)")
    ap.add_argument("--every", type=int, default=1, help="replay every N-th mutation only")
    ap.add_argument("--only", choices=("config", "coefficients"), default=None)
    ap.add_argument("--json", type=Path, default=None, help="write the result here")
    ap.add_argument("--append-docs", action="store_true", help="add the counts to docs/fuzzing.md's table")
    args = ap.parse_args(argv)
    if args.every < 1:
        ap.error("--every must be at least 1")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        result = sweep(work, args.model, args.data, args.every, args.only)
    c = result["counts"]
    print(f"mutation sweep: {result['mutations']} of {result['of']} mutations: " +
          ", ".join(f"{k} {c.get(k, 0)}" for k in ("refused", "flagged", "harmless", "silent", "broken",
                                                     "not applicable")))
    for b in result["silent_or_broken"]:
        print(f"  {b['class'].upper()}: {b['kind']}: {b['mutation']}: exit {b['exit']}, events {b['events']} "
              f"(unmutated {b['base_events']}), evaluated {b['evaluated']}; {b['stderr'][-160:]}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    if args.append_docs:
        append_docs(result)
    return 1 if result["silent_or_broken"] else 0


if __name__ == "__main__":
    sys.exit(main())
