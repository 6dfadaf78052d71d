"""The soak (docs/benchmarks.md "Soak"): hours of 1 kHz frames with bus faults through the real rt_monitor, every
counter accounted for against what was injected, zero allocations after start-up, a flat resident set, and a run
paced in real time with no deadline overrun.

    .venv/bin/python tools/benchmarks/soak.py [--work DIR] [--fast S] [--paced S] [--rate HZ] [--every N]
        [--cad --clip S] [--model COEF --data RUN] [--json OUT]          (scripts/soak runs it)

Two runs, each printing one summary line (PASS or FAIL and why); exit 1 if a requirement fails:
- fast: `boards --sink candump:- --repeat R --restart ...` | soak_feed (faults) | `rt_monitor --replay /dev/stdin`,
  as fast as the pipe goes: S seconds of data (rounded up to whole repetitions of the clip), no file of frames.
- paced: boards | soak_feed paced in real time over the loopback transport (kernel-stamped datagrams) |
  `rt_monitor --loopback DIR --mlockall` (both SCHED_FIFO where the system allows it), for S seconds of wall time.
Faults (rt_monitor/bench/soak_feed.cpp): one every N samples, the kinds in turn (drops, duplicates, swaps, a late
sender, error frames, unknown IDs, malformed input, wrong lengths), one board stalled for 2 s at 30 % of the run,
one board restarted at 60 %. The monitor's LCM output is a file:// log in /dev/shm, counted message by message, or
(paced, --lcm udpm) LCM's default UDP multicast inside a private network namespace made for the run, counted by a
subscriber there (tools/tests/netns_lcm_driver.py).
Requirements: every counter equal to what the injection implies (`expected`), the accounting identities
(`identities`), no allocation after start-up outside lcm_publish, the resident set's slope after the first 10 % within
--rss-slope-kb KB/h, and (paced) no sample whose response time exceeds one period.
Data: --model/--data, or --cad (the CAD coefficient file and a simulated contact clip of --clip s), or by default the
default identification and contact runs simulated, fitted and exported in --work (reused when there).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from dynid.config.robot_config import load_config  # noqa: E402
from dynid.export.lcm_messages import monitor_status_t  # noqa: E402
from dynid.export.monitor_config import monitor_config_text  # noqa: E402

BUILD = ROOT / "build"
BOARDS = BUILD / "firmware_like" / "boards"
RT_MONITOR = BUILD / "rt_monitor" / "rt_monitor"
FEED = BUILD / "rt_monitor" / "soak_feed"
MONITOR_FAULTED = 7  # rt_monitor: a replay read to its end that raised a watchdog fault
PROBE = BUILD / "rt_monitor" / "wake_probe"
CAD = ROOT / "rt_monitor" / "tests" / "data" / "icub_cad.dcoef"
DRIVER = ROOT / "tools" / "tests" / "netns_lcm_driver.py"  # subscribes beside the monitor in a private namespace


def dynid(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "dynid.cli", *args], check=True, stdout=subprocess.DEVNULL)


def prepare(a: argparse.Namespace) -> tuple[Path, Path]:
    """The coefficient file and the run's data.csv."""
    if a.model or a.data:
        if not (a.model and a.data):
            sys.exit("soak: --model and --data go together")
        data = Path(a.data)
        return Path(a.model), data / "data.csv" if data.is_dir() else data
    work = Path(a.work) if a.rate == 1000 else Path(a.work) / f"rate{a.rate}"  # runs of another rate kept apart
    work.mkdir(parents=True, exist_ok=True)
    rate = ["--rate", str(a.rate)]
    if a.cad:
        if a.rate != 1000:
            sys.exit("soak: --cad is a 1 kHz coefficient file")
        clip = work / f"contact{a.clip:g}"
        if not (clip / "data.csv").exists():
            dynid("simulate", "--kind", "contact", "--duration", f"{a.clip:g}", *rate, "--out", str(clip))
        return CAD, clip / "data.csv"
    for kind in ("identification", "contact"):
        if not (work / kind / "data.csv").exists():
            dynid("simulate", "--kind", kind, *rate, "--out", str(work / kind))
    coef = work / "model.dcoef"
    if not coef.exists():
        dynid("fit", "--data", str(work / "identification"), "--out", str(work / "model.json"))
        dynid("export", "--model", str(work / "model.json"), "--out", str(coef))
    return coef, work / "contact" / "data.csv"


