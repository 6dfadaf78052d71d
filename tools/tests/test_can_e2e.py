"""CAN in, LCM out, end to end: simulate → export → candump log → rt_monitor --replay → LCM file:// log → decode.

The monitor's events are checked against an independent path, the core fed the raw floating-point samples
(`rt_eval --stream`), and against the skin's ground truth; the candump writer against the DBC decoder; and each
kind of bad bus input against its counter in the status message.
"""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid, exit_counter
from test_rt_core import detector_columns, python_mirror, raw_samples, stream, without_known_answers

from dynid.config.robot_config import load_config
from dynid.detect.visibility import monitor_visibility
from dynid.export.coefficients import read_coefficients
from dynid.export.monitor_config import monitor_config_text
from dynid.export.monitor_log import read_lcm_log
from dynid.io.can_database import BusCodec
from dynid.io.candump import write_candump
from dynid.io.dataset import contact_episodes
from dynid.io.load import load_data
from dynid.robot.model import RobotModel

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "rt_monitor"
RT_MONITOR = BUILD / "rt_monitor"
T0_US = 1_700_000_000_000_000  # write_candump's default start time
EXIT_FAULTED = 7  # a replay read to its end that raised a watchdog fault


@pytest.fixture(scope="module")
def setup(default_experiments: dict, exported: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    assert RT_MONITOR.is_file(), f"{RT_MONITOR} is not built (scripts/setup)"
    root = tmp_path_factory.mktemp("can_e2e")
    coef = exported
    config = load_config("icub_right_arm")
    data = load_data(default_experiments["contact"], config)
    return {"root": root, "coef": coef, "config": config, "data": data}


def run_monitor(setup: dict, log: Path, name: str) -> tuple[subprocess.CompletedProcess, dict[str, list]]:
    lcm_log = setup["root"] / f"{name}.lcmlog"
    conf = setup["root"] / f"{name}.conf"
    conf.write_text(monitor_config_text(setup["config"], f"file://{lcm_log}?mode=w"))
    done = subprocess.run([str(RT_MONITOR), "--model", str(setup["coef"]), "--config", str(conf), "--replay", str(log)],
                          capture_output=True, text=True, timeout=300)
    return done, (read_lcm_log(lcm_log) if lcm_log.exists() else {})


def test_writer_frames_decode_to_the_data_with_the_dbc(setup: dict, tmp_path: Path) -> None:
    data, config = setup["data"], setup["config"]
    part = data.slice(0, 50)
    log = tmp_path / "x.log"
    write_candump(part, config, log)
    codec = BusCodec(config.bus)
    fs = np.array(config.can["strain"][0]["full_scale"])
    ft = {}
    q = {}
    joint = config.can["motor_control"][0]["axes"][0]["joint"]
    for line in log.read_text().splitlines():
        ts, bus, frame = line.split()
        can_id, payload = frame.split("#")
        f, v = codec.decode(bus, int(can_id, 16), bytes.fromhex(payload))
        k = round((int(ts[1:-1].replace(".", "")) - T0_US + 300) / 1000)
        if f.name == "STRAIN_TORQUE_13":
            ft.setdefault(k, [0.0] * 6)[3:] = [v[c] for c in ("Tx", "Ty", "Tz")]
        elif f.name == "STRAIN_FORCE_13":
            ft.setdefault(k, [0.0] * 6)[:3] = [v[c] for c in ("Fx", "Fy", "Fz")]
        elif f.name == "MC_POSITION_1":
            assert f.signals[0].target == f"q.{joint}"
            q[k] = v["Axis0Position"]
    got = np.array([ft[k] for k in range(50)])
    assert (np.abs(got - part.ft["r_arm_ft"]).max(axis=0) <= fs / 32768 / 2 * 1.0001).all()
    j = part.joints.index(joint)
    step = np.radians(1 / config.can["motor_control"][0]["axes"][0]["ticks_per_degree"])
    assert np.abs(np.array([q[k] for k in range(50)]) - part.q[:50, j]).max() <= step / 2 * 1.0001


def test_replay_end_to_end(setup: dict, default_experiments: dict) -> None:
    data = setup["data"]
    log = setup["root"] / "contact.log"
    n_frames = write_candump(data, setup["config"], log)
    done, msgs = run_monitor(setup, log, "contact")
    assert done.returncode == 0, done.stderr
    print(done.stdout.strip())
    events = [(m.kind, (m.utime - T0_US) // 1000) for m in msgs["DYNID_CONTACT"]]

    # Independent path: the same core on the raw floating-point samples, no CAN in between.
    c = read_coefficients(setup["coef"])
    out = stream(setup["coef"], raw_samples(data, c), setup["root"])
    event = detector_columns(c)["event"]
    ref = [(int(out[k, event]), int(k)) for k in np.flatnonzero(out[:, event])]
    assert events == ref

    # Ground truth: every onset lies in a contact episode, allowing for the filter lag and the debounce.
    eps = contact_episodes(data.contact)
    slack = c.lag + c.debounce_on + 5
    onsets = [k for kind, k in events if kind == 1]
    found = {i for k in onsets for i, (a, e) in enumerate(eps) if a <= k <= e + slack}
    assert all(any(a <= k <= e + slack for a, e in eps) for k in onsets), "an onset in a contact-free stretch"
    # Every episode the monitor can see at all (the contact alone reaches its T²_α for the debounce, from the
    # plant's truth: dynid.detect.visibility) is found; the rest are printed with their peak T².
    vis = monitor_visibility(RobotModel(setup["config"]), c, np.load(Path(default_experiments["contact"]) / "truth.npz"))
    hidden = [f"{v.start / 1000:.1f} s (peak {v.peak_t2:.3g})" for i, v in enumerate(vis) if not v.visible and i not in found]
    print(f"episodes {len(eps)}, found {len(found)}, visible {sum(v.visible for v in vis)}, onsets {len(onsets)}; "
          f"missed, below T²_α: {', '.join(hidden)}")
    assert sum(v.visible for v in vis) >= 15  # measured 18 of the 28: the check below has something to check
    assert all(i in found for i, v in enumerate(vis) if v.visible), "a visible contact missed"
    assert len(found) >= 0.6 * len(eps)

    last = msgs["DYNID_STATUS"][-1]
    assert (last.frames, last.samples, last.samples_evaluated) == (n_frames, data.n_samples, data.n_samples)
    assert last.stale_samples == last.unknown_id == last.bad_length == last.error_frames == last.unpaired_strain == 0
    duration = (data.t[-1] - data.t[0])
    assert abs(len(msgs["DYNID_STATUS"]) - 10 * duration) <= 2  # 10 Hz of CAN time
    assert len(msgs["DYNID_RESIDUAL"]) >= data.n_samples // 10 - 40


# ---- bad bus input: each kind has its counter, no contact comes from stale data, the process never crashes --

START, STOP = 10000, 16000  # 6 s of the contact run around its first detected contact


@pytest.fixture(scope="module")
def clean(setup: dict) -> dict:
    part = setup["data"].slice(START, STOP)
    log = setup["root"] / "clean.log"
    write_candump(part, setup["config"], log)
    done, msgs = run_monitor(setup, log, "clean")
    assert done.returncode == 0, done.stderr
    assert msgs["DYNID_CONTACT"], "the slice must hold a detected contact for the bad-input tests to mean anything"
    return {"lines": log.read_text().splitlines(), "part": part, "msgs": msgs}


def _sample_of(line: str) -> int:
    return round((int(line[1:line.index(")")].replace(".", "")) - T0_US) / 1000)  # frames of sample k: t_k − 300 µs … t_k


def _bad_run(setup: dict, clean: dict, lines: list[str], name: str, faults: int = 0):
    """The monitor on the changed log: never a crash; the watchdog's `faults` (its bits, rt_monitor/README.md) raised,
    and then the replay's exit 7, or none and exit 0."""
    log = setup["root"] / f"{name}.log"
    log.write_text("\n".join(lines) + "\n")
    done, msgs = run_monitor(setup, log, name)
    assert done.returncode == (EXIT_FAULTED if faults else 0), done.stderr
    assert done.stdout.startswith("rt_monitor: end of input;")
    status = msgs["DYNID_STATUS"][-1]
    assert status.faults_seen == faults, done.stderr
    eps = contact_episodes(clean["part"].contact)
    c = read_coefficients(setup["coef"])
    slack = c.lag + c.debounce_on + 5
    for m in msgs["DYNID_CONTACT"]:
        k = (m.utime - T0_US) // 1000
        if m.kind == 1:
            assert any(a <= k <= e + slack for a, e in eps), f"{name}: an onset at sample {k}, outside every contact"
    return status, msgs


def test_postures_beyond_the_fits_are_counted_and_marked(setup: dict, clean: dict, default_model: Path,
                                                         tmp_path: Path) -> None:
    """The coefficient file carries the fit's joint ranges (format version 8), which `dynid validate` and `detect`
    compare a run against; the monitor counts the samples beyond them (status, exit line) and marks each event's joints
    that are. The file's ranges are the fit data's widened by 1°; narrowed here to the middle of the slice's elbow range,
    so that the slice leaves them, the counts and marks equal the decoded samples' own."""
    from dynid.export.coefficients import write_coefficients
    from dynid.identify.model_file import load_model

    c = read_coefficients(setup["coef"])
    record = load_model(default_model).data[0].joint_range_deg
    joints = list(setup["config"].joints)
    assert np.allclose(np.rad2deg(c.fit_range), [[record[j][0] - 1, record[j][1] + 1] for j in joints], atol=1e-9)
    log = setup["root"] / "clean.log"
    q = load_data(log, setup["config"]).q  # what the monitor decodes
    elbow = joints.index("r_elbow")
    # between two decoded values, not on one (the encoder's steps repeat values: no sample sits on a knife edge)
    levels = np.unique(q[:, elbow])
    lo, hi = ((levels[k] + levels[k + 1]) / 2 for k in (len(levels) // 4, 3 * len(levels) // 4))
    c.fit_range[elbow] = [float(lo), float(hi)]
    narrowed = tmp_path / "narrowed.dcoef"
    write_coefficients(c, narrowed)
    conf = setup["root"] / "clean.conf"
    lcm_log = tmp_path / "narrowed.lcmlog"
    conf_text = conf.read_text().replace(str(setup["root"] / "clean.lcmlog"), str(lcm_log))
    (tmp_path / "narrowed.conf").write_text(conf_text)
    done = subprocess.run([str(RT_MONITOR), "--model", str(narrowed), "--config", str(tmp_path / "narrowed.conf"),
                           "--replay", str(log)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lower, upper = np.asarray(c.fit_range).T
    beyond = (q < lower) | (q > upper)  # (samples, joints)
    assert 0.3 * len(q) < beyond.any(axis=1).sum() < 0.7 * len(q)
    msgs = read_lcm_log(lcm_log)
    last = msgs["DYNID_STATUS"][-1]
    assert last.beyond_fit == beyond.any(axis=1).sum() == exit_counter(done.stdout, "beyond the fit's postures")
    assert last.beyond_fit_joints == sum(1 << j for j in np.flatnonzero(beyond[-1]))
    assert msgs["DYNID_CONTACT"]
    for m in msgs["DYNID_CONTACT"]:
        k = round((m.peak_utime - T0_US) / 1000)
        assert list(m.beyond_fit) == beyond[k].astype(int).tolist()
    # dynid spy says so, on the events that are and in its summary
    spied = dynid("spy", "--lcm-url", f"file://{lcm_log}?speed=0")
    assert spied.returncode == 0, spied.stderr
    marked = [line for line in spied.stdout.splitlines() if "BEYOND THE FIT'S POSTURES (r_elbow: α untested" in line]
    assert len(marked) == sum(any(m.beyond_fit) for m in msgs["DYNID_CONTACT"])
    assert f", {last.beyond_fit} beyond the fit's postures (α untested there)" in spied.stdout.splitlines()[-1]
    # The file as exported: the slice within the fit's postures, nothing counted
    assert clean["msgs"]["DYNID_STATUS"][-1].beyond_fit == 0


def test_a_failed_replay_leaves_the_log_it_would_have_replaced(setup: dict, clean: dict) -> None:
    # The clean run's LCM log is there; a replay of another robot's frames (every ID unknown) evaluates no sample.
    lcm_log = setup["root"] / "clean.lcmlog"
    before = lcm_log.read_bytes()
    log = setup["root"] / "foreign.log"
    log.write_text("".join(f"({1700000000 + k * 1e-3:.6f}) can0 7FF#0011223344556677\n" for k in range(2000)))
    conf = setup["root"] / "clean.conf"  # the clean run's configuration: the same file:// log, mode=w
    done = subprocess.run([str(RT_MONITOR), "--model", str(setup["coef"]), "--config", str(conf), "--replay", str(log)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 6, done.stderr
    lines = done.stderr.splitlines()
    assert lines[-2] == (f"rt_monitor: the replay failed: its LCM log is {lcm_log}.failed, {lcm_log} is left as it "
                         "was"), done.stderr
    assert lines[-1].startswith("rt_monitor: error: evaluated no sample"), done.stderr
    assert lcm_log.read_bytes() == before and not Path(f"{lcm_log}.partial").exists()
    assert read_lcm_log(Path(f"{lcm_log}.failed"))["DYNID_STATUS"]  # the failed run's status, for what went wrong


def test_unknown_ids(setup: dict, clean: dict) -> None:
    lines = []
    for i, line in enumerate(clean["lines"]):
        lines.append(line)
        if i % 100 == 0:  # class 5, and a strain type the protocol does not define, and an unconfigured board
            head = line[:line.index(")") + 1]
            lines += [f"{head} can0 514#0102", f"{head} can0 3DC#008000800080", f"{head} can2 171#0000000000000000"]
    status, msgs = _bad_run(setup, clean, lines, "unknown")
    assert status.unknown_id == 3 * len(range(0, len(clean["lines"]), 100))
    assert len(msgs["DYNID_CONTACT"]) == len(clean["msgs"]["DYNID_CONTACT"])


def test_wrong_lengths(setup: dict, clean: dict) -> None:
    lines, n = [], 0
    for i, line in enumerate(clean["lines"]):
        if i % 500 == 7:
            payload = line[line.index("#") + 1:]
            if len(payload) == 16:
                line = line[:-2]  # POSITION with 7 bytes
            else:  # one byte more; a 6-byte strain frame gets two (7 bytes is its saturation form)
                line += "0000" if " 3DA#" in line or " 3DB#" in line else "00"
            n += 1
        lines.append(line)
    status, _ = _bad_run(setup, clean, lines, "lengths")
    assert status.bad_length == n


def test_error_frames(setup: dict, clean: dict) -> None:
    lines = []
    for i, line in enumerate(clean["lines"]):
        lines.append(line)
        if i % 1000 == 0:
            lines.append(line[:line.index(")") + 1] + " can1 20000004#0004000000000000")
    status, msgs = _bad_run(setup, clean, lines, "errors")
    assert status.error_frames == len(range(0, len(clean["lines"]), 1000))
    assert len(msgs["DYNID_CONTACT"]) == len(clean["msgs"]["DYNID_CONTACT"])


def test_one_percent_dropped(setup: dict, clean: dict) -> None:
    rng = np.random.default_rng(1)
    keep = rng.random(len(clean["lines"])) >= 0.01
    lines = [l for l, k in zip(clean["lines"], keep) if k]
    # A frame in a hundred lost, about 7 % of the samples bridged: the bus drops frames, a fault (256, samples bridged)
    status, msgs = _bad_run(setup, clean, lines, "dropped", faults=256)
    halves: dict[int, int] = {}  # sample -> strain halves dropped
    held = set()  # samples with a POSITION frame dropped
    for line, k in zip(clean["lines"], keep):
        if not k and (" 3DA#" in line or " 3DB#" in line):
            halves[_sample_of(line)] = halves.get(_sample_of(line), 0) + 1
        if not k and line[line.index("#") - 1] == "1" and line[line.index("#") - 3] == "1":  # ID 1x1: POSITION
            held.add(_sample_of(line))
    assert status.samples == len(clean["part"].t) - len(halves)
    assert status.unpaired_strain == sum(1 for v in halves.values() if v == 1)
    # Lost samples, and those with a held encoder value, are bridged by interpolation: the filter never restarts.
    assert status.interpolated == len(set(halves) | held) and status.filter_restarts == 1
    assert msgs["DYNID_CONTACT"], "a 1 % loss must not hide the contact"


def test_duplicated_and_reordered(setup: dict, clean: dict) -> None:
    rng = np.random.default_rng(2)
    lines = list(clean["lines"])
    for i in sorted(rng.choice(len(lines) - 1, 60, replace=False)):
        lines[i], lines[i + 1] = lines[i + 1], lines[i]
    out = []
    for i, line in enumerate(lines):
        out.append(line)
        if rng.random() < 0.01:
            out.append(line)
    status, _ = _bad_run(setup, clean, out, "dupes")
    assert status.unpaired_strain > 0
    assert status.samples <= len(clean["part"].t)  # a duplicated half never makes a second sample


def test_stalled_board(setup: dict, clean: dict) -> None:
    # Motor board 2 (can1, address 2) goes silent for 500 samples in the middle of the first contact.
    eps = contact_episodes(clean["part"].contact)
    a = eps[0][0] + 100
    lines = [l for l in clean["lines"] if not (" can1 12" in l and a <= _sample_of(l) < a + 500)]
    status, msgs = _bad_run(setup, clean, lines, "stalled", faults=1)  # blind while every sample is stale
    assert 490 <= status.stale_samples <= 500  # stale once its last values are older than 5 ms
    # The contact open at the stall is cut (the filter restarts after it, and the detector with it): an event of its
    # own, kind 3, at its last evaluated sample; it was left open, no end ever published (a review)
    kinds = [(m.kind, (m.utime - T0_US) // 1000) for m in msgs["DYNID_CONTACT"]]
    cut = [k for kind, k in kinds if kind == 3]
    assert len(cut) == 1 and a - 5 <= cut[0] < a, kinds  # the last sample before the stall
    onset, event = next((m, e) for m, e in zip(msgs["DYNID_CONTACT"], msgs["DYNID_CONTACT"][1:]) if e.kind == 3)
    assert onset.kind == 1 and event.onset_utime == onset.utime <= event.peak_utime <= event.utime  # its contact's peak
    assert event.peak_t2 >= onset.t2 and event.peak_t2 > event.threshold and event.sample > onset.sample
    opened = 0
    for kind, _ in kinds:  # every onset closed by an end or a cut, never two open
        opened += 1 if kind == 1 else -1
        assert opened in (0, 1), kinds
    for m in msgs["DYNID_CONTACT"]:
        k = (m.utime - T0_US) // 1000
        assert not a <= k < a + 500 + 5, "an event from stale data"


def test_saturation_flags(setup: dict, clean: dict) -> None:
    lines, n = [], 0
    for i, line in enumerate(clean["lines"]):
        if " 3DA#" in line and i % 200 < 20:
            line, n = line + "01", n + 1
        lines.append(line)
    status, _ = _bad_run(setup, clean, lines, "saturated", faults=256)  # a tenth of the samples bridged
    assert status.saturated == n
    assert status.stale_samples == n  # a saturated sample is never evaluated


def _stamp(line: str, us: int) -> str:
    return f"({us // 1_000_000}.{us % 1_000_000:06d})" + line[line.index(")") + 1:]


def test_stalled_sender_late_samples(setup: dict, clean: dict) -> None:
    # Every 97th sample the sender wakes 1.8 periods late, then catches up, sending the overdue frames back to back
    # (20 µs apart, stamps never go backwards): samples are late, none is lost.
    lines, last, stamp = [], 0, {}
    for line in clean["lines"]:
        k = _sample_of(line)
        us = int(line[1:line.index(")")].replace(".", "")) + (1800 if k % 97 == 50 else 0)
        last = last + 20 if us < last else us
        lines.append(_stamp(line, last))
        if " 3DB#" in line:  # the torque half completes a sample: its stamp is the sample's
            stamp[k] = last
    log = setup["root"] / "late.log"
    log.write_text("\n".join(lines) + "\n")
    done, msgs = run_monitor(setup, log, "late")
    assert done.returncode == 0, done.stderr
    status = msgs["DYNID_STATUS"][-1]
    # A sample stamped 3/4 of a period or more after its tick reads as past a gap, until the catch-up shows it late.
    late = sum(1 for k, us in stamp.items() if us - (T0_US + 1000 * k) >= 750)
    print(f"{done.stdout.strip()}\nsamples stamped late: {late}")
    assert late >= 2 * len(range(50, len(stamp), 97))
    assert status.late == late == exit_counter(done.stdout, "late")
    # Nothing bridged, nothing restarted: the core saw the clean run's samples, so it raised the same events.
    assert (status.interpolated, status.filter_restarts, status.samples_evaluated) == (0, 1, len(clean["part"].t))
    assert [(m.kind, m.utime) for m in msgs["DYNID_CONTACT"]] == [(m.kind, m.utime) for m in clean["msgs"]["DYNID_CONTACT"]]
    assert clean["msgs"]["DYNID_STATUS"][-1].late == 0  # the clean run's stamps hold no lateness


def test_board_restart(setup: dict, clean: dict) -> None:
    # Board 1 restarts at sample 3000: a STATUS with the restarted flag and the counter from 0 again. That frame comes
    # twice (CAN retransmits a frame whose end was disturbed), the counter's frame of 255 is lost and the 0 after
    # that wrap comes twice too: none of these is a second restart.
    lines, seq = [], -1
    for line in clean["lines"]:
        if " can0 113#" in line and _sample_of(line) >= 3000:
            seq += 1  # wraps 255 -> 0 on its own later: not a restart
            line = line[:line.index("#") + 1] + ("000001" if seq == 0 else "000000") + f"{seq % 256:02X}"
            if seq % 256 == 255:
                continue
            if seq % 256 == 0:
                lines.append(line)
        lines.append(line)
    assert seq > 256
    status, _ = _bad_run(setup, clean, lines, "restart")
    assert status.board_restarts == 1
    assert status.stale_samples <= 1


# ---- the supply ratios in the status ---------------------------------------------------------------------


def test_status_supply_ratios_are_the_python_trackers(setup: dict, clean: dict, default_model: Path) -> None:
    """The last status's supply ratios: dynid.identify.supply.SupplyTracker's after the same samples, through dynid's own
    mirror of the online filter and residuals (independent of the C++ core), in the file's input-channel order."""
    from dynid.detect.online import raw_signals
    from dynid.export.coefficients import unwrap, wrap
    from dynid.export.lcm_coefficients import coefficients_t
    from dynid.identify.model_file import load_model

    identified = load_model(default_model)
    c = read_coefficients(setup["coef"])
    t, q, inputs, _, ft = raw_signals(identified.robot_model, clean["part"])
    _, tracker, _, _ = python_mirror(identified, c, t, q, inputs, ft)
    inputs_rows = [i for i, k in enumerate(c.channel_kind) if k == 1]
    want = np.array([tracker.states[i].ratio for i in inputs_rows])
    last = clean["msgs"]["DYNID_STATUS"][-1]
    assert last.n_supply == len(inputs_rows) == 4
    got = np.array(last.supply_ratio)
    print(f"supply ratios after the 6 s slice: {got}; Python tracker {want}; |Δ| max {np.abs(got - want).max():.2e}")
    assert np.abs(got - want).max() <= 1e-9
    assert np.abs(want - 1).max() > 1e-3  # the tracker moved: the check has teeth
    # Every status carries them; the first, before the filter window fills, has the prior r = 1.
    assert list(clean["msgs"]["DYNID_STATUS"][0].supply_ratio) == [1.0] * 4

    # Tracking off in the coefficient file (τ = 0): an edit of a fitted file, which its known answers refuse; marked as
    # uncalibrated (no answers), it runs with constant gains, every ratio exactly 1.
    off = coefficients_t.decode(unwrap(Path(setup["coef"]).read_bytes()))
    off.supply_time_constant = 0.0
    coef_off = setup["root"] / "supply_off.dcoef"
    coef_off.write_bytes(wrap(off.encode()))
    done, msgs = run_monitor({**setup, "coef": coef_off}, setup["root"] / "clean.log", "supply_off")
    assert done.returncode == 22 and "known answers" in done.stderr, done.stderr
    coef_off.write_bytes(wrap(without_known_answers(off).encode()))
    done, msgs = run_monitor({**setup, "coef": coef_off}, setup["root"] / "clean.log", "supply_off")
    assert done.returncode == 0, done.stderr
    assert msgs["DYNID_STATUS"] and all(list(m.supply_ratio) == [1.0] * 4 for m in msgs["DYNID_STATUS"])


# ---- dynid import of candump logs -----------------------------------------------------------------------


def test_import_candump_round_trip(setup: dict, clean: dict, tmp_path: Path) -> None:
    """The writer's log imports back to the data (the simulation is quantised as the boards are: exact)."""
    from dynid.io.dataset import Dataset

    log = setup["root"] / "clean.log"
    done = dynid("import", "--data", str(log), "--out", str(tmp_path / "d.npz"))
    assert done.returncode == 0, done.stderr
    got, want = Dataset.load(tmp_path / "d.npz"), clean["part"]
    assert got.n_samples == want.n_samples
    assert np.allclose(got.t, want.t - want.t[0], atol=1e-9)
    fs = np.array(setup["config"].can["strain"][0]["full_scale"])
    assert (np.abs(got.ft["r_arm_ft"] - want.ft["r_arm_ft"]).max(axis=0) <= fs / 65536 * 1.0001).all()
    step = np.radians(1 / 182.04444444444445)
    assert np.abs(got.q - want.q).max() <= step / 2 * 1.0001
    assert all(np.abs(got.pwm[m] - want.pwm[m]).max() <= 0.5 / 1333 + 1e-12 for m in want.pwm)
    assert (got.contact == want.contact).all()


def test_import_refuses_a_bad_log_with_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.log"
    bad.write_text("(1.000000) can0 514#00\n(1.001000) can0 515#00\n")
    done = dynid("import", "--data", str(bad), "--out", str(tmp_path / "d.npz"))
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "no frame STRAIN_TORQUE_13" in done.stderr, done.stderr
    assert not (tmp_path / "d.npz").exists()


def test_loopback_live_and_clean_shutdown(setup: dict, clean: dict, tmp_path: Path) -> None:
    """Frames over the loopback transport (struct can_frame datagrams), then SIGTERM: exit 0, final counters."""
    import signal
    import socket
    import time

    conf = tmp_path / "live.conf"
    conf.write_text(monitor_config_text(setup["config"], f"file://{tmp_path / 'live.lcmlog'}?mode=w"))
    proc = subprocess.Popen([str(RT_MONITOR), "--model", str(setup["coef"]), "--config", str(conf), "--loopback",
                             str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        buses = setup["config"].can["buses"]
        for _ in range(100):  # the monitor binds its sockets at start-up
            if all((tmp_path / f"{b}.can").exists() for b in buses):
                break
            time.sleep(0.05)
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        n = 0
        for line in clean["lines"][:14 * 200]:  # 200 samples
            _, bus, frame = line.split()
            can_id, payload = frame.split("#")
            data = bytes.fromhex(payload)
            sock.sendto(struct.pack("<IB3x8s", int(can_id, 16), len(data), data), str(tmp_path / f"{bus}.can"))
            n += 1
            if n % 500 == 0:
                time.sleep(0.01)  # let the monitor drain its queue
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert out.startswith("rt_monitor: stopped by signal; frames ")
    frames = int(out.split("frames ")[1].split(",")[0])
    assert frames == n
    assert not any((tmp_path / f"{b}.can").exists() for b in buses)  # sockets removed on exit
