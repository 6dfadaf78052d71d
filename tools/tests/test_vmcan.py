"""Real SocketCAN, in a qemu guest: boards → vcan → rt_monitor → LCM, through the kernel's CAN_RAW sockets.

This kernel has no AF_CAN, so the SocketCAN source's socket()/bind(), its kernel filters and its SO_TIMESTAMP
stamps run nowhere else. scripts/vmcan boots Debian's kernel under qemu (TCG here; KVM where it works) with the
host's / shared read-only, creates vcan interfaces named as the configuration's buses (can0 can1 can2, and vcan0),
and runs guest.sh below in it, which:
1. runs the SocketCAN gtests, the ctest rt_can_vcan among them (skipped on this kernel, run here), in the plain
   and the sanitizer build;
2. starts rt_monitor on SocketCAN (no --replay/--loopback), publishing to a file:// LCM log (no network at all);
3. plays the e2e test's 6 s contact slice through `boards --sink socketcan --realtime`, while a small injector
   writes CAN error frames on can1 through a raw socket of its own;
4. stops the monitor with SIGTERM.
The host then decodes the LCM log and checks the events against the candump replay of the same slice
(test_can_e2e's `clean` run), every frame and sample against the boards' count, and the error frames counted.
Under TCG the guest's clock counts instructions (scripts/vmcan), so the 1 kHz sender keeps its period in the guest
however slow emulation is on the host; about 30–45 s here, most of it the boot and the 6 s of data.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import pytest
from test_can_e2e import START, STOP, T0_US, run_monitor

from dynid.config.robot_config import load_config
from dynid.export.monitor_config import monitor_config_text
from dynid.export.monitor_log import read_lcm_log
from dynid.io.candump import write_candump
from dynid.io.load import load_data

ROOT = Path(__file__).resolve().parents[2]
VMCAN = ROOT / "scripts" / "vmcan"
N_ERRORS = 5  # error frames the injector writes on can1

# Skipped, with the reason, only where no guest can run: no qemu, or no kernel and busybox in build/vmcan/.
_check = subprocess.run([str(VMCAN), "--check"], capture_output=True, text=True, timeout=60)
pytestmark = pytest.mark.skipif(_check.returncode != 0, reason=_check.stdout.strip() or _check.stderr.strip())

GUEST = r"""#!/bin/sh
# Inside the vmcan guest, from the repository root; $1: the shared work directory. The monitor runs as deployed
# (SCHED_FIFO 45, mlockall); the boards, which stand for separate hardware, above it (50), so that the monitor's
# load never delays a frame. The LCM log goes to the guest's /dev/shm (no 9p round trip in the loop), copied at the end.
W=$1
# The ctest rt_can_vcan and the other SocketCAN gtests, in both builds (scripts/setup makes the sanitizer one).
for b in build build-asan; do
    $b/rt_monitor/test_rt_can --gtest_filter='SocketCan.*' >"$W/gtest-$b.out" 2>&1; echo $? >"$W/gtest-$b.rc"
done
# Under TCG the guest's clock counts instructions (scripts/vmcan's -icount), except while the vCPU idles, when it
# follows the host's, whose scheduling delays would reach the boards' wake-ups: an idle-class spinner keeps it busy.
chrt -i 0 sh -c 'while :; do :; done' &
spin=$!
build/rt_monitor/rt_monitor --model "$W/model.dcoef" --config "$W/monitor.conf" --priority 45 --mlockall \
    >"$W/monitor.out" 2>"$W/monitor.err" &
mon=$!
python3 -I "$W/inject.py" can1 %(n)d "$W/inject.ready" >"$W/inject.out" 2>&1 &
inj=$!
i=0  # both are up: the monitor's sockets are bound (its start-up line), the injector's too
until grep -q '^rt_monitor: running' "$W/monitor.err" && [ -e "$W/inject.ready" ]; do
    i=$((i + 1)); [ $i -gt 600 ] && { echo "guest.sh: monitor or injector not up in 60 s"; break; }; sleep 0.1
done
build/firmware_like/boards --config "$W/monitor.conf" --data "$W/data.csv" --sink socketcan --realtime \
    --rt-priority 50 >"$W/boards.out" 2>&1
echo $? >"$W/boards.rc"
wait $inj; echo $? >"$W/inject.rc"
kill $spin
sleep 1  # the monitor drains its sockets
kill -TERM $mon; wait $mon; echo $? >"$W/monitor.rc"
cp /dev/shm/vcan.lcmlog "$W/"
cat "$W/boards.out" "$W/monitor.out"
""" % {"n": N_ERRORS}

# Error frames as a controller reports them (the e2e test's: CAN_ERR_CRTL, RX warning), 0.2 s apart while the
# boards play, through the kernel's CAN_RAW socket like any other sender.
INJECT = r"""
import socket, struct, sys, time
bus, n, ready = sys.argv[1], int(sys.argv[2]), sys.argv[3]
s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
s.bind((bus,))
open(ready, "w").close()
time.sleep(2.0)
for _ in range(n):
    # CAN_ERR_CRTL (linux/can/error.h; Python's socket module lacks it), data[1] CAN_ERR_CRTL_RX_WARNING
    s.send(struct.pack("=IB3x8s", socket.CAN_ERR_FLAG | 0x4, 8, bytes([0, 4, 0, 0, 0, 0, 0, 0])))
    time.sleep(0.2)
