"""`cmake --install build --prefix TMP` gives a runnable tree: the monitor finds its liblcm in the tree, runs the
systemd unit's own command line, and behaves as the build tree's monitor on the same input; the unit verifies;
the lcm-spy launcher finds the installed jar; the installed C++ headers of the LCM types compile on their own.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

from dynid.config.robot_config import load_config
from dynid.io.candump import write_candump
from dynid.io.load import load_data

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build"
COEF = ROOT / "rt_monitor" / "tests" / "data" / "icub_cad.dcoef"
# What the robot PC has: no venv on PATH, no library path.
BARE_ENV = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": "/nonexistent"}


@pytest.fixture(scope="module")
def prefix(tmp_path_factory: pytest.TempPathFactory) -> Path:
    assert (BUILD / "rt_monitor" / "rt_monitor").is_file(), "build/ is not built (scripts/setup)"
    p = tmp_path_factory.mktemp("install") / "prefix"
    done = subprocess.run(["cmake", "--install", str(BUILD), "--prefix", str(p)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    return p


def test_tree_holds_the_monitor_types_config_and_unit(prefix: Path) -> None:
    want = ["bin/rt_monitor", "bin/dynid-lcm-spy", "lib/liblcm.so.1", "etc/dynid/rt_monitor.conf.example",
            "lib/systemd/system/dynid-rt-monitor.service"]
    want += [f"share/dynid/lcmtypes/{t}.lcm" for t in ("coefficients_t", "contact_event_t", "monitor_status_t", "residual_t")]
    want += [f"include/dynid/{t}.hpp" for t in ("contact_event_t", "monitor_status_t", "residual_t")]
    want.append("include/lcm/lcm_coretypes.h")
    if (BUILD / "rt_monitor" / "dynid-lcmtypes.jar").is_file():
        want.append("share/java/dynid-lcmtypes.jar")
    assert [w for w in want if not (prefix / w).exists()] == []
    assert os.access(prefix / "bin" / "rt_monitor", os.X_OK) and os.access(prefix / "bin" / "dynid-lcm-spy", os.X_OK)
    ldd = subprocess.run(["ldd", str(prefix / "bin" / "rt_monitor")], capture_output=True, text=True, env=BARE_ENV).stdout
    lcm = [l for l in ldd.splitlines() if "liblcm" in l]
    assert "not found" not in ldd and len(lcm) == 1
    assert Path(lcm[0].split("=>")[1].split("(")[0].strip()).resolve() == (prefix / "lib" / "liblcm.so.1").resolve()


def _unit(prefix: Path) -> dict[str, str]:
    text = (prefix / "lib" / "systemd" / "system" / "dynid-rt-monitor.service").read_text()
    return dict(l.split("=", 1) for l in text.splitlines() if "=" in l and not l.startswith("#"))


def test_unit_does_not_restart_on_a_refused_file_or_configuration(prefix: Path) -> None:
    """A restart fixes none of the refusals: bad arguments or configuration (2), a refused real-time setting (3-5),
    and every reason a coefficient file is refused (kExitBase + LoadError, read from the header: 21 and 22 were once
    missing, so systemd restarted an implausible file every second)."""
    header = (ROOT / "rt_monitor" / "include" / "rt_monitor" / "coefficients.hpp").read_text()
    base = int(re.search(r"kExitBase = (\d+);", header).group(1))
    enum = re.search(r"enum class LoadError : int \{(.*?)\};", header, re.S).group(1)
    reasons = [int(v) for v in re.findall(r"= (\d+),", enum) if int(v) > 0]
    prevented = set(map(int, _unit(prefix)["RestartPreventExitStatus"].split()))
    assert {2, 3, 4, 5} | {base + r for r in reasons} <= prevented, sorted(prevented)


def test_unit_runs_the_installed_monitor_with_the_rt_settings(prefix: Path) -> None:
    unit = _unit(prefix)
    argv = shlex.split(unit["ExecStart"])
    assert argv[0] == str(prefix / "bin" / "rt_monitor")
    assert {"--mlockall", "--priority", "--cpu"} <= set(argv)
    assert argv[argv.index("--priority") + 1] == unit["LimitRTPRIO"]  # the limit allows exactly that priority
    assert unit["LimitMEMLOCK"] == "infinity"
    assert argv[argv.index("--config") + 1] == str(prefix / "etc" / "dynid" / "rt_monitor.conf")
    if shutil.which("systemd-analyze"):
        done = subprocess.run(["systemd-analyze", "verify",
                               str(prefix / "lib" / "systemd" / "system" / "dynid-rt-monitor.service")],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and done.stderr == "", done.stderr  # unknown keys are warnings on stderr


def test_installed_monitor_runs_as_the_build_trees(prefix: Path, default_experiments: dict, tmp_path: Path) -> None:
    config = load_config("icub_right_arm")
    log = tmp_path / "part.log"
    write_candump(load_data(default_experiments["contact"], config).slice(10000, 12000), config, log)
    etc = prefix / "etc" / "dynid"
    shutil.copy(etc / "rt_monitor.conf.example", etc / "rt_monitor.conf")
    shutil.copy(COEF, etc / "model.dcoef")

    argv = shlex.split(_unit(prefix)["ExecStart"])
    if os.geteuid() != 0:  # the unit's limits grant these; a plain user here has none
        for opt, n in (("--mlockall", 1), ("--priority", 2)):
            i = argv.index(opt)
            del argv[i:i + n]
    if int(argv[argv.index("--cpu") + 1]) not in os.sched_getaffinity(0):
        i = argv.index("--cpu")
        del argv[i:i + 2]
    installed = subprocess.run(argv + ["--replay", str(log), "--lcm-url", f"file://{tmp_path / 'i.lcmlog'}?mode=w"],
                               capture_output=True, text=True, timeout=120, env=BARE_ENV)
    assert installed.returncode == 0, installed.stderr
    assert installed.stderr.startswith("rt_monitor: running: replay of")
    built = subprocess.run([str(BUILD / "rt_monitor" / "rt_monitor"), "--model", str(COEF), "--config",
                            str(ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"), "--replay", str(log),
                            "--lcm-url", f"file://{tmp_path / 'b.lcmlog'}?mode=w"],
                           capture_output=True, text=True, timeout=120)
    assert built.returncode == 0, built.stderr
    # Same counters (overruns aside: timing), same messages.
    assert installed.stdout.rsplit(", overruns", 1)[0] == built.stdout.rsplit(", overruns", 1)[0]
    assert "samples 2000," in installed.stdout
    import lcm

    def channels(p: Path) -> list[tuple[str, int]]:
        return [(e.channel, len(e.data)) for e in lcm.EventLog(str(p), "r")]

    assert channels(tmp_path / "i.lcmlog") == channels(tmp_path / "b.lcmlog") != []


def test_installed_launcher_finds_the_installed_jar(prefix: Path, tmp_path: Path) -> None:
    jar = prefix / "share" / "java" / "dynid-lcmtypes.jar"
    if not jar.is_file():
        pytest.skip("the Java types are not built (no JDK or no lcm.jar)")
    fake = tmp_path / "lcm-spy"
    fake.write_text("#!/bin/sh\necho \"$CLASSPATH\"\n")
    fake.chmod(0o755)
    done = subprocess.run([str(prefix / "bin" / "dynid-lcm-spy")], capture_output=True, text=True, timeout=60,
                          env={**BARE_ENV, "LCM_SPY": str(fake)})
    assert done.returncode == 0, done.stderr
    assert Path(done.stdout.strip()).resolve() == jar.resolve()


# A consumer of the installed types: includes from the prefix only (and the system's), encodes a status message and
# decodes it back, and prints the bytes for the Python type (lcm-gen's, generated by scripts/setup) to decode independently.
CONSUMER = r"""
#include <dynid/monitor_status_t.hpp>
#include <cstdio>
#include <vector>
int main() {
    dynid::monitor_status_t a{};
    a.utime = 1700000000123456;
    a.frames = 14000;
    a.late = 92;
    a.in_contact = 1;
    a.loop_us_max = 3.25;
    a.n_supply = 3;
    a.supply_ratio = {1.0, 0.9875, 1.03125};
    std::vector<uint8_t> wire(size_t(a.getEncodedSize()));
    const int n = a.encode(wire.data(), 0, int(wire.size()));
    dynid::monitor_status_t b;
    const int m = b.decode(wire.data(), 0, n);
    if (n != int(wire.size()) || m != n || b.late != a.late || b.supply_ratio != a.supply_ratio) return 1;
    for (uint8_t x : wire) std::printf("%02x", x);
    std::printf("\n");
    return 0;
}
"""


def test_installed_headers_compile_on_their_own(prefix: Path, tmp_path: Path) -> None:
    compiler = shutil.which("g++") or shutil.which("c++")
    assert compiler, "no C++ compiler (scripts/setup installs g++)"
    src, exe, deps = tmp_path / "consumer.cpp", tmp_path / "consumer", tmp_path / "consumer.d"
    src.write_text(CONSUMER)
    done = subprocess.run([compiler, "-std=c++17", "-Wall", "-Werror", "-I", str(prefix / "include"), "-MD", "-MF",
                           str(deps), str(src), "-o", str(exe)], capture_output=True, text=True, timeout=300,
                          env=BARE_ENV)
    assert done.returncode == 0, done.stderr
    # The LCM core header came from the prefix, not from a system-wide LCM.
    assert str(prefix / "include" / "lcm" / "lcm_coretypes.h") in deps.read_text().split()
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, env=BARE_ENV)
    assert run.returncode == 0, run.stderr
    from dynid.export.lcm_messages import monitor_status_t

    m = monitor_status_t.decode(bytes.fromhex(run.stdout.strip()))
    assert (m.utime, m.frames, m.late, m.in_contact, m.loop_us_max) == (1700000000123456, 14000, 92, 1, 3.25)
    assert (m.n_supply, list(m.supply_ratio)) == (3, [1.0, 0.9875, 1.03125])
