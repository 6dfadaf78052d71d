"""The bus as data (dynid.config.bus): a robot that is no iCub, played, decoded and monitored with no robot code.

- Every bad bus description is refused with one line naming the field.
- A synthetic Panda run (the bundled `panda`'s CANopen-style bus: positions, velocities and joint torques on two buses)
  goes through `dynid play` (boards' generic encoder) into a candump log: `cantools decode` with the DBC of
  `dynid export --dbc` decodes every frame (no unknown ID, no wrong size) to the run's values within each signal's
  quantisation; `dynid import` of the log gives the run back within it; `rt_monitor --replay` with the robot's CAD
  coefficient file assembles every sample and its T² equals the core's on the imported samples (`rt_eval --stream`:
  the C++ and cantools decode the same bits to the same doubles).
- The player's refusals: a run without a value the bus carries, samples closer than one sample's frames.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid
import yaml
from test_rt_core import detector_columns, raw_samples, stream

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError, DataError
from dynid.export.coefficients import read_coefficients
from dynid.export.monitor_config import lcm_url_problem, url_for_writing
from dynid.export.monitor_log import read_lcm_log
from dynid.export.player import clock_drift, play_run
from dynid.io.dataset import Dataset
from dynid.io.load import load_data

ROOT = Path(__file__).resolve().parents[2]
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"
T0_US = 1_700_000_000_000_000
N = 1500  # 1.5 s at 1 kHz


def run(*args: object, stdin: Path | None = None) -> subprocess.CompletedProcess:
    with open(stdin or "/dev/null", "rb") as f:
        return subprocess.run([str(a) for a in args], stdin=f, capture_output=True, text=True, timeout=300)


# ---- the description's refusals --------------------------------------------------------------------------


def _robot(tmp_path: Path, edit) -> Path:
    data = yaml.safe_load((ROOT / "tools/dynid/config/robots/panda.yaml").read_text())
    edit(data["bus"])
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _frame(bus: dict, name: str) -> dict:
    return next(f for f in bus["frames"] if f["name"] == name)


REFUSED = {
    "an unknown key": (lambda b: b.update(colour="blue"), "field 'bus.colour' is not a known setting"),
    "a bus not listed": (lambda b: _frame(b, "TPDO1_2").update(bus="can9"),
                         "field 'bus.frames[1].bus' names 'can9', which is not in 'buses'"),
    "an extended ID": (lambda b: _frame(b, "TPDO1_2").update(id=0x800),
                       "field 'bus.frames[1].id' must be an 11-bit standard CAN ID, 0 to 0x7FF, got 2048"),
    "an ID twice on a bus": (lambda b: _frame(b, "TPDO1_2").update(id=0x181),
                             "field 'bus.frames[1].id' 0x181 is frame 'TPDO1_1''s on can0 already"),
    "a frame name twice": (lambda b: _frame(b, "TPDO1_2").update(name="TPDO1_1"),
                           "field 'bus.frames' names frame 'TPDO1_1' twice"),
    "a DLC of 9": (lambda b: _frame(b, "TPDO1_2").update(dlc=9), "field 'bus.frames[1].dlc' must be an integer 0 to 8"),
    "a signal past the DLC": (lambda b: _frame(b, "TPDO1_2").update(dlc=7),
                              "field 'bus.frames[1].signals[2].start' puts 'Torque' outside the frame's 7 bytes"),
    # a walkthrough's: the offset's range was named first, the signal leaving its frame not at all
    "a signal past the DLC with an offset": (
        lambda b: (_frame(b, "TPDO1_2").update(dlc=7), _frame(b, "TPDO1_2")["signals"][2].update(offset=300)),
        "field 'bus.frames[1].signals[2].start' puts 'Torque' outside the frame's 7 bytes"),
    "overlapping signals": (lambda b: _frame(b, "TPDO1_2")["signals"][1].update(start=24),
                            "field 'bus.frames[1].signals[1].start' overlaps signal 'Position' in frame 'TPDO1_2'"),
    "a big-endian signal overlapping": (
        lambda b: _frame(b, "TPDO1_2")["signals"][1].update(start=31, byte_order="big"),
        "field 'bus.frames[1].signals[1].start' overlaps signal 'Position' in frame 'TPDO1_2'"),
    "a torque's zero at the edge of its range": (
        lambda b: _frame(b, "TPDO1_2")["signals"][2].update(offset=300),
        "field 'bus.frames[1].signals[2].offset' 300 puts 'tau.panda_joint2' at -27.68 to 627.67: a sensor that reads "
        "both ways holds zero in the middle half of its range"),
    "a position's unit in degrees": (
        lambda b: _frame(b, "TPDO1_2")["signals"][0].update(unit="deg"),
        "field 'bus.frames[1].signals[0].unit' 'deg' is not a unit of q.panda_joint2: the bus's values are in the "
        "project's units, the scale converting to them (rad or m)"),
    "a 16-bit float": (lambda b: _frame(b, "TPDO1_2")["signals"][1].update(type="float"),
                       "field 'bus.frames[1].signals[1].length' must be 32 or 64 for an IEEE float, got 16"),
    "a scale of 0": (lambda b: _frame(b, "TPDO1_2")["signals"][1].update(scale=0),
                     "field 'bus.frames[1].signals[1].scale' must not be 0"),
    "an unknown joint": (lambda b: _frame(b, "TPDO1_2")["signals"][0].update(target="q.elbow"),
                         "'q.elbow' names joint 'elbow', which is not in 'joints'"),
    "a value carried twice": (lambda b: _frame(b, "TPDO1_2")["signals"][0].update(target="q.panda_joint1"),
                              "'q.panda_joint1' is carried by 'TPDO1_1.Position' already"),
    "a current of a torque robot": (lambda b: _frame(b, "TPDO1_2")["signals"][2].update(target="current.m0"),
                                    "'current.m0' names motor 'm0', which is not under 'motors'"),
    "an unknown target": (lambda b: _frame(b, "TPDO1_2")["signals"][2].update(target="speed"),
                          "'speed' is no target"),
    "a scaled flag": (lambda b: _frame(b, "TPDO1_2")["signals"][2].update(target="fault"),
                      "'fault' is a count or flag: an integer with scale 1 and offset 0"),
    "a flag of a value not carried": (lambda b: _frame(b, "TPDO1_2")["signals"].append(
        {"name": "Sat", "start": 63, "length": 1, "target": "saturated.tau.panda_joint1"}),
        "field 'bus.frames[1].signals[3].start' overlaps signal 'Torque'"),
    "a clock not sent last": (lambda b: b.update(clock="TPDO1_1"),
                              "field 'bus.clock' names 'TPDO1_1', but frame 'TPDO1_2' is sent at or after it"),
    "a clock of no frame": (lambda b: b.update(clock="SYNC"), "field 'bus.clock' names frame 'SYNC', which is not in"),
    "a pair apart by more than pair_us": (lambda b: b.update(pairs=[["TPDO1_1", "TPDO1_7"]], pair_us=100),
                                          "sends 'TPDO1_7' 300 µs after 'TPDO1_1': the second half follows the first"),
    "the clock as a first half": (lambda b: b.update(pairs=[["TPDO1_7", "TPDO1_6"]]),
                                  "sends 'TPDO1_6' -50 µs after 'TPDO1_7'"),
    "a frame beyond one period": (lambda b: _frame(b, "TPDO1_2").update(offset_us=-2000),
                                  "sends 'TPDO1_2' 2000 µs before the clock frame: a sample's frames fit in one period"),
    "a period under the rate's": (lambda b: _frame(b, "TPDO1_2").update(period_ms=0.5),
                                  "field 'bus.frames[1].period_ms' must be one sample period (1 ms) to 60000 ms"),
    "a stale_ms beyond the monitor's": (lambda b: b.update(stale_ms=5000), "field 'bus.stale_ms' must be 0.1 to 1000 ms"),
    # Found by a walkthrough of a lab's own bus: exported, played without the column, refused at the monitor's start
    "a joint no signal carries": (lambda b: _frame(b, "TPDO1_2")["signals"][0].pop("target"),
                                  "field 'bus.frames' carries no signal with target 'q.panda_joint2': every joint's "
                                  "position, motor input and F/T component must be on the bus"),
    "a joint torque no signal carries": (lambda b: _frame(b, "TPDO1_2")["signals"][2].pop("target"),
                                         "carries no signal with target 'tau.panda_joint2'"),
    "a patch no signal carries": (lambda b: b.update(patches=[{"name": "palm", "sides": {}}]),
                                  "field 'bus.patches' lists patch 'palm', which no signal carries"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_a_bad_bus_description_is_refused_with_one_line(case: str, tmp_path: Path) -> None:
    edit, why = REFUSED[case]
    with pytest.raises(ConfigError) as e:
        load_config(_robot(tmp_path, edit))
    assert why in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_a_bus_and_a_can_section_together_are_refused(tmp_path: Path) -> None:
    arm = yaml.safe_load((ROOT / "tools/dynid/config/robots/icub_right_arm.yaml").read_text())
    arm["bus"] = yaml.safe_load((ROOT / "tools/dynid/config/robots/panda.yaml").read_text())["bus"]
    (tmp_path / "arm.yaml").write_text(yaml.safe_dump(arm, sort_keys=False))
    with pytest.raises(ConfigError, match="and 'can' both describe the bus: give one"):
        load_config(tmp_path / "arm.yaml")


def test_the_icub_short_form_refuses_a_motor_that_takes_no_pwm(tmp_path: Path) -> None:
    """`can:` compiles PID_VAL frames into PWM values: a current-driven motor there would be read as a duty cycle."""
    arm = yaml.safe_load((ROOT / "tools/dynid/config/robots/icub_right_arm.yaml").read_text())
    arm["actuation"][0]["input"] = "current"
    (tmp_path / "arm.yaml").write_text(yaml.safe_dump(arm, sort_keys=False))
    with pytest.raises(ConfigError, match="whose input is current: the iCub board's PID_VAL frame carries PWM; describe "
                                          "this bus with 'bus:' instead") as e:
        load_config(tmp_path / "arm.yaml")
    assert "\n" not in str(e.value)


# LCM opens a file:// URL for reading unless it says mode=w or mode=a, the last mode= winning (liblcm 1.5.3); the
# monitor only publishes. (URL, the URL it should be; None: fine as it is.)
LCM_URLS = [
    ("file://{d}/e.lcmlog", "file://{d}/e.lcmlog?mode=w"),
    ("file://{d}/e.lcmlog?", "file://{d}/e.lcmlog?mode=w"),
    ("file://{d}/e.lcmlog?mode", "file://{d}/e.lcmlog?mode&mode=w"),
    ("file://{d}/e.lcmlog?mode=", "file://{d}/e.lcmlog?mode=w"),
    ("file://{d}/e.lcmlog?mode=r", "file://{d}/e.lcmlog?mode=w"),
    ("file://{d}/e.lcmlog?speed=2", "file://{d}/e.lcmlog?speed=2&mode=w"),
    ("file://{d}/e.lcmlog?xmode=w", "file://{d}/e.lcmlog?xmode=w&mode=w"),
    ("file://{d}/e.lcmlog?mode=w&mode=r", "file://{d}/e.lcmlog?mode=w&mode=w"),
    ("file://{d}/e.lcmlog?mode=r&mode=w", None),
    ("file://{d}/e.lcmlog?speed=2&mode=a", None),
    ("memq://", None),
]


@pytest.fixture(scope="module")
def arm_monitor(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(coefficient file, monitor configuration) of the default arm's CAD model."""
    root = tmp_path_factory.mktemp("lcm_url")
    coef, conf = root / "cad.dcoef", root / "arm.conf"
    assert dynid("export", "--cad", "--out", coef).returncode == 0
    assert dynid("export", "--robot", "icub_right_arm", "--monitor-config", conf).returncode == 0
    return coef, conf


