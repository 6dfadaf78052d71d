"""rt_monitor's real-time options: --mlockall, --priority N (SCHED_FIFO), --cpu LIST, as the kernel sees the running
process (/proc, sched_getscheduler, sched_getaffinity), and each refusal: one line, its own exit code.

LCM goes to memq:// (in-process) in every run here.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"
COEF = ROOT / "rt_monitor" / "tests" / "data" / "icub_cad.dcoef"
CONF = ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"
CAD = "; a CAD export's file: no known answers to check the core against"  # the start-up line's end for COEF
EXIT_MLOCKALL, EXIT_PRIORITY, EXIT_CPU = 3, 4, 5


def monitor(*opts: str, tmp: Path, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess:
    """A run on an empty candump log: it applies the settings, then ends at once."""
    log = tmp / "empty.log"
    log.write_text("")
    return subprocess.run([*prefix, str(RT_MONITOR), "--model", str(COEF), "--config", str(CONF), "--replay", str(log),
                           "--lcm-url", "memq://", *opts], capture_output=True, text=True, timeout=60)


def test_settings_are_applied_to_the_running_process(tmp_path: Path) -> None:
    if os.geteuid() != 0:
        pytest.skip("SCHED_FIFO and mlockall of a large process need root (CAP_SYS_NICE, CAP_IPC_LOCK)")
    cpu = max(os.sched_getaffinity(0))
    proc = subprocess.Popen([str(RT_MONITOR), "--model", str(COEF), "--config", str(CONF), "--loopback", str(tmp_path),
                             "--lcm-url", "memq://", "--mlockall", "--priority", "7", "--cpu", str(cpu)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()  # written once the settings are in force
        assert line == (f"rt_monitor: running: loopback transport in {tmp_path}; LCM memq://; mlockall on, "
                        f"SCHED_FIFO priority 7, CPU {cpu}; acceleration residuals{CAD}\n")
        assert os.sched_getscheduler(proc.pid) == os.SCHED_FIFO
        assert os.sched_getparam(proc.pid).sched_priority == 7
        assert os.sched_getaffinity(proc.pid) == {cpu}
        status = dict(l.split(":", 1) for l in Path(f"/proc/{proc.pid}/status").read_text().splitlines())
        locked_kb, size_kb = int(status["VmLck"].split()[0]), int(status["VmRSS"].split()[0])
        assert locked_kb >= 0.9 * size_kb > 0  # the resident pages are locked
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0 and out.startswith("rt_monitor: stopped by signal;")


def test_without_options_the_start_up_line_says_so(tmp_path: Path) -> None:
    done = monitor(tmp=tmp_path)
    # The empty log evaluates no sample: exit 6, said after the start-up line (the watchdog: rt_monitor/README.md)
    assert done.returncode == 6 and "rt_monitor: error: evaluated no sample" in done.stderr, done.stderr
    allowed = sorted(os.sched_getaffinity(0))
    cpus = f"{allowed[0]}-{allowed[-1]}" if allowed == list(range(allowed[0], allowed[-1] + 1)) else None
    first = done.stderr.splitlines()[0]
    assert first.startswith(f"rt_monitor: running: replay of {tmp_path / 'empty.log'}; LCM memq://; mlockall off, "
                            "default scheduling, CPUs ")
    if cpus:
        assert first.endswith(f"CPUs {cpus}; acceleration residuals{CAD}")


def _refused(done: subprocess.CompletedProcess, code: int, *words: str) -> None:
    assert done.returncode == code, (done.returncode, done.stderr)
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("rt_monitor: error: "), done.stderr
    assert all(w in done.stderr for w in words), done.stderr
    assert done.stdout == ""  # refused before the loop: no run, no counters


@pytest.mark.parametrize("priority", ["0", "100", "200"])
def test_priority_outside_sched_fifo_range_is_a_bad_value(priority: str, tmp_path: Path) -> None:
    """Exit 2 before the system is asked: SCHED_FIFO's range is known unprivileged (sched_get_priority_min/max)."""
    lo, hi = os.sched_get_priority_min(os.SCHED_FIFO), os.sched_get_priority_max(os.SCHED_FIFO)
    done = monitor("--priority", priority, tmp=tmp_path)
    assert done.returncode == 2 and done.stdout == "", (done.returncode, done.stderr)
    assert f"--priority {priority}: SCHED_FIFO's priorities are {lo}..{hi}" in done.stderr.splitlines()[0], done.stderr


