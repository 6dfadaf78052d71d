"""The monitor never runs blind in silence (issue 31): each case used to evaluate nothing, or alarm from wrong data,
with exit 0 and no word. Now the watchdog raises a status fault (DYNID_STATUS `faults`) with one line on stderr
naming the reason, a replay that evaluated nothing or ended blind exits 6, and an implausible scale is refused at
load (exit 2). A live run whose strain board goes silent is a named fault within 100 ms.
"""

from __future__ import annotations

import re
import signal
import socket
import struct
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import pytest

from dynid.config.robot_config import load_config
from dynid.export.monitor_config import monitor_config_text
from dynid.export.monitor_log import read_lcm_log
from dynid.io.candump import write_candump
from dynid.io.load import load_data

ROOT = Path(__file__).resolve().parents[2]
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"
BLIND, SILENT, NOT_FINITE, PERIOD, JOINT_RANGE, STOPPED, DUTY_RANGE, START_FIT, BRIDGED, TIME_BACK, LONG_CONTACT = (
    1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024)
EXIT_BLIND = 6
EXIT_FAULTED = 7  # a replay to its end that raised a fault


@pytest.fixture(scope="module")
def bench(default_experiments: dict, exported: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """10 s of the default contact run as a candump log, the exported default model, the bundled configuration."""
    root = tmp_path_factory.mktemp("watchdog")
    config = load_config("icub_right_arm")
    data = load_data(default_experiments["contact"], config).slice(0, 10_000)
    log = root / "run.log"
    write_candump(data, config, log)
    return {"root": root, "config": config, "coef": exported, "log": log, "data": data}


def replay(bench: dict, name: str, change=lambda text: text, coef: Path | None = None, log: Path | None = None):
    """rt_monitor --replay of the run with the configuration text changed: (exit, stderr, LCM messages)."""
    lcm = bench["root"] / f"{name}.lcmlog"
    conf = bench["root"] / f"{name}.conf"
    conf.write_text(change(monitor_config_text(bench["config"], f"file://{lcm}?mode=w")))
    done = subprocess.run([str(RT_MONITOR), "--model", str(coef or bench["coef"]), "--config", str(conf), "--replay",
                           str(log or bench["log"])], capture_output=True, text=True, timeout=300)
    whole = done.returncode in (0, EXIT_FAULTED)  # read to its end: the log in place; else the failed replay's own
    written = lcm if whole else lcm.with_name(lcm.name + ".failed")
    return done.returncode, done.stderr, (read_lcm_log(written) if written.exists() else {})


def faults(msgs: dict) -> int:
    seen = 0
    for m in msgs.get("DYNID_STATUS", []):
        seen |= m.faults_seen
    return seen


def test_a_clean_replay_raises_no_fault(bench: dict) -> None:
    code, err, msgs = replay(bench, "clean")
    assert code == 0 and "fault:" not in err and "raised faults" not in err, err
    assert faults(msgs) == 0 and msgs["DYNID_STATUS"][-1].samples_evaluated == 10_000
    assert all(m.faults == 0 for m in msgs.get("DYNID_CONTACT", []))


def test_pair_us_below_the_halves_spacing_is_blind_and_says_why(bench: dict) -> None:
    """`pair_us 1`, inside its documented range, pairs no strain halves: zero samples evaluated, once with exit 0."""
    code, err, msgs = replay(bench, "pair", lambda t: t.replace("pair_us 500", "pair_us 1"))
    assert code == EXIT_BLIND, err
    assert re.search(r"fault: blind: no sample evaluated for [\d.]+ ms: the clock pair's halves are not paired "
                     r"\(pair_us 1 µs; the last pair refused came \d+ µs apart\)", err), err
    assert "rt_monitor: error: evaluated no sample" in err
    assert faults(msgs) & BLIND


@pytest.mark.parametrize("frame, new_id, words", [
    ("STRAIN_TORQUE_13", "0x30B", "no clock frame STRAIN_TORQUE_13 (0x30B on can0)"),  # the strain board moved
    ("MC_POSITION_4", "0x101", "every sample is stale (q.r_wrist_yaw not renewed"),     # an axis's address changed
])
def test_a_wrong_address_is_blind_and_named(bench: dict, frame: str, new_id: str, words: str) -> None:
    code, err, msgs = replay(bench, frame, lambda t: re.sub(rf"^frame {frame} (\S+) 0x[0-9A-Fa-f]+ ",
                                                            rf"frame {frame} \1 {new_id} ", t, flags=re.M))
    assert code == EXIT_BLIND and words in err, err
    assert "fault: silent frame: frame " in err, err  # its own frame never comes
    assert faults(msgs) & BLIND and faults(msgs) & SILENT


@pytest.mark.parametrize("target, scale", [("ft.r_arm_ft.fx", "1e-300"), ("pwm.m0", "1e-300"), ("q.r_elbow", "1e+300")])
def test_an_implausible_scale_is_refused_at_load(bench: dict, target: str, scale: str) -> None:
    def change(text: str) -> str:
        return re.sub(rf"^(signal \S+ \d+ \d+ \w+ \w) \S+ (\S+ {re.escape(target)})$", rf"\1 {scale} \2", text, flags=re.M)
    code, err, msgs = replay(bench, f"scale-{target}", change)
    assert code == 2 and err.count("\n") == 1, err
    assert f"'{target}': scale {scale.replace('+', '')}" in err.replace("e+", "e") and "outside the plausible" in err, err


def test_an_offset_that_puts_zero_at_the_edge_is_refused_at_load(bench: dict) -> None:
    """The strain board's fx offset 0 instead of −200: a force sensor that would read 0 to 400 N."""
    code, err, _ = replay(bench, "ft-offset", lambda t: re.sub(r"^(signal \S+ \d+ \d+ \w+ \w \S+) -200.0 (ft.r_arm_ft.fx)$",
                                                               r"\1 0.0 \2", t, flags=re.M))
    assert code == 2 and err.count("\n") == 1, err
    assert "'ft.r_arm_ft.fx': offset 0 puts its decoded range at 0 to 399.994" in err and "middle half" in err, err


def test_a_pwm_offset_is_a_duty_fault(bench: dict) -> None:
    """pwm.m0's offset −1 (in range for the signal): duties beyond ±1, named on status and stderr."""
    code, err, msgs = replay(bench, "duty", lambda t: re.sub(r"^(signal \S+ \d+ \d+ \w+ \w \S+) 0.0 (pwm.m0)$",
                                                         r"\1 -1.0 \2", t, flags=re.M))
    assert "fault: duty out of range: pwm.m0 at" in err and "beyond ±1 duty" in err, err
    assert faults(msgs) & DUTY_RANGE


def test_a_model_that_is_not_the_robots_is_a_start_fit_fault(bench: dict, tmp_path: Path) -> None:
    """A CRC-valid file whose gravity points up: every value plausible, T² above T²_α from the start. A fitted file's
    known answers refuse it at load; one without them (a CAD export's kind) runs into the start-fit fault."""
    from dynid.export.coefficients import unwrap, wrap
    from dynid.export.lcm_coefficients import coefficients_t
    from test_rt_core import without_known_answers

    c = coefficients_t.decode(unwrap(Path(bench["coef"]).read_bytes()))
    c.gravity = [-g for g in c.gravity]
    coef = tmp_path / "up.dcoef"
    coef.write_bytes(wrap(c.encode()))
    code, err, msgs = replay(bench, "gravity-up", coef=coef)
    assert code == 22 and "does not reproduce the file's known answers" in err, err
    coef.write_bytes(wrap(without_known_answers(c).encode()))
    code, err, msgs = replay(bench, "gravity-up", coef=coef)
    assert "fault: model does not fit at start: T² above T²_α on" in err and "of the first 4000 samples" in err, err
    assert faults(msgs) & START_FIT


def test_a_wrong_encoder_scale_is_a_joint_range_fault_not_silence(bench: dict) -> None:
    """Ticks per degree off by 100 (in range): positions far outside the joint's limits, named on status and stderr."""
    def change(text: str) -> str:
        return re.sub(r"^(signal MC_POSITION_2 32 32 le s) (\S+) (0.0 q.r_elbow)$",
                      lambda m: f"{m[1]} {float(m[2]) * 100!r} {m[3]}", text, flags=re.M)
    code, err, msgs = replay(bench, "ticks", change)
    assert "fault: joint out of range: r_elbow at" in err and "a wrong encoder scale or zero" in err, err
    assert faults(msgs) & JOINT_RANGE


def test_a_file_for_another_sample_rate_is_a_period_fault(bench: dict, tmp_path: Path) -> None:
    """A coefficient file of 500 Hz against the arm's 1 kHz stream: its filter and thresholds are for another rate."""
    coef = tmp_path / "cad500.dcoef"
    done = subprocess.run([str(ROOT / ".venv" / "bin" / "dynid"), "export", "--cad", "--rate", "500", "--out", str(coef)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    code, err, msgs = replay(bench, "period", coef=coef)
    assert "fault: sample period: the samples come 1000 µs apart, the coefficient file's period is 2000 µs" in err, err
    assert faults(msgs) & PERIOD


def test_a_strain_board_gone_silent_live_is_a_fault_within_100_ms(bench: dict, tmp_path: Path) -> None:
    """Frames paced in real time over the loopback transport; after 1 s the strain board stops, the others go on."""
    lcm = tmp_path / "live.lcmlog"
    conf = tmp_path / "live.conf"
    conf.write_text(monitor_config_text(bench["config"], f"file://{lcm}?mode=w"))
    proc = subprocess.Popen([str(RT_MONITOR), "--model", str(bench["coef"]), "--config", str(conf), "--loopback",
                             str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(100):  # the monitor binds its sockets at start-up
            if all((tmp_path / f"{b}.can").exists() for b in bench["config"].can["buses"]):
                break
            time.sleep(0.05)
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        frames: dict[int, list[tuple[str, int, bytes]]] = {}
        for line in bench["log"].read_text().splitlines():
            stamp, bus, frame = line.split()
            can_id, payload = frame.split("#")
            frames.setdefault(round(float(stamp[1:-1]) * 1000), []).append((bus, int(can_id, 16), bytes.fromhex(payload)))
        ticks = sorted(frames)[:1500]
        start = time.monotonic()
        for k, tick in enumerate(ticks):
            for bus, can_id, data in frames[tick]:
                if k >= 1000 and can_id in (0x3DA, 0x3DB):  # the strain board goes silent at 1 s
                    continue
                sock.sendto(struct.pack("<IB3x8s", can_id, len(data), data), str(tmp_path / f"{bus}.can"))
            wait = start + (k + 1) * 1e-3 - time.monotonic()
            if wait > 0:
                time.sleep(wait)
        time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "fault: blind: no sample evaluated for" in err and "no clock frame STRAIN_TORQUE_13" in err, err
    msgs = read_lcm_log(lcm)
    residuals = [m.utime for m in msgs["DYNID_RESIDUAL"]]
    first_fault = next(m.utime for m in msgs["DYNID_STATUS"] if m.faults & BLIND)
    last_sample = max(u for u in residuals if u < first_fault)
    print(f"the fault {1e-3 * (first_fault - last_sample):.1f} ms after the last residual message (every 10 samples)")
    assert first_fault - last_sample <= 100_000


def test_stamps_a_tenth_apart_are_a_period_fault(bench: dict, tmp_path: Path) -> None:
    """The stream 1.1 times slower than the file's period passed the old ±20 % check: the sample clock invented a
    sample in ten, with no fault (a walkthrough: TIAGo at 1.15, 15 % of its samples). Now ±5 %."""
    lines = bench["log"].read_text().splitlines()
    t0 = float(lines[0][1:lines[0].index(")")])
    stretched = tmp_path / "stretched.log"
    stretched.write_text("".join(f"({t0 + 1.1 * (float(l[1:l.index(')')]) - t0):.6f}){l[l.index(')') + 1:]}\n"
                                 for l in lines))
    code, err, msgs = replay(bench, "stretched", log=stretched)
    assert "fault: sample period: the samples come 1100 µs apart, the coefficient file's period is 1000 µs" in err, err
    assert faults(msgs) & PERIOD
    # It published contacts and exited 0, its events alike to any other's (a review): now each event carries the
    # faults active when it was published, spy says so, and the replay's exit names them
    assert code == EXIT_FAULTED, err
    events = msgs["DYNID_CONTACT"]
    # raised at the 64th sample, before the first onset; the sample clock bridges one sample in eleven besides
    assert events and all(m.faults == PERIOD | BRIDGED for m in events)
    assert re.search(rf"warning: the replay raised faults \(sample period, samples bridged; DYNID_STATUS faults_seen "
                     rf"{PERIOD | BRIDGED}\): {len(events)} of its {len(events)} events came while one held", err), err
    spied = subprocess.run([str(ROOT / ".venv" / "bin" / "dynid"), "spy", "--lcm-url",
                            f"file://{bench['root'] / 'stretched.lcmlog'}?speed=0"],
                           capture_output=True, text=True, timeout=120)
    assert spied.returncode == 0, spied.stderr
    marked = [l for l in spied.stdout.splitlines() if "contact" in l and "UNDER FAULT: SAMPLE PERIOD, SAMPLES BRIDGED" in l]
    assert len(marked) == len(events), spied.stdout


def test_a_frame_at_half_its_rate_is_a_bridged_fault(bench: dict, tmp_path: Path) -> None:
    """One joint's position frame every other sample: half the samples were interpolated, with no fault (only the
    `interpolated` counter said it). Now a fault names the share; a clean replay bridges none."""
    halved = thinned(bench, tmp_path, 2, "halved", upto=0.5)  # the first half of the run; the second clean
    code, err, msgs = replay(bench, "halved", log=halved)
    assert re.search(r"fault: samples bridged: (4\d|5\d) % of the last 1000 samples bridged by interpolation", err), err
    assert faults(msgs) & BRIDGED and not msgs["DYNID_STATUS"][-1].faults & BRIDGED  # cleared by the clean half
    assert msgs["DYNID_STATUS"][-1].interpolated > 0.2 * 10_000
    # One frame in five: gaps too long to bridge, the filter restarting every few samples
    code, err, msgs = replay(bench, "fifth", log=thinned(bench, tmp_path, 5, "fifth"))
    assert re.search(r"fault: samples bridged: .*(bridged by interpolation|the filter restarted \d+ times)", err), err
    assert faults(msgs) & BRIDGED


def thinned(bench: dict, tmp_path: Path, every: int, name: str, upto: float = 1.0) -> Path:
    """The run's log with the elbow's position frame kept once in `every` (over the first `upto` of the log)."""
    frame = next(f for f in bench["config"].bus.frames if any(s.target == "q.r_elbow" for s in f.signals))
    lines = bench["log"].read_text().splitlines()
    kept, k = [], 0
    for i, line in enumerate(lines):
        if i < upto * len(lines) and line.split()[2].split("#")[0] == f"{frame.id:03X}":
            k += 1
            if k % every:
                continue
        kept.append(line)
    out = tmp_path / f"{name}.log"
    out.write_text("\n".join(kept) + "\n")
    return out


def test_stamps_that_go_back_are_a_fault(bench: dict, tmp_path: Path) -> None:
    """A log whose stamps jump back 50 ms halfway (a sender's clock reset): the filter restarted, with no fault and no
    line (a walkthrough); now a fault that says how far back, cleared after a second in order."""
    lines = bench["log"].read_text().splitlines()
    half = len(lines) // 2
    shifted = [f"({float(l[1:l.index(')')]) - 0.05:.6f}){l[l.index(')') + 1:]}" for l in lines[half:]]
    back = tmp_path / "back.log"
    back.write_text("\n".join(lines[:half] + shifted) + "\n")
    code, err, msgs = replay(bench, "back", log=back)
    assert code == EXIT_FAULTED and re.search(r"fault: stamps went back: a sample stamped 4\d\.\d ms before the one before it", err), err
    assert faults(msgs) & TIME_BACK and not msgs["DYNID_STATUS"][-1].faults & TIME_BACK  # cleared by the end


def test_a_model_that_stops_fitting_mid_run_is_a_long_contact_fault(bench: dict, tmp_path: Path) -> None:
    """The elbow's encoder 0.2 rad off from 4 s (after the start-fit check's block) to 7.5 s: one contact that did not
    end while the offset held, every contact in it unreported, no fault and exit 0 (a review). Now a contact held for
    contact_limit_s is a fault, cleared when the contact ends, and the replay exits 7; the clean run's stay under it."""
    data = bench["data"]
    elbow = data.joints.index("r_elbow")
    q = data.q.copy()
    off = (data.t - data.t[0] >= 4.0) & (data.t - data.t[0] < 7.5)
    q[off, elbow] += 0.2
    log = tmp_path / "offset.log"
    write_candump(replace(data, q=q), bench["config"], log)
    limit = lambda text: text.replace("contact_limit_s 10", "contact_limit_s 2")  # noqa: E731 (the run is 10 s)
    code, err, msgs = replay(bench, "offset", limit, log=log)
    assert re.search(r"fault: contact too long: a contact held for 2\.0 s \(contact_limit_s\): more likely the model "
                     r"no longer fitting", err), err
    assert code == EXIT_FAULTED and faults(msgs) & LONG_CONTACT
    t0 = msgs["DYNID_STATUS"][0].utime
    onset = next(m.utime for m in msgs["DYNID_CONTACT"] if m.kind == 1 and m.utime >= t0 + 4e6)
    end = next(m.utime for m in msgs["DYNID_CONTACT"] if m.kind == 2 and m.utime > onset)
    held = [m.utime for m in msgs["DYNID_STATUS"] if m.faults & LONG_CONTACT]
    assert 1.99e6 <= held[0] - onset <= 2.1e6  # at the limit (the onset its first sample), published at once
    assert end - onset > 3e6 and held[-1] < end and not msgs["DYNID_STATUS"][-1].faults & LONG_CONTACT  # cleared
    # its end clears the fault at its own sample: no event was published while it held, and the exit line says so
    # (it said every event came from suspect data)
    assert not any(m.faults for m in msgs["DYNID_CONTACT"])
    assert f"0 of its {len(msgs['DYNID_CONTACT'])} events came while one held" in err, err
    code, err, msgs = replay(bench, "clean-limited", limit)
    assert code == 0 and not faults(msgs), err


def test_a_configuration_sets_its_contact_limit(tmp_path: Path) -> None:
    """The limit is the robot configuration's `monitor: {contact_limit_s}` (the leg standing on its feet: 30 s), what
    export --monitor-config writes; out of the monitor's range, exit 2 and one line."""
    from dynid.config.robot_config import BUNDLED_DIR
    from dynid.errors import ConfigError

    assert "contact_limit_s 30\n" in monitor_config_text(load_config("icub_right_leg_standing", need_urdf=False))
    assert "contact_limit_s 10\n" in monitor_config_text(load_config("icub_right_arm"))
    mine = tmp_path / "arm.yaml"
    mine.write_text((BUNDLED_DIR / "icub_right_arm.yaml").read_text() + "monitor: {contact_limit_s: 1000000}\n")
    with pytest.raises(ConfigError, match=r"contact_limit_s.* must be 0.1 to 86400 s \(the monitor's range\), got 1e\+06"):
        load_config(str(mine))


def test_a_rate_that_changes_mid_run_is_a_period_fault(bench: dict, tmp_path: Path) -> None:
    """5 s at the file's period, then stamps 0.5 ms apart (a board reconfigured): checked on the first 64 samples only,
    no fault (a review). Now on every second's samples too: raised after the change, named."""
    lines = bench["log"].read_text().splitlines()
    stamp = lambda l: float(l[1:l.index(")")])  # noqa: E731
    t0, half = stamp(lines[0]), stamp(lines[0]) + 5.0
    fast = tmp_path / "fast.log"
    fast.write_text("".join(f"({stamp(l) if stamp(l) < half else half + 0.5 * (stamp(l) - half):.6f}){l[l.index(')') + 1:]}\n"
                            for l in lines))
    code, err, msgs = replay(bench, "fast", log=fast)
    assert "fault: sample period: the samples come 500 µs apart, the coefficient file's period is 1000 µs" in err, err
    assert code == EXIT_FAULTED and faults(msgs) & PERIOD
    first = next(m.utime for m in msgs["DYNID_STATUS"] if m.faults & PERIOD) * 1e-6 - 1_700_000_000.0
    # within two blocks of a second's samples (1000) after the change, 0.5 s each at the new rate
    assert 5.0 <= first - (t0 - 1_700_000_000.0) <= 5.0 + 2 * 0.5


def test_equal_stamps_are_a_time_fault_and_a_status_follows_stamps_that_went_back(bench: dict, tmp_path: Path) -> None:
    """A sample stamped as the one before restarted the filter with no fault (a review); stamps 3 s back halfway held
    the status messages back for 3 s of data (their period counted from the old stamps)."""
    lines = bench["log"].read_text().splitlines()
    frames_per_sample = len(lines) // 10_000
    k = 3000 * frames_per_sample  # a whole sample's frames, stamped as the one before
    same = lines[:k] + [lines[k - frames_per_sample + i][:lines[k - frames_per_sample + i].index(")")] +
                        lines[k + i][lines[k + i].index(")"):] for i in range(frames_per_sample)] + lines[k + frames_per_sample:]
    equal = tmp_path / "equal.log"
    equal.write_text("\n".join(same) + "\n")
    code, err, msgs = replay(bench, "equal", log=equal)
    assert "fault: stamps went back: a sample stamped the same µs as the one before it" in err, err
    assert code == EXIT_FAULTED and faults(msgs) & TIME_BACK
    half = len(lines) // 2
    back = tmp_path / "back3.log"
    back.write_text("\n".join(lines[:half] + [f"({float(l[1:l.index(')')]) - 3.0:.6f}){l[l.index(')') + 1:]}"
                                              for l in lines[half:]]) + "\n")
    code, err, msgs = replay(bench, "back3", log=back)
    assert code == EXIT_FAULTED and faults(msgs) & TIME_BACK, err
    statuses = msgs["DYNID_STATUS"]
    gaps = [b.samples_evaluated - a.samples_evaluated for a, b in zip(statuses, statuses[1:])]
    assert max(gaps) <= 110, gaps  # one status every 100 samples (10 Hz) through the jump, not 3 s without
    assert len(statuses) >= 100
    assert any(m.faults & TIME_BACK for m in statuses)  # published when it rose, not only in faults_seen