@pytest.mark.parametrize(("url", "fixed"), LCM_URLS)
def test_an_lcm_log_the_monitor_would_open_for_reading_is_refused(url: str, fixed: str | None, tmp_path: Path,
                                                                  arm_monitor: tuple[Path, Path]) -> None:
    """`dynid export --lcm-url` and `rt_monitor` refuse such a URL by one rule, in one line that gives the URL it
    should be, before anything is written or run (found by a user's first try: 'No such file or directory')."""
    url, fixed = url.format(d=tmp_path), fixed and fixed.format(d=tmp_path)
    assert url_for_writing(url) == fixed
    coef, conf = arm_monitor
    done = run(*isolated(url), ROOT / "build/rt_monitor/rt_monitor", "--model", coef, "--config", conf, "--replay",
               "/dev/null", "--lcm-url", url)
    if fixed is None:  # LCM opened, the run started (and, on an empty replay, ends evaluating no sample: exit 6)
        assert "rt_monitor: running: replay of /dev/null" in done.stderr and "reading" not in done.stderr, done.stderr
        return
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        f"rt_monitor: error: LCM URL '{url}' opens its file for reading (LCM's default without mode=w or mode=a), "
        f"and the monitor writes: {fixed}"], done.stderr
    if url != LCM_URLS[0][0].format(d=tmp_path):
        return  # the command line's refusal once (url_for_writing gave the rest above): a process costs a second
    out = tmp_path / "arm.conf"
    done = dynid("export", "--robot", "icub_right_arm", "--monitor-config", out, "--lcm-url", url)
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        f"dynid export: error: --lcm-url {url} opens its file for reading (LCM's default without mode=w or mode=a), "
        f"and the monitor writes: {fixed}"], done.stderr
    assert not out.exists() and not (tmp_path / "e.lcmlog").exists()