def csv_samples(csv: Path) -> tuple[int, float]:
    """Rows and the mean sample period (s) of a data.csv."""
    with open(csv) as f:
        head = f.readline().split(",")
        ti = head.index("t")
        first = last = None
        n = 0
        for line in f:
            t = float(line.split(",", ti + 1)[ti])
            first = t if first is None else first
            last = t
            n += 1
    return n, (last - first) / (n - 1)


class RssSampler(threading.Thread):
    """VmRSS of a process every `every` s: (wall s, kB)."""

    def __init__(self, pid: int, every: float):
        super().__init__(daemon=True)
        self.pid, self.every, self.samples, self.stop = pid, every, [], threading.Event()

    def run(self) -> None:
        t0 = time.monotonic()
        while not self.stop.is_set():
            try:
                for line in Path(f"/proc/{self.pid}/status").read_text().splitlines():
                    if line.startswith("VmRSS:"):
                        self.samples.append((time.monotonic() - t0, int(line.split()[1])))
            except (OSError, ValueError):
                return
            self.stop.wait(self.every)


def rss_figures(samples: list[tuple[float, int]], data_per_wall: float) -> dict:
    """The resident set after the first 10 % of the run: first, last, min, max, and the fitted slope in kB per hour
    of wall time and per hour of data."""
    if len(samples) < 4:
        return {"samples": len(samples), "slope_kb_per_h_data": 0.0, "slope_kb_per_h_wall": 0.0}
    t = np.array([s[0] for s in samples])
    kb = np.array([s[1] for s in samples], float)
    keep = t >= 0.1 * t[-1]
    t, kb = t[keep], kb[keep]
    slope = float(np.polyfit(t, kb, 1)[0]) * 3600 if np.ptp(t) > 0 else 0.0
    return {"samples": int(len(samples)), "first_kb": int(kb[0]), "last_kb": int(kb[-1]), "min_kb": int(kb.min()),
            "max_kb": int(kb.max()), "slope_kb_per_h_wall": slope, "slope_kb_per_h_data": slope / data_per_wall}


def lcm_counts(path: Path) -> tuple[dict[str, int], monitor_status_t | None]:
    """Messages per channel of an LCM log file, and the last status decoded."""
    counts: dict[str, int] = {}
    last = None
    with open(path, "rb") as f:
        while True:
            head = f.read(28)
            if len(head) < 28:
                break
            sync, _, _, clen, dlen = struct.unpack(">IqqII", head)
            if sync != 0xEDA1DA01:
                raise ValueError(f"{path}: not an LCM log (bad sync word)")
            channel = f.read(clen).decode()
            data = f.read(dlen)
            counts[channel] = counts.get(channel, 0) + 1
            if channel == "DYNID_STATUS":
                last = data
    return counts, monitor_status_t.decode(last) if last is not None else None


