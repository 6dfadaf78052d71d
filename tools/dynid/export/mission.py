"""The live half of the mission: the board emulators play a run into the loopback transport, rt_monitor detects,
its LCM messages go to a `file://` log (never UDP multicast on the host), and the events are summarised against
the skin's ground truth (dynid.export.monitor_log).

    python -m dynid.export.mission --model COEF --data RUN_DIR --out DIR [--no-fifo] [--json SUMMARY.json]

The boards play in real time: a live transport stamps each frame when it is sent (SO_TIMESTAMP), as a real bus
stamps it on arrival, and the monitor's sample clock is that stamp. Where the system allows it, both programs
run SCHED_FIFO (boards 20, rt_monitor 30), so that a sender woken late on a loaded machine does not bunch its
frames; --no-fifo runs them as ordinary processes.

Writes DIR/monitor.conf, DIR/events.lcmlog (every DYNID_* message) and prints the boards' bus loads, the
monitor's final counters and the summary. Exit 2 with one line on bad input, 1 if a program fails.
"""

from __future__ import annotations

import argparse
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..config.robot_config import load_config
from ..errors import DataError, InputError
from . import monitor_log as contact_summary
from .monitor_config import fits_a_configuration, monitor_config_text

ROOT = Path(__file__).resolve().parents[3]
BOARDS = ROOT / "build" / "firmware_like" / "boards"
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"


class MissionError(Exception):
    pass


def fifo_allowed() -> bool:
    """Whether this process may start SCHED_FIFO programs (root or CAP_SYS_NICE, and an RT budget)."""
    try:
        return subprocess.run(["chrt", "-f", "1", "true"], capture_output=True).returncode == 0
    except OSError:
        return False


def fifo_args(on: bool) -> dict[str, tuple[str, ...]]:
    return {"boards_args": ("--rt-priority", "20"), "monitor_prefix": ("chrt", "-f", "30")} if on else {}


def play(coef: Path, data: Path, out: Path, robot: str = "icub_right_arm", realtime: bool = False,
         monitor_args: tuple[str, ...] = (), boards_args: tuple[str, ...] = (),
         monitor_prefix: tuple[str, ...] = ()) -> dict[str, str]:
    """boards → loopback → rt_monitor → LCM file://; returns both programs' stdout and the log's path."""
    for exe in (BOARDS, RT_MONITOR):
        if not exe.is_file():
            raise MissionError(f"{exe} is not built (run scripts/setup)")
    final_log = out / "events.lcmlog"
    if not fits_a_configuration(str(final_log)):  # before anything runs or is written
        raise InputError(f"--out {str(out)!r}: the monitor's configuration names its LCM log there by a file:// URL, "
                         "which cannot hold whitespace, '#' or control characters; choose a directory without them")
    out.mkdir(parents=True, exist_ok=True)
    conf = out / "monitor.conf"
    config = load_config(robot)
    # AF_UNIX socket paths are limited to 108 bytes: the transport's directory is a short temporary one. The LCM
    # log is written in memory (/dev/shm) during the run and moved to `out` after it: a monitor blocked in a
    # write to a busy disk stops reading, its socket queues (10 datagrams) fill, the boards block and their
    # frames are stamped late, which the monitor reads as lost samples.
    shm = Path("/dev/shm")
    with tempfile.TemporaryDirectory(prefix="dynid-can-") as sock_dir, \
            tempfile.TemporaryDirectory(prefix="dynid-lcm-", dir=shm if shm.is_dir() else None) as lcm_dir:
        lcm_log = Path(lcm_dir) / "events.lcmlog"
        conf.write_text(monitor_config_text(config, f"file://{lcm_log}?mode=w"))
        mon = subprocess.Popen([*monitor_prefix, str(RT_MONITOR), "--model", str(coef), "--config", str(conf), "--loopback", sock_dir,
                                *monitor_args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            buses = config.can["buses"]
            for _ in range(200):  # the monitor binds its sockets at start-up
                if all((Path(sock_dir) / f"{b}.can").exists() for b in buses) or mon.poll() is not None:
                    break
                time.sleep(0.02)
            if mon.poll() is not None:
                raise MissionError(f"rt_monitor ended at start-up: {mon.communicate()[1].strip()}")
            b = subprocess.run([str(BOARDS), "--config", str(conf), "--data", str(data), "--sink",
                                f"loopback:{sock_dir}", *(["--realtime"] if realtime else []), *boards_args],
                               capture_output=True, text=True)
            if b.returncode != 0:
                raise MissionError(b.stderr.strip() or f"boards failed with exit code {b.returncode}")
            # Drained when the monitor's LCM log stops growing (its status runs at 10 Hz of CAN time).
            size, still = -1, 0
            while still < 5:
                time.sleep(0.1)
                now = lcm_log.stat().st_size if lcm_log.exists() else 0
                still = still + 1 if now == size else 0
                size = now
            mon.send_signal(signal.SIGTERM)
            m_out, m_err = mon.communicate(timeout=30)
        finally:
            if mon.poll() is None:
                mon.kill()
                mon.wait()
        if mon.returncode != 0:
            raise MissionError(f"rt_monitor failed ({mon.returncode}): {m_err.strip()}")
        shutil.move(str(lcm_log), str(final_log))
    conf.write_text(monitor_config_text(config, f"file://{final_log}?mode=w"))  # as a replay of it would need
    return {"boards": b.stdout, "monitor": m_out, "lcm_log": str(final_log), "conf": str(conf)}


def sample0_us(boards_stdout: str) -> int:
    """When the boards sent sample 0 (µs): the realtime clock of a paced run, else the CAN time base (--t0)."""
    for line in boards_stdout.splitlines():
        if line.startswith("boards: sample 0 at CLOCK_REALTIME "):
            return int(line.split()[-2])
    return 1_700_000_000_000_000


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m dynid.export.mission", description=__doc__.splitlines()[0])
    p.add_argument("--model", required=True, type=Path, help="coefficient file (dynid export)")
    p.add_argument("--data", required=True, type=Path, help="a simulated run with skin ground truth")
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--robot", default="icub_right_arm")
    p.add_argument("--no-fifo", action="store_true", help="never run the boards and the monitor SCHED_FIFO")
    p.add_argument("--json", type=Path)
    a = p.parse_args(argv)

    for path, what in ((a.model, "coefficient file"), (a.data, "run")):
        if not path.exists():
            print(f"dynid.export.mission: error: {what} not found: {path}", file=sys.stderr)
            return 2
    try:
        fifo = not a.no_fifo and fifo_allowed()
        print(f"live mission: boards → loopback → rt_monitor → LCM {a.out / 'events.lcmlog'}, in real time"
              f"{', SCHED_FIFO' if fifo else ''}", flush=True)
        r = play(a.model, a.data, a.out, a.robot, True, **fifo_args(fifo))
    except MissionError as e:
        print(f"dynid.export.mission: error: {e}", file=sys.stderr)
        return 1
    except (DataError, InputError) as e:
        print(f"dynid.export.mission: error: {e}", file=sys.stderr)
        return 2
    print(r["boards"].strip())
    print(r["monitor"].strip())
    args = ["--events", r["lcm_log"], "--data", str(a.data), "--model", str(a.model), "--robot", a.robot,
            "--t0", f"{sample0_us(r['boards']) / 1e6:.6f}"]
    return contact_summary.main(args + (["--json", str(a.json)] if a.json else []))


if __name__ == "__main__":
    sys.exit(main())