def isolated(url: str) -> list[str]:
    """The prefix rt_monitor runs under for `url`: a udp URL in a network namespace of its own (`unshare --net`: lo
    only, down), so that a monitor that failed to refuse it could not reach the host's network either; without that
    (not root), the test is skipped and only the Python rule is held."""
    if not url.startswith("udp"):
        return []
    if os.geteuid() != 0 or not shutil.which("unshare"):
        pytest.skip("a udp URL is given to rt_monitor only inside a network namespace (needs root and unshare)")
    return ["unshare", "--net"]


# URLs liblcm cannot open as the monitor's LCM (URL, the reason's start; None: fine). Found by a walkthrough: export
# wrote `lcm_url bogus` and rt_monitor then failed with exit 1, not as a configuration error. Nothing here reaches the
# network: rt_monitor runs only on the refused URLs, which it refuses before LCM is opened, and the udp ones inside a
# network namespace of their own besides; the good ones (multicast among them) are judged by the Python rule alone.
BAD_LCM_URLS = [
    ("bogus", "no LCM provider 'bogus'"),
    ("udp://239.255.76.67:7667", "no LCM provider 'udp'"),
    ("file://", "a file:// URL names its log"),
    ("udpm://8.8.8.8:7667", "'8.8.8.8' is not a UDP multicast group"),
    ("udpm://239.255.76:7667", "'239.255.76' is not a UDP multicast group"),
    ("udpm://239.255.76.67.1:7667", "'239.255.76.67.1' is not a UDP multicast group"),
    ("udpm://239.256.76.67:7667", "'239.256.76.67' is not a UDP multicast group"),
    ("udpm://239.255.76.67:0", "port '0' is not 1-65535"),
    ("udpm://239.255.76.67:", "port '' is not 1-65535"),
    ("udpm://239.255.76.67:7667?ttl=256", "ttl '256' is not 0-255"),
    ("udpm://239.255.76.67:7667?ttl=x", "ttl 'x' is not 0-255"),
    ("udpm://239.255.76.67:7667?ttl=1", None),
    ("udpm://", None),
    ("tcpq://localhost:7700", None),
]