def test_cpu_not_allowed_is_refused(tmp_path: Path) -> None:
    cpu = max(os.sched_getaffinity(0)) + 1  # a CPU this machine does not have, or may not use
    _refused(monitor("--cpu", str(cpu), tmp=tmp_path), EXIT_CPU, f"--cpu {cpu}", "refused the CPU affinity")
    _refused(monitor("--cpu", "100000", tmp=tmp_path), EXIT_CPU, "--cpu 100000")


def test_cpu_list_pins_to_every_cpu_of_it(tmp_path: Path) -> None:
    """--cpu takes a list as taskset -c does; the running process's affinity is that set, and the start-up line
    names it."""
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) < 2:
        pytest.skip("a list needs two CPUs this process may use")
    chosen = allowed[:2]
    text = f"{chosen[0]}-{chosen[1]}" if chosen[1] == chosen[0] + 1 else f"{chosen[0]},{chosen[1]}"
    proc = subprocess.Popen([str(RT_MONITOR), "--model", str(COEF), "--config", str(CONF), "--loopback", str(tmp_path),
                             "--lcm-url", "memq://", "--cpu", text], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stderr.readline()
        assert line.endswith(f"default scheduling, CPUs {text}; acceleration residuals{CAD}\n"), line
        assert os.sched_getaffinity(proc.pid) == set(chosen)
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0  # the SIGTERM handler is in place before the start-up line


@pytest.mark.parametrize("text", ["", "a", "-1", "1-0", "0,0", "1,0", "0,", "0-", "0--1", "1 ", "99999999"])
def test_bad_cpu_list_is_a_usage_error(text: str, tmp_path: Path) -> None:
    done = monitor("--cpu", text, tmp=tmp_path)
    assert done.returncode == 2, done.stderr
    first = done.stderr.splitlines()[0]  # then the usage line
    assert first == f"rt_monitor: error: --cpu needs a CPU list as taskset -c takes it (1, 0,2 or 0-3), got '{text}'"


def _unprivileged(limit: str) -> tuple[str, ...]:
    """A prefix that runs the monitor with the resource limit at 0 and, as root, without the capability that
    overrides it (the bounding set drops it across exec)."""
    if not shutil.which("prlimit"):
        pytest.skip("no prlimit (util-linux) to lower the resource limit")
    prefix: tuple[str, ...] = ("prlimit", f"--{limit}=0", "--")
    if os.geteuid() == 0:
        if not shutil.which("setpriv"):
            pytest.skip("running as root and no setpriv (util-linux) to drop the capability")
        prefix = ("setpriv", "--bounding-set=-sys_nice,-ipc_lock", "--inh-caps=-sys_nice,-ipc_lock", *prefix)
    return prefix


def test_sched_fifo_refused_without_rtprio(tmp_path: Path) -> None:
    _refused(monitor("--priority", "10", tmp=tmp_path, prefix=_unprivileged("rtprio")), EXIT_PRIORITY,
             "--priority 10", "Operation not permitted", "RLIMIT_RTPRIO of at least 10 (now 0")


def test_mlockall_refused_without_memlock(tmp_path: Path) -> None:
    _refused(monitor("--mlockall", tmp=tmp_path, prefix=_unprivileged("memlock")), EXIT_MLOCKALL,
             "--mlockall", "RLIMIT_MEMLOCK", "(now 0 bytes")


@pytest.mark.parametrize("args, why", [
    (["--priority", "high"], "--priority needs an integer, got 'high'"),
    (["--cpu", "-1"], "--cpu needs a CPU list as taskset -c takes it (1, 0,2 or 0-3), got '-1'"),
    (["--cpu"], "'--cpu' needs a value"),
])
def test_malformed_values_are_usage_errors(args: list[str], why: str, tmp_path: Path) -> None:
    done = monitor(*args, tmp=tmp_path)
    assert done.returncode == 2 and why in done.stderr.splitlines()[0], done.stderr