print(f"injected {n} error frames on {bus}")
"""


@pytest.fixture(scope="module")
def guest(default_experiments: dict, exported: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    work = tmp_path_factory.mktemp("vmcan")
    config = load_config("icub_right_arm")
    shutil.copy(exported, work / "model.dcoef")
    (work / "monitor.conf").write_text(monitor_config_text(config, "file:///dev/shm/vcan.lcmlog?mode=w"))
    lines = (Path(default_experiments["contact"]) / "data.csv").read_text().splitlines()
    (work / "data.csv").write_text("\n".join([lines[0], *lines[1 + START:1 + STOP]]) + "\n")
    (work / "guest.sh").write_text(GUEST)
    (work / "inject.py").write_text(INJECT)

    t = time.monotonic()
    done = subprocess.run([str(VMCAN), "--work", str(work), "--timeout", "240", "--", "sh", str(work / "guest.sh"),
                           str(work)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    took = time.monotonic() - t
    print(done.stdout)
    assert done.returncode == 0, done.stdout + done.stderr
    files = {p.name: p.read_text() for p in work.iterdir() if p.suffix in (".out", ".err", ".rc")}
    return {"work": work, "files": files, "took": took, "config": config, "coef": work / "model.dcoef",
            "msgs": read_lcm_log(work / "vcan.lcmlog") if (work / "vcan.lcmlog").exists() else {}}


@pytest.fixture(scope="module")
def replay(guest: dict, default_experiments: dict) -> dict:
    """test_can_e2e's `clean` run: the same slice, written by dynid.io.candump, replayed by the same monitor."""
    root = guest["work"] / "replay"
    root.mkdir()
    data = load_data(default_experiments["contact"], guest["config"]).slice(START, STOP)
    n_frames = write_candump(data, guest["config"], root / "clean.log")
    setup = {"root": root, "coef": guest["coef"], "config": guest["config"]}
    done, msgs = run_monitor(setup, root / "clean.log", "clean")
    assert done.returncode == 0, done.stderr
    assert msgs["DYNID_CONTACT"], "the slice holds a detected contact"
    return {"msgs": msgs, "n_frames": n_frames, "n_samples": data.n_samples}


@pytest.mark.parametrize("build", ["build", "build-asan"])
def test_socketcan_gtests_run_in_the_guest(guest: dict, build: str) -> None:
    """The ctest rt_can_vcan (skipped on this kernel) and the other SocketCAN tests, on a kernel with AF_CAN; in the
    AddressSanitizer + UBSan build too."""
    out = guest["files"][f"gtest-{build}.out"]
    assert guest["files"][f"gtest-{build}.rc"].strip() == "0", out
    assert "[       OK ] SocketCan.VcanRoundTrip" in out and "SKIPPED" not in out, out
    assert "[       OK ] SocketCan.FramesTheKernelDroppedAreCounted" in out, out  # SO_RXQ_OVFL


def test_boards_to_monitor_over_vcan_gives_the_replays_events(guest: dict, replay: dict) -> None:
    files, msgs = guest["files"], guest["msgs"]
    assert files["boards.rc"].strip() == "0", files["boards.out"]
    assert files["monitor.rc"].strip() == "0", files["monitor.err"]
    assert files["monitor.err"].startswith("rt_monitor: running: SocketCAN"), files["monitor.err"]

    # The same contact events as the candump replay, sample for sample, on the grid of the guest's CAN time.
    got = [(m.kind, m.sample, m.side) for m in msgs["DYNID_CONTACT"]]
    want = [(m.kind, m.sample, m.side) for m in replay["msgs"]["DYNID_CONTACT"]]
    assert got == want
    # Each at its sample's time on the boards' clock (the kernel's stamps; the replay's are the log's): within a
    # fraction of a period, where the sample clock's grid sits among the stamps of the sample's frames.
    sample0 = int(files["boards.out"].split("sample 0 at CLOCK_REALTIME ")[1].split()[0])
    assert all(abs(m.utime - sample0 - 1000 * m.sample) < 500 for m in msgs["DYNID_CONTACT"])
    assert [m.utime - T0_US for m in replay["msgs"]["DYNID_CONTACT"]] == [1000 * m.sample for m in replay["msgs"]["DYNID_CONTACT"]]

    # Every frame the boards wrote reached the monitor through the kernel, every sample was evaluated.
    n = int(files["boards.out"].split(" samples, ")[1].split(" frames")[0])
    assert n == replay["n_frames"]
    last = msgs["DYNID_STATUS"][-1]
    assert (last.frames, last.samples, last.samples_evaluated) == (n + N_ERRORS, replay["n_samples"], replay["n_samples"])
    assert last.stale_samples == last.unknown_id == last.bad_length == last.unpaired_strain == last.source_bad == 0
    assert last.interpolated == 0 and last.filter_restarts == 1  # nothing lost on the bus (late ones are kept)
    print(f"guest: {len(got)} events, the replay's; {last.late} samples late (not lost); whole guest run {guest['took']:.1f} s")


def test_error_frames_on_the_bus_are_counted(guest: dict) -> None:
    files, msgs = guest["files"], guest["msgs"]
    assert files["inject.rc"].strip() == "0", files["inject.out"]
    assert msgs["DYNID_STATUS"][-1].error_frames == N_ERRORS
    assert any(0 < m.error_frames < N_ERRORS for m in msgs["DYNID_STATUS"])  # counted live, while the boards played
    assert f"error frames {N_ERRORS}," in files["monitor.out"]
    assert files["monitor.out"].startswith("rt_monitor: stopped by signal;")  # SIGTERM, exit 0: no crash
    assert ", kernel drops 0," in files["monitor.out"]  # no frame dropped by the kernel (SO_RXQ_OVFL)