@pytest.mark.parametrize(("url", "why"), BAD_LCM_URLS)
def test_an_lcm_url_liblcm_cannot_open_is_a_configuration_error(url: str, why: str | None, tmp_path: Path,
                                                                arm_monitor: tuple[Path, Path]) -> None:
    """`dynid export --lcm-url` and rt_monitor refuse by one rule, in one line, exit 2, before anything is opened (a
    good URL is not run here: the monitor would open it)."""
    assert lcm_url_problem(url).startswith(why) if why else lcm_url_problem(url) == ""
    if why is None:
        return  # never opened: a good udpm URL would join a multicast group on the host network
    coef, conf = arm_monitor
    done = run(*isolated(url), ROOT / "build/rt_monitor/rt_monitor", "--model", coef, "--config", conf, "--replay",
               "/dev/null", "--lcm-url", url)
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        f"rt_monitor: error: LCM URL '{url}': {lcm_url_problem(url)}"], done.stderr
    if url == BAD_LCM_URLS[0][0]:  # the command line's refusal once: a process costs a second
        out = tmp_path / "arm.conf"
        done = dynid("export", "--robot", "icub_right_arm", "--monitor-config", out, "--lcm-url", url)
        assert done.returncode == 2 and done.stderr.strip().splitlines() == [
            f"dynid export: error: --lcm-url {url}: {lcm_url_problem(url)}"], done.stderr
        assert not out.exists()


@pytest.mark.parametrize("url", ["file:///tmp/my runs/e.lcmlog?mode=w", "file:///tmp/run#3.lcmlog?mode=w",
                                 "udpm://239.255.76.67:7667?ttl=0&x=\nstale_ms 1"])
def test_an_lcm_url_the_configuration_cannot_carry_is_refused(url: str, tmp_path: Path) -> None:
    """The configuration is whitespace-separated tokens with # comments: rt_monitor would read such a URL as another
    (a review found all three written with exit 0; the newline injected a configuration line)."""
    out = tmp_path / "arm.conf"
    done = dynid("export", "--robot", "icub_right_arm", "--monitor-config", out, "--lcm-url", url)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "cannot hold whitespace, '#' or control characters" in done.stderr and not out.exists()


# ---- a robot that is no iCub, end to end -----------------------------------------------------------------