def expected(rep: dict, paced: bool) -> dict[str, int]:
    """Every monitor counter from what soak_feed passed and injected (docs/benchmarks.md, "Soak": how they add up)."""
    out, stall = rep["out"], rep["stall"]
    e = {
        "frames.total": rep["frames_out"],
        "frames.strain": out["strain_force"] + out["strain_torque"],
        "frames.position": out["position"], "frames.pid": out["pid"], "frames.status": out["status"],
        "frames.skin": out["skin"] - rep["bad_length"],  # a skin frame one byte long is a bad length
        "frames.error": out["error"], "frames.unknown_id": out["unknown"], "frames.bad_length": rep["bad_length"],
        "frames.saturated": rep["saturated"], "frames.board_faults": rep["status_faults"],
        "frames.board_restarts": rep["restarts"] + rep["seq_zero_after_gap"],
        # a duplicated half, or a half whose other half was dropped
        "frames.unpaired_strain": rep["strain_one_half"] + rep["injected"]["dup_force"] + rep["injected"]["dup_torque"],
        "frames.pending_strain": 0,
        "source_counters." + ("bad_size" if paced else "bad_lines"): rep["bad_input"],
        "samples.assembled": rep["samples"] - rep["strain_lost_samples"],
        # stale: the stalled board's samples once its values are older than stale_ms, the sample of each restart
        # (the board's values are dropped until fresh ones come), saturated ones
        "samples.stale": stall["stale"] + rep["restarts"] + rep["saturated_samples"],
        "samples.lost": rep["strain_lost_samples"],
        # held: a POSITION dropped; a duplicated force half opens the sample again, after its positions; the stall's
        # first samples, while its values are younger than stale_ms (not bridged: stale samples follow)
        "samples.held": rep["position_dropped"] + rep["injected"]["dup_force"] + stall["held"],
        "samples.interpolated": rep["position_dropped"] + rep["injected"]["dup_force"] + rep["strain_lost_samples"],
        "samples.filter_restarts": 1 + (1 if stall["samples"] else 0) + rep["restarts"],
    }
    if not paced:
        e["samples.late"] = rep["late_samples"]
    return e


# Paced, these rest on the kernel's stamps: a sender stalled by the platform at the wrong moment moves a stall's
# first stale sample, makes the sample clock read a late burst as losses (sample_clock.hpp), or sends a sample's
# torque half more than pair_us after its force half (two unpaired halves, a sample fewer).
TIMING_DEPENDENT = ("frames.unpaired_strain", "samples.assembled", "samples.stale", "samples.lost", "samples.held",
                    "samples.interpolated", "samples.filter_restarts")


def identities(s: dict, counts: dict[str, int]) -> dict[str, tuple[int, int]]:
    """Sums that must hold inside the monitor's own counters and against its LCM log: name -> (left, right)."""
    f, sm, ev, pub = s["frames"], s["samples"], s["events"], s["published"]
    return {
        "frames = error + unknown + bad length + strain + position + pid + status + skin":
            (f["total"], f["error"] + f["unknown_id"] + f["bad_length"] + f["strain"] + f["position"] + f["pid"]
             + f["status"] + f["skin"]),
        "frames = the source's frames": (f["total"], s["source_counters"]["frames"]),
        "strain halves = 2 samples + unpaired + pending": (f["strain"], 2 * sm["assembled"] + f["unpaired_strain"]
                                                           + f["pending_strain"]),
        "taken = assembled - stale": (sm["taken"], sm["assembled"] - sm["stale"]),
        "evaluated = taken - held + interpolated": (sm["evaluated"], sm["taken"] - sm["held"] + sm["interpolated"]),
        "interpolated <= held + lost": (min(sm["interpolated"], sm["held"] + sm["lost"]), sm["interpolated"]),
        "events = onsets + ends + cut": (ev["total"], ev["onsets"] + ev["ends"] + ev["cut"]),
        "onsets = ends + cut by a restart + open at the end": (ev["onsets"], ev["ends"] + ev["cut"] + ev["in_contact"]),
        "contact messages in the log = events": (counts.get("DYNID_CONTACT", 0), ev["total"]),
        "contact messages in the log = published": (counts.get("DYNID_CONTACT", 0), pub["contact"]),
        "residual messages in the log = published": (counts.get("DYNID_RESIDUAL", 0), pub["residual"]),
        "status messages in the log = published": (counts.get("DYNID_STATUS", 0), pub["status"]),
        "publish failures": (pub["failed"] + pub["unencoded"], 0),
    }


def get(d: dict, dotted: str) -> int:
    for k in dotted.split("."):
        d = d[k]
    return d  # type: ignore[return-value]


