"""The monitor's LCM output as deployed: the real UDP multicast provider inside a private network namespace, the
generated Python types against today's .lcm files, the Java types (lcm-spy), and `dynid spy`.

Every run replays the same short candump log (6 s of the default contact experiment around its first contact);
a file:// run of it is the reference the other transports and decoders are compared with.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
from conftest import dynid

from dynid.cli.spy import plain
from dynid.config.robot_config import load_config
from dynid.export.monitor_config import monitor_config_text
from dynid.export.monitor_log import read_lcm_log
from dynid.io.candump import write_candump
from dynid.io.load import load_data

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "rt_monitor"
RT_MONITOR = BUILD / "rt_monitor"
VENV_BIN = Path(sys.executable).parent
START, STOP = 10000, 16000  # the slice test_can_e2e's bad-input tests use: it holds a detected contact


@pytest.fixture(scope="module")
def run(default_experiments: dict, exported: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The coefficient file, the candump log, a configuration without lcm_url (LCM's default), and the file:// run."""
    assert RT_MONITOR.is_file(), f"{RT_MONITOR} is not built (scripts/setup)"
    root = tmp_path_factory.mktemp("lcm_deploy")
    coef = exported
    config = load_config("icub_right_arm")
    part = load_data(default_experiments["contact"], config).slice(START, STOP)
    log = root / "contact.log"
    write_candump(part, config, log)
    (root / "default.conf").write_text(monitor_config_text(config))  # no lcm_url: LCM's default, UDP multicast
    lcm_log = root / "reference.lcmlog"
    (root / "file.conf").write_text(monitor_config_text(config, f"file://{lcm_log}?mode=w"))
    done = subprocess.run([str(RT_MONITOR), "--model", str(coef), "--config", str(root / "file.conf"), "--replay", str(log)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    msgs = read_lcm_log(lcm_log)
    assert msgs["DYNID_CONTACT"], "the slice must hold a detected contact"
    return {"root": root, "coef": coef, "log": log, "lcm_log": lcm_log, "msgs": msgs, "stdout": done.stdout}


# ---- generated Python types -------------------------------------------------------------------------------


def test_generated_python_types_are_lcm_gens_output_for_todays_lcm_files(tmp_path: Path) -> None:
    """The Python types dynid imports (scripts/setup generates them; not checked in) are lcm-gen's output for the .lcm
    files as they are now: a .lcm edited without a rerun of scripts/setup fails here, not as a fingerprint mismatch
    on the bus."""
    import dynid.export._lcmtypes as generated

    subprocess.run([str(VENV_BIN / "lcm-gen"), "--python", "--ppath", str(tmp_path),
                    *sorted(str(p) for p in (ROOT / "rt_monitor" / "lcmtypes").glob("*.lcm"))], check=True)
    here, fresh = Path(generated.__file__).parent, tmp_path / "dynid"
    names = {p.name for d in (here, fresh) for p in d.glob("*.py")}
    stale = sorted(n for n in names if not ((here / n).is_file() and (fresh / n).is_file()
                                            and (here / n).read_bytes() == (fresh / n).read_bytes()))
    assert stale == [], f"{here}: {', '.join(stale)} not lcm-gen's output: run scripts/setup"


def test_without_the_generated_types_dynid_says_to_run_setup(tmp_path: Path) -> None:
    """A package without them (a clone run without scripts/setup): the CLI ends in one line naming the fix, exit 2,
    and an import raises that line, not a ModuleNotFoundError from inside."""
    shutil.copytree(ROOT / "tools" / "dynid", tmp_path / "dynid",
                    ignore=shutil.ignore_patterns("_lcmtypes", "__pycache__", "_kernels*"))
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    line = "lcm-gen's Python for rt_monitor/lcmtypes (dynid.export._lcmtypes) is not generated: run scripts/setup"
    for command in ("export", "spy"):
        done = subprocess.run([sys.executable, "-m", "dynid", command, "--help"], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=120)
        assert (done.returncode, done.stdout, done.stderr) == (2, "", f"dynid {command}: error: {line}\n")
    done = subprocess.run([sys.executable, "-c", "from dynid.export.lcm_messages import residual_t"], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and done.stderr.splitlines()[-1] == f"dynid.errors.SetupError: {line}", done.stderr
    assert "ModuleNotFoundError" not in done.stderr and str(tmp_path / "dynid") in done.stderr  # the copy, not the tree


# ---- the real UDP multicast provider, inside a private network namespace ----------------------------------


@pytest.fixture
def netns() -> str:
    """A network namespace of its own, deleted afterwards whatever happens; skipped where it cannot be made."""
    if os.geteuid() != 0:
        pytest.skip("creating a network namespace needs root (run the suite as root to test UDP multicast)")
    if not shutil.which("ip"):
        pytest.skip("no 'ip' command (iproute2) to create a network namespace")
    name = f"dynid-test-{os.getpid()}-{uuid.uuid4().hex[:6]}"
    made = subprocess.run(["ip", "netns", "add", name], capture_output=True, text=True)
    if made.returncode != 0:
        pytest.skip(f"cannot create a network namespace: {made.stderr.strip()}")
    try:
        yield name
    finally:
        subprocess.run(["ip", "netns", "del", name], capture_output=True)
        listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
        assert name not in listed.split(), f"network namespace {name} left behind"


def test_udp_multicast_inside_a_private_namespace(run: dict, netns: str) -> None:
    # Every process that opens an LCM socket is a child of the driver, which `ip netns exec` starts inside the
    # namespace (it runs nothing when it cannot enter it) and which itself refuses to run in the host's
    # namespace or beside any interface but lo. The host never opens a udpm socket in this test.
    host_ns = os.readlink("/proc/self/ns/net")
    env = {k: v for k, v in os.environ.items() if k != "LCM_DEFAULT_URL"}
    done = subprocess.run(
        ["ip", "netns", "exec", netns, sys.executable, str(Path(__file__).with_name("netns_lcm_driver.py")), host_ns,
         str(RT_MONITOR), "--model", str(run["coef"]), "--config", str(run["root"] / "default.conf"),
         "--replay", str(run["log"]), "--realtime"],  # at the boards' pace: a burst would overrun lo's socket buffers
        capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    assert got["netns"] != host_ns and got["interfaces"] == ["lo"]
    assert got["returncode"] == 0, got["stderr"]
    # The same run, final counters and all (but overruns: timing, on a shared machine).
    assert got["stdout"].rsplit(", overruns", 1)[0] == run["stdout"].rsplit(", overruns", 1)[0]
    # Over UDP multicast, the same contact events as the file:// run, and the last status with the same counters.
    assert got["events"] == [[m.kind, m.utime] for m in run["msgs"]["DYNID_CONTACT"]]
    ref = run["msgs"]["DYNID_STATUS"]
    assert got["statuses"] == len(ref)
    last = got["last_status"]
    assert {k: last[k] for k in ("utime", "frames", "samples", "samples_evaluated", "in_contact")} == \
        {k: getattr(ref[-1], k) for k in ("utime", "frames", "samples", "samples_evaluated", "in_contact")}
    assert got["residuals"] == len(run["msgs"]["DYNID_RESIDUAL"])


# ---- Java: the jar of the types (lcm-spy) -----------------------------------------------------------------

JAR = BUILD / "dynid-lcmtypes.jar"


def _lcm_jar() -> Path:
    import lcm

    jar = Path(lcm.__file__).resolve().parents[1] / "share" / "java" / "lcm.jar"  # the lcm wheel ships it
    return jar


def test_java_types_decode_the_published_messages(run: dict, tmp_path: Path) -> None:
    if not (shutil.which("javac") and shutil.which("java")):
        pytest.skip("no JDK (javac, java): the Java types are not built")
    if not _lcm_jar().is_file():
        pytest.skip(f"no lcm.jar at {_lcm_jar()}: the Java types are not built")
    assert JAR.is_file(), f"{JAR} not built although a JDK and lcm.jar are present (scripts/setup)"
    cp = f"{_lcm_jar()}:{JAR}"
    src = ROOT / "rt_monitor" / "tests" / "java" / "DecodeLcmLog.java"
    subprocess.run(["javac", "-cp", cp, "-d", str(tmp_path), str(src)], check=True, capture_output=True, timeout=300)
    done = subprocess.run(["java", "-cp", f"{cp}:{tmp_path}", "DecodeLcmLog", str(run["lcm_log"])],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    py = [(c, m) for c in ("DYNID_CONTACT", "DYNID_STATUS", "DYNID_RESIDUAL") for m in run["msgs"][c]]
    assert len(lines) == len(py)
    by_channel: dict[str, list[dict[str, str]]] = {}
    for line in lines:
        channel, *pairs = line.split("\t")
        by_channel.setdefault(channel, []).append(dict(p.split("=", 1) for p in pairs))
    for channel, msgs in run["msgs"].items():
        java = by_channel.get(channel, [])
        assert len(java) == len(msgs), channel
        for j, m in zip(java, msgs):
            assert set(j) == set(m.__slots__)
            for name in m.__slots__:
                want = getattr(m, name)
                items = _flat(want) if isinstance(want, (list, tuple)) else [want]  # Java prints arrays flat
                got = j[name].split(",") if isinstance(want, (list, tuple)) else [j[name]]
                conv = [type(w)(g) if not isinstance(w, bool) else g == "true" for w, g in zip(items, got)]
                assert conv == items, f"{channel}.{name}: Java {j[name]!r}, Python {want!r}"
    kinds = [int(j["kind"]) for j in by_channel["DYNID_CONTACT"]]
    assert kinds and kinds[0] == 1  # the contact's onset, decoded in Java


def _flat(v) -> list:
    return [y for x in v for y in _flat(x)] if isinstance(v, (list, tuple)) else [v]


def test_lcm_spy_launcher_puts_the_jar_on_the_classpath(tmp_path: Path) -> None:
    if not JAR.is_file():
        pytest.skip("the Java types are not built (no JDK or no lcm.jar)")
    fake = tmp_path / "lcm-spy"  # stands in for lcm-spy (a GUI): shows the CLASSPATH and arguments it was given
    fake.write_text("#!/bin/sh\necho \"CLASSPATH=$CLASSPATH ARGS=$*\"\n")
    fake.chmod(0o755)
    env = {**os.environ, "LCM_SPY": str(fake), "CLASSPATH": "/x/other.jar"}
    done = subprocess.run([str(BUILD / "dynid-lcm-spy"), "--lcm-url", "memq://"], capture_output=True, text=True,
                          env=env, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"CLASSPATH={JAR}:/x/other.jar ARGS=--lcm-url memq://"
    # Without a jar it refuses in one line, exit 2.
    env["DYNID_LCMTYPES_JAR"] = str(tmp_path / "missing.jar")
    done = subprocess.run([str(BUILD / "dynid-lcm-spy")], capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "dynid-lcmtypes.jar" in done.stderr


# ---- dynid spy -------------------------------------------------------------------------------------------


def _spy(*args: str) -> subprocess.CompletedProcess:
    return dynid("spy", *args)


def test_spy_json_is_every_message_of_the_log(run: dict) -> None:
    done = _spy("--lcm-url", f"file://{run['lcm_log']}?speed=0", "--json")
    assert done.returncode == 0, done.stderr
    lines = [json.loads(l) for l in done.stdout.splitlines()]
    summary = lines.pop()["summary"]
    msgs = run["msgs"]
    for channel in msgs:
        got = [l for l in lines if l["channel"] == channel]
        assert len(got) == len(msgs[channel])
        for g, m in zip(got, msgs[channel]):
            assert all(g["message"][k] == plain(getattr(m, k)) for k in m.__slots__)
    assert summary["stopped"] == "end of the log"
    assert summary["messages"] == {c: len(m) for c, m in msgs.items()}
    kinds = [m.kind for m in msgs["DYNID_CONTACT"]]
    assert (summary["onsets"], summary["ends"]) == (kinds.count(1), kinds.count(2))
    assert summary["last_status"]["frames"] == msgs["DYNID_STATUS"][-1].frames


def test_spy_view_shows_events_status_and_rates(run: dict) -> None:
    done = _spy("--lcm-url", f"file://{run['lcm_log']}?speed=0")
    assert done.returncode == 0, done.stderr
    out = done.stdout.splitlines()
    events = [l for l in out if " contact " in l and " T² " in l]
    msgs = run["msgs"]
    t0 = min(m.utime for c in ("DYNID_CONTACT", "DYNID_STATUS") for m in msgs[c][:1])
    want = [(f"{(m.utime - t0) * 1e-6:.3f} s", {1: "onset", 2: "end"}[m.kind], f"T² {m.t2:9.1f}")
            for m in msgs["DYNID_CONTACT"]]
    assert [(l.split("  contact")[0].strip(), l.split()[3], "T² " + l.split("T² ")[1][:9]) for l in events] == want
    # An end names the peak its sides and torques describe
    ends = [m for m in msgs["DYNID_CONTACT"] if m.kind == 2]
    assert ends and [l.split("  peak ")[1].split(":")[0] for l in events if " end " in l] == [
        f"T² {m.peak_t2:.1f} at {(m.peak_utime - t0) * 1e-6:.3f} s" for m in ends]
    assert all(m.onset_utime <= m.peak_utime < m.utime and m.peak_t2 > m.threshold for m in ends)
    # A status line a second of CAN time; the replayed boards' rates: 14 frames a sample at 1 kHz.
    status = [l for l in out if "frames/s" in l]
    assert len(status) >= 4
    assert all(re.search(r"  samples \d+ assembled, \d+ evaluated  ", l) for l in status), status[0]
    rates = [float(l.split(" frames/s")[0].split()[-1]) for l in status]
    samples = [float(l.split(" samples/s")[0].split()[-1]) for l in status]
    n_frames, n_samples = msgs["DYNID_STATUS"][-1].frames, msgs["DYNID_STATUS"][-1].samples
    assert all(abs(r - 1000 * n_frames / n_samples) < 0.05 * 1000 * n_frames / n_samples for r in rates), rates
    assert all(abs(s - 1000) <= 20 for s in samples), samples
    last = msgs["DYNID_STATUS"][-1]
    kinds = [m.kind for m in msgs["DYNID_CONTACT"]]
    def n(count: int, noun: str) -> str:
        return f"{count} {noun}{'' if count == 1 else 's'}"

    head = (f"dynid spy: stopped (end of the log): {n(len(kinds), 'contact event')} ({n(kinds.count(1), 'onset')}, "
            f"{n(kinds.count(2), 'end')}), {len(msgs['DYNID_STATUS'])} status, {len(msgs['DYNID_RESIDUAL'])} residual "
            f"messages; last status: frames {last.frames}, samples {last.samples}, evaluated {last.samples_evaluated}, ")
    assert out[-1].startswith(head), out[-1]
    # The counters that are not zero are named (the replay restarts the filter once, at its start).
    assert f"filter restarts {last.filter_restarts}" in out[-1] and last.filter_restarts == 1
    assert ("overruns" in out[-1]) == (last.overruns > 0) and "unknown id" not in out[-1]
    assert (", late " in out[-1]) == (last.late > 0)
    # The input channels' supply ratios, on every status line and in the summary (the last status's).
    assert last.n_supply == 4 and list(last.supply_ratio) != [1.0] * 4
    assert out[-1].endswith(", supply r " + " ".join(f"{r:.4f}" for r in last.supply_ratio))
    assert all("  supply r " in l for l in status)


def test_spy_into_a_pipe_closed_early_stops_quietly(run: dict) -> None:
    # `dynid spy ... | head -1`: once the reader has its line, spy stops as a tool killed by SIGPIPE, saying nothing.
    # (--json: every message, megabytes, more than the pipe holds, so spy is still writing when the pipe closes.)
    proc = subprocess.Popen([sys.executable, "-m", "dynid.cli", "spy", "--lcm-url", f"file://{run['lcm_log']}?speed=0",
                             "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 128 + signal.SIGPIPE and first and err == "", err


def test_spy_count_stops_after_n_events(run: dict) -> None:
    done = _spy("--lcm-url", f"file://{run['lcm_log']}?speed=0", "--count", "1", "--json")
    assert done.returncode == 0, done.stderr
    lines = [json.loads(l) for l in done.stdout.splitlines()]
    assert lines[-1]["summary"]["stopped"] == "1 contact event"
    assert [l["channel"] for l in lines[:-1]].count("DYNID_CONTACT") == 1


def test_spy_duration_on_a_silent_bus() -> None:
    done = _spy("--lcm-url", "memq://", "--duration", "0.3", "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["summary"] == {"stopped": "0.3 s", "messages": {c: 0 for c in
                                                  ("DYNID_CONTACT", "DYNID_STATUS", "DYNID_RESIDUAL")},
                                                  "onsets": 0, "ends": 0, "last_status": None, "skipped": 0}


@pytest.mark.parametrize("args, why", [
    (["--lcm-url", "bogus://x"], "cannot open LCM at 'bogus://x'"),
    (["--lcm-url", "file:///nonexistent/x.lcmlog"], "No such file"),
    (["--count", "0"], "must be positive"),
    (["--count", "1", "--duration", "1"], "exclude each other"),
    # a URL pasted from rt_monitor's configuration: LCM would open (and empty) the log to write
    (["--lcm-url", "file:///nonexistent/x.lcmlog?mode=w"], "opens its log for writing (mode=w empties it), and spy reads"),
    (["--lcm-url", "file:///nonexistent/x.lcmlog?speed=0&mode=a"], "opens its log for writing"),
])
def test_spy_bad_input_is_one_line_exit_2(args: list[str], why: str) -> None:
    done = _spy(*args)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and why in done.stderr, done.stderr