@pytest.fixture(scope="module")
def panda(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A synthetic Panda run (sinusoids: q, its derivative, torques) played onto its bus, and what reads it back."""
    root = tmp_path_factory.mktemp("bus")
    config = load_config("panda")
    t = np.arange(N) * 1e-3
    k = np.arange(1, 8)
    # up to 2.6 rad/s, as the Panda's joints, about the middle of each joint's range (the watchdog flags a position
    # beyond it: joint 4's range is −3.07 to −0.07 rad, joint 6's −0.02 to 3.75)
    middle = np.array([0.0, 0.0, 0.0, -1.57, 0.0, 1.87, 0.0])
    q = 0.6 * np.sin(2 * np.pi * 0.1 * k * t[:, None] + k) + middle
    dq = 0.6 * 2 * np.pi * 0.1 * k * np.cos(2 * np.pi * 0.1 * k * t[:, None] + k)
    tau = {j: 20 * np.sin(3 * t + i) - 5 + 0.5 * i for i, j in enumerate(config.joints)}
    data = Dataset(t=t, joints=config.joints, q=q, dq=dq, tau=tau, meta={"robot": "panda"})
    data.save(root / "run.npz")
    log, dbc, conf, coef = root / "run.log", root / "panda.dbc", root / "panda.conf", root / "panda.dcoef"
    done = dynid("play", "--robot", "panda", "--data", root / "run.npz", "--sink", f"candump:{log}")
    assert done.returncode == 0, done.stderr
    assert "clamped" not in done.stdout  # every value within its signal's range
    lcm = root / "events.lcmlog"
    for args in (("--dbc", dbc, "--monitor-config", conf, "--lcm-url", f"file://{lcm}?mode=w"),
                 ("--cad", "--rate", "1000", "--out", coef)):
        done = dynid("export", "--robot", "panda", *args)
        assert done.returncode == 0, done.stderr
    return {"root": root, "config": config, "data": data, "log": log, "dbc": dbc, "conf": conf, "coef": coef,
            "lcm": lcm, "played": done}


def test_cantools_decodes_every_frame_to_the_run_within_quantisation(panda: dict) -> None:
    decoded = run(sys.executable, "-m", "cantools", "decode", "--single-line", panda["dbc"], stdin=panda["log"])
    assert decoded.returncode == 0, decoded.stderr
    lines = decoded.stdout.splitlines()
    assert len(lines) == len(panda["log"].read_text().splitlines()) == 7 * N
    assert not [l for l in lines if "Unknown frame id" in l or "Wrong data size" in l]
    bus, data = panda["config"].bus, panda["data"]
    worst: dict[str, float] = {}
    for line in lines:
        stamp, iface, frame = line.split(" ::")[0].split()
        k = (int(stamp[1:-1].replace(".", "")) - T0_US + 300) // 1000
        name, body = re.match(r"\s*(\w+)\((.*)\)$", line.split(" ::")[1]).groups()
        f = bus.frame(name)
        assert (f.bus, f.id) == (iface, int(frame.split("#")[0], 16))
        values = {n: float(v.split()[0]) for n, v in (x.split(": ") for x in body.split(", "))}
        for s in f.signals:
            family, _, j = s.target.partition(".")
            truth = {"q": data.q[k, data.joints.index(j)], "dq": data.dq[k, data.joints.index(j)],
                     "tau": data.tau[j][k]}[family]
            worst[family] = max(worst.get(family, 0), abs(values[s.name] - truth) / (s.scale / 2))
    assert worst.keys() == {"q", "dq", "tau"} and max(worst.values()) <= 1 + 1e-6, worst  # within half a step


def test_import_gives_the_run_back_within_quantisation(panda: dict) -> None:
    got, want, bus = load_data(panda["log"], panda["config"]), panda["data"], panda["config"].bus
    assert got.n_samples == N and np.abs(got.t - want.t).max() <= 0.5e-6  # stamps in µs
    scale = {s.target: s.scale for f in bus.frames for s in f.signals}
    for i, j in enumerate(want.joints):
        assert np.abs(got.q[:, i] - want.q[:, i]).max() <= scale[f"q.{j}"] / 2 * (1 + 1e-9), j
        assert np.abs(got.dq[:, i] - want.dq[:, i]).max() <= scale[f"dq.{j}"] / 2 * (1 + 1e-9), j
        assert np.abs(got.tau[j] - want.tau[j]).max() <= scale[f"tau.{j}"] / 2 * (1 + 1e-9), j
    assert got.meta["source_format"] == "candump" and not got.pwm and not got.ft


def test_the_monitor_assembles_every_sample_and_computes_the_cores_t2(panda: dict) -> None:
    done = run(RT_MONITOR, "--model", panda["coef"], "--config", panda["conf"], "--replay", panda["log"])
    assert done.returncode == 0, done.stderr
    assert f"frames {7 * N}, samples {N}, evaluated {N}, stale 0," in done.stdout, done.stdout
    assert "unknown id 0, bad length 0," in done.stdout and "interpolated 0, late 0," in done.stdout
    # The same samples through the core alone: the imported run (decoded by cantools) in the file's order.
    c = read_coefficients(panda["coef"])
    imported = load_data(panda["log"], panda["config"])
    out = stream(panda["coef"], raw_samples(imported, c), panda["root"])
    t2 = out[:, detector_columns(c)["t2"]]
    residuals = read_lcm_log(panda["lcm"])["DYNID_RESIDUAL"]
    assert len(residuals) >= 100  # every 10th evaluated sample once the filter is full (0.15 s)
    for m in residuals:
        k = round((m.utime - T0_US) / 1000)
        assert m.t2 == pytest.approx(t2[k], rel=1e-9, abs=1e-12), k


# ---- the player's refusals -------------------------------------------------------------------------------


def test_the_player_refuses_a_run_without_a_value_the_bus_carries(panda: dict, tmp_path: Path) -> None:
    data = panda["data"]
    # no torques, which the bus carries (a missing q̇ is estimated from q: the test above)
    without = Dataset(t=data.t, joints=data.joints, q=data.q, dq=data.dq)
    with pytest.raises(DataError, match=r"the run has no tau.panda_joint1, which frame \w+ of panda's bus carries"):
        play_run(panda["config"], without, f"candump:{tmp_path / 'x.log'}")
    assert not (tmp_path / "x.log").exists()


def test_a_position_beyond_its_signals_range_is_refused_not_clamped(panda: dict, tmp_path: Path) -> None:
    """A position scale too fine for the joint's travel (a walkthrough's 1e-7 rad on 16 bits: ±3.3 mrad; here 1e-10 on 32) played a log of
    clamped postures, exit 0, "5450 values clamped" its only trace; a velocity beyond its range is clamped and said
    (the test below), a position is refused."""
    config = panda["config"]
    frames = tuple(replace(f, signals=tuple(replace(s, scale=1e-10) if s.target == "q.panda_joint2" else s
                                            for s in f.signals)) for f in config.bus.frames)
    fine = replace(config, bus=replace(config.bus, frames=frames))
    with pytest.raises(DataError, match=r"q.panda_joint2 reaches 0.5\d+ \(sample 0\), beyond the -0.214748 to "
                                        r"0.214748 its signal TPDO1_2.Position carries \(32 bits, scale 1e-10\)"):
        play_run(fine, panda["data"].slice(0, 100), f"candump:{tmp_path / 'x.log'}")
    assert not (tmp_path / "x.log").exists()


def test_the_load_is_of_the_descriptions_bit_rate(panda: dict, tmp_path: Path) -> None:
    """The player's bus load is of the description's `bitrate`, as export --dbc prints it (a walkthrough's 500 kbit/s bus:
    export said 15.4 %, play 7.4 % of 1 Mbit/s; at 20 kbit/s export said 386 % and exited 0, play 7.4 %). A bus that
    cannot carry a sample in its period is refused by export, and the player's 70 % budget is of the same rate."""
    config, data = panda["config"], panda["data"].slice(0, 200)
    fast = play_run(config, data, f"candump:{tmp_path / 'a.log'}").load
    slow_config = replace(config, bus=replace(config.bus, bitrate=800_000))
    slow = play_run(slow_config, data, f"candump:{tmp_path / 'b.log'}").load
    assert set(slow) == set(fast) and all(slow[b] == pytest.approx(1.25 * fast[b], rel=0.01) for b in fast)
    assert all(slow[b] == pytest.approx(v, rel=0.02) for b, v in slow_config.bus.load().items())
    with pytest.raises(DataError, match=r"bus can0 is loaded at \d+ % \(70 % or more at 0.1 Mbit/s\)"):
        play_run(replace(config, bus=replace(config.bus, bitrate=100_000)), data, f"candump:{tmp_path / 'c.log'}")
    assert not (tmp_path / "c.log").exists()
    robot = _robot(tmp_path, lambda b: b.update(bitrate=20_000))
    done = dynid("export", "--robot", str(robot), "--dbc", str(tmp_path / "p.dbc"))
    assert done.returncode == 2 and "would be loaded at" in done.stderr and "do not fit in its period" in done.stderr
    assert not (tmp_path / "p.dbc").exists()