def judge(name: str, stats: dict, rep: dict, counts: dict[str, int], last: monitor_status_t | None, rss: dict,
          a: argparse.Namespace, paced: bool, extra: dict) -> dict:
    fails, notes = [], []
    want = expected(rep, paced)
    wrong = {k: (get(stats, k), v) for k, v in want.items() if get(stats, k) != v}
    for k, (g, v) in wrong.items():
        (notes if paced and a.timing == "report" and k in TIMING_DEPENDENT else fails).append(
            f"{k} = {g}, expected {v}")
    ids = identities(stats, counts)
    fails += [f"identity {k}: {l} != {r}" for k, (l, r) in ids.items() if l != r]
    # The last status message carries the exit's counters.
    if last is None or (last.frames, last.samples, last.samples_evaluated, last.late) != (
            stats["frames"]["total"], stats["samples"]["assembled"], stats["samples"]["evaluated"],
            stats["samples"]["late"]):
        fails.append("the last status message differs from the exit counters")
    alloc = stats["allocations"]
    if alloc["elsewhere"] != 0:
        fails.append(f"{alloc['elsewhere']} allocations after start-up outside lcm_publish")
    if not alloc["malloc_counted"]:
        fails.append("malloc is not counted in this build")
    # A leak grows the resident set: an upward trend, or an end above the run's lowest point. Memory given back (a
    # quick run's first second still returns start-up pages) is not one.
    slope = rss.get("slope_kb_per_h_data", 0.0)
    if slope > a.rss_slope_kb:
        fails.append(f"resident set grows {slope:+.1f} kB/h, above {a.rss_slope_kb:g}")
    if rss.get("last_kb", 0) - rss.get("min_kb", 0) > a.rss_slope_kb:
        fails.append(f"resident set ends {rss['last_kb'] - rss['min_kb']} kB above its lowest point")
    over, missed = stats["processing_us"]["over_period"], stats["response_us"]["over_period"]
    if paced and a.timing == "require" and over:
        fails.append(f"{over} loop overruns (processing time above one period)")
    if paced and a.timing == "require" and missed:
        fails.append(f"{missed} missed deadlines (response time above one period)")
    if paced and stats["stopped"] != "signal" or not paced and stats["stopped"] != "end of input":
        fails.append(f"monitor stopped: {stats['stopped']}")
    r, pr = stats["response_us"], stats["processing_us"]
    probe = extra.get("probe") or {}
    timing = (f"loop overruns {over} (processing p50 {pr['p50']:.1f} µs, max {pr['max']:.1f} µs), missed deadlines "
              f"{missed} (response p50 {r['p50']:.1f} µs, p99 {r['p99']:.1f} µs, max {r['max']:.1f} µs; a "
              f"{'SCHED_FIFO ' if extra.get('fifo') else ''}probe woke late by more than a period "
              f"{probe.get('over_period', '?')} times, max "
              f"{probe.get('max', 0) / 1000:.1f} ms)" + ("" if a.timing == "require" else " [timing reported only]")
              if paced else f"processing p50 {pr['p50']:.1f} µs, max {pr['max']:.0f} µs (not paced: no deadline)")
    line = (f"soak {name}: {extra['data_s']:.1f} s of data ({rep['samples']} samples, {rep['frames_out']} frames, "
            f"{sum(rep['injected'].values())} faults) in {extra['wall_s']:.1f} s, LCM {extra['lcm_provider']}; "
            f"allocations after start-up "
            f"{alloc['elsewhere']} (+{alloc['in_lcm_publish']} in lcm_publish); RSS {rss.get('last_kb', 0) / 1024:.1f} MB, "
            f"slope {slope:+.1f} kB/h; {timing}; "
            f"counters {len(want) + len(ids) - len(wrong) - sum(l != r for l, r in ids.values())}/"
            f"{len(want) + len(ids)} accounted; events {stats['events']['total']}: " + ("PASS" if not fails else "FAIL"))
    return {"line": line, "fails": fails, "notes": notes, "stats": stats, "feed": rep, "lcm": counts, "rss": rss,
            "expected": want, **extra}


