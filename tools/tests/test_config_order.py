"""The monitor configuration's keys come in any order, for both programs that read it (rt_monitor, boards).

A configuration with the settings (`lcm_url` among them), the patches, the clock and pair, every signal line before
the frame lines it names, and `buses` last, loads and behaves as the bundled arm's ordered one: the same frames from `boards`, the same counters and the same
published contact events and residuals from `rt_monitor`, each run publishing to the `lcm_url` of its own file.
A board line naming a bus the `buses` line lacks, a missing and a second `buses` line are still refused with one
line naming the problem. Driven through the command lines only (no dynid import).
"""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import pytest
from conftest import dynid

ROOT = Path(__file__).resolve().parents[2]
BOARDS = ROOT / "build" / "firmware_like" / "boards"
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"
COEF = ROOT / "rt_monitor" / "tests" / "data" / "icub_cad.dcoef"
CONF = ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"


def run(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=300)


def ordered(url: str) -> str:
    """The bundled arm's configuration with an lcm_url after buses, where dynid writes it."""
    lines = CONF.read_text().splitlines()
    at = next(i for i, l in enumerate(lines) if l.startswith("buses ")) + 1
    return "\n".join(lines[:at] + [f"lcm_url {url}"] + lines[at:]) + "\n"


def shuffled(url: str) -> str:
    """The same keys with `buses` last: settings, lcm_url, patches, clock and pair, the signals, then the frames
    they belong to. Repeated keys keep their relative order (the patch lines number the skin mask's bits, a frame's
    signal lines its signals, the frame lines the send order)."""
    lines = ordered(url).splitlines()
    kind = {k: [l for l in lines if l.split(" ", 1)[0] in k] for k in
            [("#",), ("lcm_url",), ("robot", "stale_ms", "pair_us", "status_hz", "residual_every", "contact_limit_s"),
             ("patch",),
             ("clock", "pair"), ("signal",), ("frame",), ("buses",)]}
    out = [l for k in kind.values() for l in k]
    assert sorted(out) == sorted(lines)
    assert out.index(f"lcm_url {url}") < out.index(next(l for l in out if l.startswith("buses ")))
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short simulated contact run through the board emulators, as a candump log."""
    root = tmp_path_factory.mktemp("order")
    done = dynid("simulate", "--kind", "contact", "--duration", "2", "--out", root / "run")
    assert done.returncode == 0, done.stderr
    (root / "ordered.conf").write_text(ordered("memq://"))
    done = run(BOARDS, "--config", root / "ordered.conf", "--data", root / "run", "--sink", f"candump:{root / 'run.log'}")
    assert done.returncode == 0, done.stderr
    return root / "run.log"


def test_boards_sends_the_same_frames_with_buses_last(log: Path, tmp_path: Path) -> None:
    conf = tmp_path / "shuffled.conf"
    conf.write_text(shuffled("memq://"))
    out = tmp_path / "shuffled.log"
    done = run(BOARDS, "--config", conf, "--data", log.parent / "run", "--sink", f"candump:{out}")
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == log.read_bytes()
    assert "bus can2 load 61.5 %" in done.stdout  # every board where it was


def _lcm_events(path: Path) -> list[tuple[str, bytes]]:
    """(channel, payload) of each event of an LCM log file (big-endian: sync, number, time, lengths)."""
    data, out, at = path.read_bytes(), [], 0
    while at < len(data):
        sync, _, _, n_channel, n_data = struct.unpack_from(">IqqII", data, at)
        assert sync == 0xEDA1DA01
        at += 28
        out.append((data[at:at + n_channel].decode(), data[at + n_channel:at + n_channel + n_data]))
        at += n_channel + n_data
    return out


def test_rt_monitor_behaves_the_same_with_buses_last(log: Path, tmp_path: Path) -> None:
    results = {}
    for name, text in (("ordered", ordered), ("shuffled", shuffled)):
        lcm_log = tmp_path / f"{name}.lcmlog"
        conf = tmp_path / f"{name}.conf"
        conf.write_text(text(f"file://{lcm_log}?mode=w"))  # the configuration's own URL: no --lcm-url
        done = run(RT_MONITOR, "--model", COEF, "--config", conf, "--replay", log)
        assert done.returncode == 0, done.stderr
        assert f"LCM file://{lcm_log}?mode=w" in done.stderr  # the start-up line: lcm_url was read
        events = _lcm_events(lcm_log)
        # Status messages carry loop times (wall clock); contact events and residuals are the data's alone.
        results[name] = (done.stdout.rsplit(", overruns", 1)[0],
                         [e for e in events if e[0] != "DYNID_STATUS"],
                         sum(e[0] == "DYNID_STATUS" for e in events))
    assert results["shuffled"] == results["ordered"]
    stdout, published, n_status = results["ordered"]
    assert "samples 2000, evaluated " in stdout and ", stale 0," in stdout  # every sample assembled
    assert len(published) > 100 and n_status >= 19  # residuals every 10th sample, status at 10 Hz


@pytest.mark.parametrize("case", ["unknown bus", "no buses", "second buses"])
def test_bad_bus_lines_are_one_clear_line(case: str, tmp_path: Path) -> None:
    lines = shuffled("memq://").splitlines()
    if case == "unknown bus":
        bad = next(i for i, l in enumerate(lines) if l.startswith("frame MC_POSITION_3 can1 "))
        lines[bad] = lines[bad].replace(" can1 ", " can7 ")
        rt_why = f"{tmp_path}/bad.conf:{bad + 1}: bus 'can7' is not in the 'buses' line (can0 can1 can2)"
        boards_why = f"{tmp_path}/bad.conf:{bad + 1}: bus 'can7' is not in the 'buses' line"
    elif case == "no buses":
        lines = lines[:-1]
        rt_why = (f"{tmp_path}/bad.conf: no 'buses' line (not an rt_monitor configuration? `dynid export --robot "
                  "CFG --monitor-config FILE` writes one)")  # line 0: the file's (as for "no 'clock' line")
        boards_why = f"{tmp_path}/bad.conf: no 'buses' line"
    else:
        lines.insert(1, "buses can0 can1")
        rt_why = boards_why = f"{tmp_path}/bad.conf:{len(lines)}: a second 'buses' line (the first is line 2)"
    conf = tmp_path / "bad.conf"
    conf.write_text("\n".join(lines) + "\n")
    empty = tmp_path / "empty.log"
    empty.write_text("")
    done = run(RT_MONITOR, "--model", COEF, "--config", conf, "--replay", empty)
    assert done.returncode == 2
    assert done.stderr.splitlines()[0] == f"rt_monitor: error: {rt_why}", done.stderr
    data = tmp_path / "data.csv"
    data.write_text("t\n0\n")
    done = run(BOARDS, "--config", conf, "--data", data, "--sink", f"candump:{tmp_path / 'x.log'}")
    assert done.returncode == 4
    assert done.stderr.splitlines() == [f"boards: error: {boards_why}"], done.stderr


# Issue 22: what a hostile user got past the monitor's configuration. Each is now exit 2 and one line on stderr
# naming the file, the line and the problem (no usage line: the arguments were fine); nothing is read or published.
REFUSED = {
    "joint carried twice": ("append", "frame EXTRA can2 0x7F0 4 0 extra 0 -10\nsignal EXTRA 0 32 le s 1e-05 0.0 q.r_elbow",
                            "'q.r_elbow' is carried by another signal already (line {q.r_elbow})"),
    "frame duplicated": ("dup", "frame MC_POSITION_1 ", "a second frame 'MC_POSITION_1' (the first is line {first})"),
    "signal duplicated": ("dup", "signal MC_PID_VAL_2 16 ", "the signal at bit 16 overlaps another signal of frame 'MC_PID_VAL_2'"),
    "clock duplicated": ("dup", "clock ", "a second 'clock' line (the first is line {first})"),
    "an old strain line": ("append", "strain can0 13 200.0 200.0 200.0 10.0 10.0 10.0",
                           "'strain' is a line of the iCub-only format before the bus description: write the "
                           "configuration again (dynid export --robot ROBOT --monitor-config FILE)"),
    "stale_ms huge": ("set", "stale_ms 99999999999", "stale_ms 99999999999 is out of range: 0.1 to 1000 ms"),
    "stale_ms 0": ("set", "stale_ms 0", "stale_ms 0 is out of range: 0.1 to 1000 ms"),
    "pair_us huge": ("set", "pair_us 99999999999", "pair_us 99999999999 is out of range: 1 to 10000 µs"),
    "status_hz huge": ("set", "status_hz 99999999999", "status_hz 99999999999 is out of range: 0.1 to 1000 Hz"),
    "no robot": ("drop", "robot ", "no 'robot' line (the coefficient file's robot is checked against it)"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_refused_configuration_is_one_line(case: str, tmp_path: Path) -> None:
    how, text, why = REFUSED[case]
    lines = CONF.read_text().splitlines()
    first = next((i + 1 for i, l in enumerate(lines) if l.startswith(text)), 0)
    elbow = next(i + 1 for i, l in enumerate(lines) if l.endswith(" q.r_elbow"))
    why = why.replace("{first}", str(first)).replace("{q.r_elbow}", str(elbow))
    at = 0
    if how == "append":
        lines.extend(text.split("\n"))
        at = len(lines)
    elif how == "dup":
        lines.append(next(l for l in lines if l.startswith(text)))
        at = len(lines)
    elif how == "set":
        key = text.split()[0]
        at = next(i for i, l in enumerate(lines) if l.startswith(key + " ")) + 1
        lines[at - 1] = text
    else:
        lines = [l for l in lines if not l.startswith(text)]
    conf = tmp_path / "bad.conf"
    conf.write_text("\n".join(lines) + "\n")
    empty = tmp_path / "empty.log"
    empty.write_text("")
    done = run(RT_MONITOR, "--model", COEF, "--config", conf, "--replay", empty, "--lcm-url", "memq://")
    assert done.returncode == 2, done.stderr
    where = f"{conf}:{at}" if at else str(conf)  # a line the file lacks: the file's own
    assert done.stderr.splitlines() == [f"rt_monitor: error: {where}: {why}"], done.stderr
    assert done.stdout == ""