def test_values_beyond_a_signals_range_are_clamped_and_said(panda: dict, tmp_path: Path) -> None:
    """A few samples beyond a value's signal (not a position) are clamped as the board would send them, and said; a
    run beyond it on more than 1 % of its samples is refused: the signal's scale cannot carry it (a walkthrough's F/T
    scale a thousand times small: every sample clamped, exit 0)."""
    data = panda["data"].slice(0, 1000)
    dq = data.dq.copy()
    data.dq[[10, 500], 2] = [4.0, -5.0]  # beyond the ±3.28 rad/s of the velocity signals, 2 samples in 1000
    played = play_run(panda["config"], data, f"candump:{tmp_path / 'x.log'}")
    assert "boards: 2 values clamped at their signal's range (the first: dq.panda_joint3" in played.summary
    got = load_data(tmp_path / "x.log", panda["config"])
    assert 3.2767 - 1e-9 <= np.abs(got.dq).max() <= 3.2768 + 1e-9  # the int16 range at 1e-4 rad/s
    data.dq = dq * 4
    with pytest.raises(DataError, match=r"dq.panda_joint\d is beyond the -3.2768 to 3.2767 its signal TPDO[\w.]+ "
                                        r"carries \(16 bits, scale 0.0001\) on \d+ of 1000 samples \(the first: "):
        play_run(panda["config"], data, f"candump:{tmp_path / 'y.log'}")
    assert not (tmp_path / "y.log").exists()


def test_samples_closer_than_one_samples_frames_are_refused(panda: dict, tmp_path: Path) -> None:
    data = panda["data"].slice(0, 100)
    data.t = data.t * 0.2  # 200 µs apart; the Panda's bus sends a sample's frames over 300 µs
    with pytest.raises(DataError, match=r"two samples 200 us apart, while the bus table sends a sample's frames over "
                                        r"300 us: they would mix"):
        play_run(panda["config"], data, f"candump:{tmp_path / 'x.log'}")
    assert not (tmp_path / "x.log").exists()