class Netns:
    """A private network namespace (only lo in it), deleted on exit: the paced run's LCM over UDP multicast stays in it."""

    def __enter__(self) -> str:
        if os.geteuid() != 0 or not shutil.which("ip"):
            sys.exit("soak: --lcm udpm needs root and iproute2 (a private network namespace)")
        self.name = f"dynid-soak-{os.getpid()}"
        subprocess.run(["ip", "netns", "add", self.name], check=True, capture_output=True)
        return self.name

    def __exit__(self, *exc: object) -> None:
        subprocess.run(["ip", "netns", "del", self.name], capture_output=True)
        if self.name in subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout.split():
            raise RuntimeError(f"network namespace {self.name} left behind")


def child_pid(pid: int, timeout: float = 10.0) -> int:
    """The monitor among the children of `pid` (the namespace driver runs `ip` first, then the monitor; under chrt,
    which execs it, the PID is the same)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            kids = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
        except OSError:
            kids = []
        for k in kids:
            try:
                if str(RT_MONITOR).encode() in Path(f"/proc/{k}/cmdline").read_bytes():
                    return int(k)
            except OSError:
                continue
        time.sleep(0.01)
    raise SystemExit("soak: the monitor did not start in the network namespace")


def fifo_allowed() -> bool:
    try:
        return subprocess.run(["chrt", "-f", "1", "true"], capture_output=True).returncode == 0
    except OSError:
        return False


def run(name: str, a: argparse.Namespace, coef: Path, csv: Path, seconds: float, paced: bool) -> dict:
    n_clip, period = csv_samples(csv)
    repeat = max(1, math.ceil(seconds / (n_clip * period) - 1e-9))
    n = n_clip * repeat
    rate = 1.0 / period
    stall_at, stall_n = int(0.3 * n), int(round(2.0 * rate))
    restart_at = int(0.6 * n)
    config = load_config(a.robot)
    udpm = paced and a.lcm == "udpm"
    shm = Path("/dev/shm") if Path("/dev/shm").is_dir() else None
    with contextlib.ExitStack() as stack:
        tmp_p = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="dynid-soak-", dir=shm)))
        sock = stack.enter_context(tempfile.TemporaryDirectory(prefix="dynid-soak-sock-"))
        netns = stack.enter_context(Netns()) if udpm else None
        lcm_log, stats_file, feed_file = tmp_p / "soak.lcmlog", tmp_p / "stats.json", tmp_p / "feed.json"
        conf = tmp_p / "monitor.conf"
        # udpm: no lcm_url, so LCM's default (UDP multicast, ttl=0), inside the namespace only
        conf.write_text(monitor_config_text(config, None if udpm else f"file://{lcm_log}?mode=w"))
        fifo = paced and not a.no_fifo and fifo_allowed()
        nice = (lambda: os.nice(a.nice)) if a.nice and not paced else None  # paced: the default or SCHED_FIFO
        boards = [str(BOARDS), "--config", str(conf), "--data", str(csv), "--sink", "candump:-", "--repeat",
                  str(repeat), "--restart", f"{a.restart_address}@{restart_at}"]
        feed = [str(FEED), "--every", str(a.every), "--stall", f"{a.stall_address}@{stall_at}:{stall_n}",
                "--guard", f"{restart_at - 50}:{restart_at + 50}", "--until", str(n - 100), "--report", str(feed_file)]
        monitor = [str(RT_MONITOR), "--model", str(coef), "--config", str(conf), "--stats-out", str(stats_file)]
        if paced:
            feed += ["--loopback", sock] + (["--priority", "50"] if fifo else [])
            monitor = (["chrt", "-f", "45"] if fifo else []) + monitor + ["--loopback", sock, "--mlockall"]
        else:
            monitor += ["--replay", "/dev/stdin"]
        if netns:  # the driver subscribes in the namespace and starts the monitor there, as its child
            monitor = ["ip", "netns", "exec", netns, sys.executable, str(DRIVER), os.readlink("/proc/self/ns/net"),
                       *monitor]
        probe = subprocess.Popen([str(PROBE), "--period-us", str(round(period * 1e6))] + (
            ["--priority", "45"] if fifo else []), stdout=subprocess.PIPE, text=True) if paced else None
        probe_out = ""
        t0 = time.monotonic()
        mon = subprocess.Popen(monitor, stdin=subprocess.PIPE if not paced else subprocess.DEVNULL,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=nice)
        mon_pid = child_pid(mon.pid) if netns else mon.pid
        # The fast run may last under a second on a quick core: sample often enough to fit a slope to it.
        sampler = RssSampler(mon_pid, 1.0 if paced else 0.01)
        sampler.start()
        fd = bd = None
        finished = False
        try:
            if paced:
                for _ in range(500):  # the monitor binds its sockets at start-up
                    if all((Path(sock) / f"{b}.can").exists() for b in config.can["buses"]) or mon.poll() is not None:
                        break
                    time.sleep(0.02)
            fd = subprocess.Popen(feed, stdin=subprocess.PIPE, stdout=mon.stdin if not paced else subprocess.DEVNULL,
                                  stderr=subprocess.PIPE, preexec_fn=nice)
            bd = subprocess.Popen(boards, stdout=fd.stdin, stderr=subprocess.PIPE, preexec_fn=nice)
            fd.stdin.close()  # type: ignore[union-attr]  (boards and the monitor hold the pipes' ends now)
            fd.stdin = None
            if not paced:
                mon.stdin.close()  # type: ignore[union-attr]
                mon.stdin = None
            b_err = bd.communicate()[1].decode()
            f_err = fd.communicate()[1].decode()
            if paced:
                time.sleep(0.5)  # the last datagrams drained
                mon.send_signal(signal.SIGTERM)  # the namespace driver passes it on
            m_out, m_err = mon.communicate(timeout=120)
            wall = time.monotonic() - t0
            finished = True
        finally:  # whatever happened (an interrupt too), no process of the run is left behind
            if probe is not None:
                probe.send_signal(signal.SIGTERM)
                probe_out = probe.communicate(timeout=30)[0]
            for p in (bd, fd, mon, probe):
                if p is not None and p.poll() is None:
                    p.kill()
                    p.wait()
            if netns and not finished:  # the monitor is the namespace driver's child
                with contextlib.suppress(ProcessLookupError):
                    os.kill(mon_pid, signal.SIGKILL)
            sampler.stop.set()
            sampler.join()
        for what, p, err in (("boards", bd, b_err), ("soak_feed", fd, f_err), ("rt_monitor", mon, m_err)):
            # boards' exit 6: every frame sent, but a bus would be loaded at 70 % or more (a rate above 1 kHz);
            # rt_monitor's 7: the replay raised watchdog faults, which the soak injects (a stalled board, a restart)
            # and judges from the counters below
            if p.returncode != 0 and not (what == "boards" and p.returncode == 6) and not (
                    what == "rt_monitor" and p.returncode == MONITOR_FAULTED):
                raise SystemExit(f"soak {name}: {what} failed ({p.returncode}): {err.strip()}")
        if netns:  # what the subscriber in the namespace received
            got = json.loads(m_out)
            if got["returncode"] not in (0, MONITOR_FAULTED):
                raise SystemExit(f"soak {name}: rt_monitor failed ({got['returncode']}): {got['stderr'].strip()}")
            m_out = got["stdout"]
            counts = {"DYNID_CONTACT": len(got["events"]), "DYNID_STATUS": got["statuses"],
                      "DYNID_RESIDUAL": got["residuals"]}
            last = SimpleNamespace(**got["last_status"]) if got["last_status"] else None
            lcm_mb = 0.0
        else:
            counts, last = lcm_counts(lcm_log)
            lcm_mb = lcm_log.stat().st_size / 1e6
        stats = json.loads(stats_file.read_text())
        rep = json.loads(feed_file.read_text())
    data_s = n * period
    extra = {"data_s": data_s, "wall_s": wall, "repeat": repeat, "fifo": fifo, "boards": b_err.strip(),
             "monitor": m_out.strip(),
             "lcm_provider": "udpm in a private network namespace" if udpm else "file:// in /dev/shm",
             "lcm_log_mb": lcm_mb, "stall_at": stall_at, "stall_samples": stall_n, "restart_at": restart_at,
             "rate_hz": rate, "probe": json.loads(probe_out) if probe_out.strip() else None}
    if rep["samples"] != n:
        raise SystemExit(f"soak {name}: the feed saw {rep['samples']} samples, expected {n}")
    rss = rss_figures(sampler.samples, data_s / wall)
    r = judge(name, stats, rep, counts, last, rss, a, paced, extra)
    if bd.returncode == 6:
        r["notes"].append("boards: a bus would be loaded at 70 % or more at this rate (1 Mbit/s, worst-case stuffing)")
    return r


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", default=str(ROOT / "out" / "soak"), help="where the simulated runs and model are kept")
    p.add_argument("--fast", type=float, default=3600.0, help="seconds of data replayed as fast as possible (0: skip)")
    p.add_argument("--paced", type=float, default=600.0, help="seconds of the real-time paced run (0: skip)")
    p.add_argument("--rate", type=int, default=1000, help="sample rate of the simulated runs (Hz)")
    p.add_argument("--every", type=int, default=1000, help="one fault every N samples")
    p.add_argument("--cad", action="store_true", help="the CAD coefficient file and a simulated contact clip")
    p.add_argument("--clip", type=float, default=120.0, help="with --cad: the clip's length (s)")
    p.add_argument("--model", help="a coefficient file (with --data)")
    p.add_argument("--data", help="a run directory or data.csv (with --model)")
    p.add_argument("--robot", default="icub_right_arm", help="robot configuration (its monitor configuration)")
    p.add_argument("--stall-address", type=int, default=2, help="the motor-control board stalled for 2 s")
    p.add_argument("--restart-address", type=int, default=1, help="the motor-control board restarted")
    p.add_argument("--rss-slope-kb", type=float, default=64.0, help="largest |RSS slope| allowed, kB per hour of data")
    p.add_argument("--nice", type=int, default=10, help="niceness of the fast run's processes")
    p.add_argument("--no-fifo", action="store_true", help="never SCHED_FIFO (default: where the system allows it)")
    p.add_argument("--timing", choices=("require", "report"), default="require",
                   help="paced run: fail on a loop overrun, a missed deadline or a counter that rests on the kernel's "
                        "stamps (require), or only report them (report: for shared test machines)")
    p.add_argument("--lcm", choices=("file", "udpm"), default="file",
                   help="paced run's LCM: a file:// log in /dev/shm, or LCM's default UDP multicast inside a private "
                        "network namespace made for the run (root), counted by a subscriber there")
    p.add_argument("--json", help="write every figure here")
    a = p.parse_args(argv)
    for exe in (BOARDS, RT_MONITOR, FEED, PROBE):
        if not exe.is_file():
            sys.exit(f"soak: {exe} is not built (scripts/setup)")
    coef, csv = prepare(a)
    results = {}
    for name, seconds, paced in (("fast", a.fast, False), ("paced", a.paced, True)):
        if seconds > 0:
            r = run(name, a, coef, csv, seconds, paced)
            print(r["line"], flush=True)
            for f in r["fails"]:
                print(f"  {f}", flush=True)
            for f in r["notes"]:
                print(f"  (timing, reported only) {f}", flush=True)
            results[name] = r
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=1, default=str) + "\n")
    return 1 if any(r["fails"] for r in results.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