def test_nominal_stamps_put_the_runs_own_samples_on_the_nominal_period(panda: dict, tmp_path: Path) -> None:
    """--stamps nominal: the bus's period (the Panda's 1 kHz) where the run's median step agrees with it to 5 %, as
    the coefficient file's period is taken; a run recorded at another rate keeps its own median step."""
    data = panda["data"].slice(0, 200)
    jitter = np.random.default_rng(0).uniform(-0.3e-3, 0.3e-3, data.n_samples)
    data.t = data.t + jitter
    data.t[50:] += 0.0042  # a gap of about 5 ms
    assert np.median(np.diff(data.t)) != 1e-3
    log = tmp_path / "nominal.log"
    played = play_run(panda["config"], data, f"candump:{log}", stamps="nominal")
    got = load_data(log, panda["config"])
    assert played.nominal_s == 1e-3 and got.n_samples == 200 and np.allclose(np.diff(got.t), 1e-3, atol=1e-12)
    assert np.abs(got.q - data.q).max() <= 0.5e-6 * (1 + 1e-9)  # the same samples, in order
    slow = data.slice(0, 200)
    slow.t = data.t[0] + 2.0 * (data.t - data.t[0])  # recorded at about 500 Hz: not the bus's rate
    played = play_run(panda["config"], slow, f"candump:{tmp_path / 'slow.log'}", stamps="nominal")
    assert played.nominal_s == pytest.approx(np.median(np.diff(slow.t)).round(6), abs=1e-12)


def test_play_says_where_the_nominal_period_comes_from_and_that_a_jittered_log_loses_its_time_axis(
        panda: dict, tmp_path: Path) -> None:
    data = panda["data"].slice(0, 300)
    data.t = data.t + np.random.default_rng(0).uniform(-0.3e-3, 0.3e-3, data.n_samples)  # a jittered logger's stamps
    data.save(tmp_path / "jittered.npz")
    done = dynid("play", "--robot", "panda", "--data", tmp_path / "jittered.npz", "--stamps", "nominal",
               "--sink", f"candump:{tmp_path / 'j.log'}")
    assert done.returncode == 0, done.stderr
    assert "samples at stamps every 1 ms (the bus's period)" in done.stdout
    assert "note: the log's stamps are the nominal grid, not the recording's" in done.stdout
    # re-stamped, the log maps to the run by sample, not by time (a walkthrough read the Panda's run 0.23 s off at
    # the end of a window whose recorded steps average 1.034 ms): the line says so, and it holds
    assert (f"time: the log's sample k is the run's k-th sample from t = {data.t[0]:.6g} s on, stamped k × 1 ms after "
            "the first; `dynid import`, `dynid spy` and rt_monitor count time from that first sample, so a time T there "
            "is the run's sample k = T / 1 ms") in done.stdout
    back = load_data(tmp_path / "j.log", panda["config"])
    assert back.t[0] == 0.0 and np.allclose(back.t, 1e-3 * np.arange(data.n_samples), atol=1e-9)
    assert np.abs(back.q - data.q).max() <= 0.5e-6 * (1 + 1e-9)  # sample k is the run's k-th
    # at its recorded stamps, the log's time counts from its first sample: where that is in the run is said (a
    # walkthrough read the foot's put-down 0.31 s early in the monitor's events of the iCub leg, whose run starts
    # at 0.31 s)
    done = dynid("play", "--robot", "panda", "--data", tmp_path / "jittered.npz", "--sink", f"candump:{tmp_path / 'r.log'}")
    assert done.returncode == 0, done.stderr
    assert (f"time: the log's first sample is the run's t = {data.t[0]:.6g} s; `dynid import`, `dynid spy` and "
            f"rt_monitor count time from it: a time there is the run's less {data.t[0]:.6g} s") in done.stdout
    slow = panda["data"].slice(0, 300)
    slow.t = 2.0 * slow.t  # recorded at 500 Hz on the Panda's 1 kHz bus, on the dot
    slow.save(tmp_path / "slow.npz")
    done = dynid("play", "--robot", "panda", "--data", tmp_path / "slow.npz", "--stamps", "nominal",
               "--sink", f"candump:{tmp_path / 's.log'}")
    assert done.returncode == 0, done.stderr
    assert "stamps every 2 ms (the run's median step: the bus's period, 1 ms, is not the run's)" in done.stdout
    assert "note:" not in done.stdout  # its steps are the grid's: nothing relabelled
    assert ("time:" in done.stdout) == (slow.t[0] != 0.0)


def test_a_run_without_the_velocity_the_bus_carries_sends_its_estimate(panda: dict, tmp_path: Path) -> None:
    # A simulated Panda run records q and torques, not q̇; the Panda's bus carries q̇ (TPDO1): the offline filter's.
    data = panda["data"].slice(0, 1000)
    truth = data.dq.copy()
    data.dq = None
    played = play_run(panda["config"], data, f"candump:{tmp_path / 'e.log'}")
    assert played.dq_estimated and played.samples == 1000
    got = load_data(tmp_path / "e.log", panda["config"])
    inner = slice(20, -20)  # the filter's ends are one-sided
    # within 0.2 % of the fastest joint's 2.6 rad/s: the filter's bias (measured 1.8e-3) and the bus's 1e-4 steps
    assert np.abs(got.dq[inner] - truth[inner]).max() < 5e-3
    assert not play_run(panda["config"], panda["data"].slice(0, 100), f"candump:{tmp_path / 'r.log'}").dq_estimated


def test_clock_drift_counts_whole_periods_and_leaves_real_losses_alone() -> None:
    t = np.concatenate([[0.0], np.cumsum(np.tile([0.010, 0.012], 500))])  # a logger's 10 and 12 ms at 100 Hz
    drift = clock_drift(t, 0.010)
    assert drift.span_s == pytest.approx(11.0) and drift.drift_s == pytest.approx(1.0) and drift.periods == 100
    assert drift.ppm == pytest.approx(1e6 / 11) and drift.misleads()
    lossy = np.delete(np.arange(1000) * 1e-3, [100, 500, 501, 502])  # samples lost, stamped on the period
    assert clock_drift(lossy, 1e-3).drift_s == pytest.approx(0.0, abs=1e-12) and not clock_drift(lossy, 1e-3).misleads()
    slow_clock = np.arange(1000) * 1.0002e-3  # a board clock 200 ppm slow: the sample clock follows it
    assert not clock_drift(slow_clock, 1e-3).misleads()


def test_play_names_recorded_stamps_that_drift_and_the_monitor_bridges_them(panda: dict, tmp_path: Path) -> None:
    """Recorded steps of 1.0 and 1.2 ms at the Panda's 1 kHz: `play` notes the drift, and the monitor bridges samples
    the run never lost; with --stamps nominal it evaluates the run's samples one for one."""
    data = panda["data"].slice(0, 600)
    data.t = data.t[0] + np.concatenate([[0.0], np.cumsum(np.tile([1.0e-3, 1.2e-3], 300)[:599])])
    data.save(tmp_path / "drift.npz")
    evaluated = {}
    for stamps in ("recorded", "nominal"):
        log = tmp_path / f"{stamps}.log"
        done = dynid("play", "--robot", "panda", "--data", tmp_path / "drift.npz", "--sink", f"candump:{log}",
                   "--stamps", stamps)
        assert done.returncode == 0, done.stderr
        assert ("note: the recorded steps are not whole periods of 1 ms" in done.stdout) == (stamps == "recorded")
        conf = tmp_path / f"{stamps}.conf"
        conf.write_text(panda["conf"].read_text().replace(str(panda["lcm"]), str(tmp_path / f"{stamps}.lcmlog")))
        done = run(RT_MONITOR, "--model", panda["coef"], "--config", conf, "--replay", log)
        # the recorded steps average 1.1 ms: not the file's period, which the watchdog says (the replay's exit 7)
        assert done.returncode == (7 if stamps == "recorded" else 0), done.stderr
        assert ("fault: sample period: the samples come 1200 µs apart" in done.stderr) == (stamps == "recorded")
        evaluated[stamps] = int(done.stdout.split(", evaluated ")[1].split(",")[0])
    assert evaluated["nominal"] == 600 and evaluated["recorded"] > 600  # bridged: samples the run never had


def test_buses_that_share_an_id_get_a_dbc_each(tmp_path: Path) -> None:
    """A DBC holds an ID once and `cantools decode` matches on the ID alone: two buses reusing node IDs (two CANopen
    chains) are written as one DBC per bus, each decoding its bus."""
    robot = _robot(tmp_path, lambda b: [_frame(b, f"TPDO1_{n}").update(id=0x180 + n - 4) for n in (5, 6, 7)])
    out = tmp_path / "panda.dbc"
    done = dynid("export", "--robot", robot, "--dbc", out, "--json", tmp_path / "e.json")
    assert done.returncode == 0, done.stderr
    assert not out.exists() and (tmp_path / "panda-can0.dbc").is_file() and (tmp_path / "panda-can1.dbc").is_file()
    import cantools

    for bus, ids in (("can0", {0x181, 0x182, 0x183, 0x184}), ("can1", {0x181, 0x182, 0x183})):
        db = cantools.database.load_file(str(tmp_path / f"panda-{bus}.dbc"), strict=True)
        assert {m.frame_id for m in db.messages} == ids, bus


def test_play_estimates_dq_only_where_the_run_records_no_velocity(panda: dict, tmp_path: Path) -> None:
    """The Panda's bus carries q̇. A run with neither dq nor the controller's velocity.J sends the derivative filter's
    estimate, and says so; one with velocity.J sends those (a walkthrough's UR10e log was told it recorded none)."""
    data = panda["data"].slice(0, 300)
    bare = replace(data, dq=None)
    played = play_run(panda["config"], bare, f"candump:{tmp_path / 'bare.log'}", stamps="nominal")
    assert played.dq_estimated
    recorded = 1.05 * data.dq  # a controller's velocity, 5 % off q's rate: what is sent tells which one went out
    measured = replace(bare, extra={f"velocity.{j}": recorded[:, i] for i, j in enumerate(data.joints)})
    played = play_run(panda["config"], measured, f"candump:{tmp_path / 'measured.log'}", stamps="nominal")
    assert not played.dq_estimated
    back = load_data(tmp_path / "measured.log", panda["config"])
    sent = back.dq if back.dq is not None else np.column_stack([back.extra[f"velocity.{j}"] for j in data.joints])
    assert np.abs(sent - recorded).max() <= 0.5e-4 * (1 + 1e-9)  # the recorded ones, to the bus's quantum
