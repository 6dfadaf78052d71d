"""The `boards` player (firmware_like/) against the Python side.

- Cross-language: the frames `boards` writes for a slice of the default contact run, with the iCub board emulators
  and with the generic encoder from the bus table, are the frames dynid.io.candump writes (through cantools) for the
  same data, byte for byte (integer and IEEE arithmetic on the same inputs: exact), and they decode with the bus's
  cantools database to the CSV's values within each signal's quantisation.
- The bus load it prints is the one recomputed here from the log (worst-case bit stuffing) and is < 70 %.
- Saturation (7-byte strain frames), a board restart, and bad input (one line, a distinct exit code each).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.export.monitor_config import monitor_config_text
from dynid.io.can_database import BusCodec
from dynid.io.candump import write_candump
from dynid.io.load import load_data

ROOT = Path(__file__).resolve().parents[2]
BOARDS = ROOT / "build" / "firmware_like" / "boards"
T0_US = 1_700_000_000_000_000
N = 3000  # 3 s of the contact run: several skin and strain changes, under a second of test time


def boards(*args: str) -> subprocess.CompletedProcess:
    assert BOARDS.is_file(), f"{BOARDS} is not built (scripts/setup)"
    return subprocess.run([str(BOARDS), *args], capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def part(default_experiments: dict, tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("boards")
    lines = (default_experiments["contact"] / "data.csv").read_text().splitlines()
    header = lines[0].split(",")
    contact = np.array([float(l.split(",")[header.index("contact")]) for l in lines[1:]])
    # A stretch that starts before a contact episode and holds its onset.
    first = int(np.flatnonzero(contact)[0])
    rows = lines[1 + max(0, first - N // 2): 1 + max(0, first - N // 2) + N]
    csv = root / "data.csv"
    csv.write_text("\n".join([lines[0]] + rows) + "\n")
    config = load_config("icub_right_arm")
    conf = root / "monitor.conf"
    conf.write_text(monitor_config_text(config))
    return {"root": root, "csv": csv, "conf": conf, "config": config, "header": lines[0]}


def _frames(log: Path) -> list[tuple[int, str, int, bytes]]:
    out = []
    for line in log.read_text().splitlines():
        ts, bus, frame = line.split()
        can_id, payload = frame.split("#")
        out.append((int(ts[1:-1].replace(".", "")), bus, int(can_id, 16), bytes.fromhex(payload)))
    return out


def test_candump_to_standard_output_is_the_log_file(part: dict) -> None:
    """--sink candump:- streams the same log to stdout (a pipe into the soak's fault injector) and the summary to stderr."""
    log = part["root"] / "file.log"
    assert boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{log}").returncode == 0
    done = boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", "candump:-", "--repeat", "2")
    assert done.returncode == 0, done.stderr
    lines, once = done.stdout.splitlines(), log.read_text().splitlines()
    assert lines[:len(once)] == once and len(lines) == 2 * len(once)
    assert f"{2 * N} samples, {2 * len(once)} frames" in done.stderr and "bus can0 load" in done.stderr


@pytest.mark.parametrize("encoder", ["icub", "generic"])
def test_frames_match_the_python_writer_and_decode_to_the_csv(part: dict, encoder: str) -> None:
    log = part["root"] / f"c_{encoder}.log"
    done = boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{log}",
                  "--encoder", encoder)
    assert done.returncode == 0, done.stderr
    data = load_data(part["csv"], part["config"])
    py_log = part["root"] / "py.log"
    n = write_candump(data, part["config"], py_log)
    assert log.read_text() == py_log.read_text()  # same frames, same order, same times
    assert f"{N} samples, {n} frames" in done.stdout

    # Independently of both writers: cantools decodes every frame to the CSV's values within quantisation.
    codec, can = BusCodec(part["config"].bus), part["config"].can
    fs = np.asarray(can["strain"][0]["full_scale"], float)
    ft = np.full((N, 6), np.nan)
    q = {ax["joint"]: np.full(N, np.nan) for b in can["motor_control"] for ax in b["axes"]}
    pwm = {ax["motor"]: np.full(N, np.nan) for b in can["motor_control"] for ax in b["axes"] if ax.get("motor")}
    skin = np.zeros(N, int)
    channels = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
    for t, bus, can_id, payload in _frames(log):
        frame, values = codec.decode(bus, can_id, payload)
        k = (t - T0_US + 300) // 1000  # every frame of sample k lies in (t_k − 1 ms, t_k]
        for s in frame.signals:
            family, _, name = s.target.partition(".")
            if family == "ft":
                ft[k, channels.index(s.name)] = values[s.name]
            elif family == "q":
                q[name][k] = values[s.name]
            elif family == "pwm":
                pwm[name][k] = values[s.name]
            elif family == "skin" and values[s.name]:
                skin[k] = 1
    assert (np.abs(ft - data.ft["r_arm_ft"]).max(axis=0) <= fs / 65536 * 1.0001).all()  # every channel, not a list order
    for j, v in q.items():
        tick = np.radians(1 / 182.04444444444445)
        assert np.abs(v - data.q[:, data.joints.index(j)]).max() <= tick / 2 * 1.0001, j
    for m, v in pwm.items():
        assert np.abs(v - data.pwm[m]).max() <= 0.5 / 1333 + 1e-12, m
    assert (skin == (data.contact != 0)).all() and skin.any() and not skin.all()


@pytest.mark.parametrize("encoder", ["icub", "generic"])
def test_a_run_without_contact_labels_sends_no_skin_frames(part: dict, encoder: str) -> None:
    """A run with no contact column knows nothing of contact: both players send none of the skin boards' frames
    (all-zero taxels would read back as a run known to be contact-free), the same frames otherwise, and the log reads
    back with no contact column."""
    header = part["header"].split(",")
    keep = [i for i, name in enumerate(header) if name not in ("contact", "skin.patch", "skin.side")]
    lines = part["csv"].read_text().splitlines()
    unlabelled = part["root"] / f"unlabelled_{encoder}.csv"
    unlabelled.write_text("\n".join(",".join(line.split(",")[i] for i in keep) for line in lines) + "\n")
    log = part["root"] / f"unlabelled_{encoder}.log"
    done = boards("--config", str(part["conf"]), "--data", str(unlabelled), "--sink", f"candump:{log}",
                  "--encoder", encoder)
    assert done.returncode == 0, done.stderr
    data = load_data(unlabelled, part["config"])
    assert data.contact is None
    py_log = part["root"] / f"unlabelled_py_{encoder}.log"
    write_candump(data, part["config"], py_log)
    assert log.read_text() == py_log.read_text()
    with_labels = part["root"] / f"labelled_{encoder}.log"
    assert boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{with_labels}",
                  "--encoder", encoder).returncode == 0
    skin_ids = {f.id for f in part["config"].bus.frames if any(s.target.startswith("skin.") for s in f.signals)}
    sent, labelled = ({can_id for _, _, can_id, _ in _frames(p)} for p in (log, with_labels))
    assert skin_ids and not sent & skin_ids and sent == labelled - skin_ids
    back = load_data(log, part["config"])
    assert back.contact is None and back.n_samples == N


def _bits(dlc: int) -> int:
    return 34 + 8 * dlc + 13 + (34 + 8 * dlc - 1) // 4  # standard ID, worst-case stuffing, with the IFS


def test_bus_load_is_printed_and_under_70_percent(part: dict) -> None:
    log = part["root"] / "load.log"
    done = boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{log}")
    assert done.returncode == 0, done.stderr
    printed = {m[0]: float(m[1]) for m in re.findall(r"bus (\S+) load ([\d.]+) %", done.stdout)}
    bits: dict[str, int] = {}
    for _, bus, _, payload in _frames(log):
        bits[bus] = bits.get(bus, 0) + _bits(len(payload))
    duration = N * 1e-3
    want = {b: 100 * v / (duration * 1e6) for b, v in bits.items()}
    assert printed.keys() == want.keys() == set(part["config"].bus.buses)
    for b in want:
        assert abs(printed[b] - want[b]) < 0.06, (b, printed[b], want[b])
        assert printed[b] < 70


def test_saturation_variant_flags_the_clamped_channel(part: dict) -> None:
    lines = part["csv"].read_text().splitlines()
    cols = lines[0].split(",")
    i = cols.index("ft.r_arm_ft.fy")
    rows = [l.split(",") for l in lines[1:101]]
    rows[50][i] = "250.0"  # beyond the 200 N full scale
    csv = part["root"] / "sat.csv"
    csv.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    log = part["root"] / "sat.log"
    assert boards("--config", str(part["conf"]), "--data", str(csv), "--sink", f"candump:{log}").returncode == 0
    strain = [(t, p) for t, _, can_id, p in _frames(log) if can_id == 0x3DA]
    assert {len(p) for _, p in strain} == {7}  # the whole run in the 7-byte form once a channel clamps
    flagged = [(t - T0_US + 300) // 1000 for t, p in strain if p[6]]
    assert flagged == [50] and strain[50][1][6] == 0b010 and strain[50][1][2:4] == b"\xff\xff"
    py_log = part["root"] / "sat_py.log"
    write_candump(load_data(csv, part["config"]), part["config"], py_log)
    assert log.read_text() == py_log.read_text()
    generic = part["root"] / "sat_generic.log"  # the generic encoder: the frame's long form, its flags from the table
    assert boards("--config", str(part["conf"]), "--data", str(csv), "--sink", f"candump:{generic}", "--encoder",
                  "generic").returncode == 0
    assert generic.read_text() == log.read_text()


@pytest.mark.parametrize("encoder", ["icub", "generic"])
def test_board_restart_sends_the_flag_and_restarts_the_sequence(part: dict, encoder: str) -> None:
    log = part["root"] / f"restart_{encoder}.log"
    done = boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{log}",
                  "--restart", "2@1005", "--encoder", encoder)
    assert done.returncode == 0, done.stderr
    codec = BusCodec(part["config"].bus)
    status = [((t - T0_US + 250) // 1000, codec.decode(b, i, p)[1]) for t, b, i, p in _frames(log) if i == 0x123]
    seqs = [(k, s["Sequence"], s["BoardRestarted"]) for k, s in status]
    assert seqs[:3] == [(0, 0, 0), (10, 1, 0), (20, 2, 0)]
    after = [x for x in seqs if x[0] >= 1005]
    assert after[:3] == [(1005, 0, 1), (1015, 1, 0), (1025, 2, 0)]
    if encoder == "generic":  # the same bytes as the emulators
        assert log.read_text() == (part["root"] / "restart_icub.log").read_text()
    # A node by its name does the same.
    named = part["root"] / f"restart_named_{encoder}.log"
    assert boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{named}",
                  "--restart", "icub_mc_can1_2@1005", "--encoder", encoder).returncode == 0
    assert named.read_text() == log.read_text()


@pytest.mark.parametrize("case, code, words", [
    ("flag", 2, "unknown argument"),
    ("missing", 3, "No such file"),
    ("badcsv", 4, "not a finite number"),
    ("nocolumn", 4, "no column 'q.r_elbow'"),
    ("time", 4, "not strictly increasing"),
    # A time far after the first (issue 22): its µs stamp overflowed int64 (undefined behaviour) before.
    ("span", 4, "s after the first row, more than the 1e+07 s a run may span"),
    ("socketcan", 5, "socketcan"),
    ("encoder", 2, "--encoder auto|generic|icub"),
    ("restart", 2, "--restart nope@3: no node nope in"),
    ("old_conf", 4, "'strain' is a line of the iCub-only format before the bus description"),
])
def test_bad_input_one_line_and_a_distinct_exit_code(part: dict, case: str, code: int, words: str) -> None:
    root, head = part["root"], part["header"]
    row = part["csv"].read_text().splitlines()[1]
    args = ["--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{root / 'bad.log'}"]
    if case == "flag":
        args.append("--fast")
    elif case == "encoder":
        args += ["--encoder", "canopen"]
    elif case == "restart":
        args += ["--restart", "nope@3"]
    elif case == "old_conf":
        old = root / "old.conf"
        old.write_text(part["conf"].read_text() + "strain can0 13 200 200 200 10 10 10\n")
        args[1] = str(old)
    elif case == "missing":
        args[3] = str(root / "nothere.csv")
    elif case in ("badcsv", "nocolumn", "time", "span"):
        bad = root / f"{case}.csv"
        if case == "badcsv":
            text = f"{head}\n{row}\n{row.replace(',', ',x', 1)}\n"
        elif case == "nocolumn":
            text = head.replace("q.r_elbow", "q.r_elbo") + f"\n{row}\n"
        elif case == "span":
            fields = row.split(",")
            fields[head.split(",").index("t")] = "1e300"
            text = f"{head}\n{row}\n{','.join(fields)}\n"
        else:
            text = f"{head}\n{row}\n{row}\n"
        bad.write_text(text)
        args[3] = str(bad)
    else:
        args[5] = "socketcan"
    done = boards(*args)
    assert done.returncode == code, done.stderr
    first = done.stderr.splitlines()[0]
    assert first.startswith("boards: error:") and words in first, done.stderr
    assert len(done.stderr.splitlines()) <= 2  # the error, and the usage line for a bad flag
    assert not (root / "bad.log").exists()


def test_an_overloaded_bus_is_refused_after_printing_the_loads(part: dict) -> None:
    # Every board on can0: 46.9 + 47.9 + 61.5 % of one bus.
    text = part["conf"].read_text().splitlines()
    one_bus = "\n".join(l if l.startswith(("buses", "#", "robot")) else l.replace(" can1 ", " can0 ").replace(" can2 ", " can0 ")
                        for l in text) + "\n"
    conf = part["root"] / "one_bus.conf"
    conf.write_text(one_bus)
    done = boards("--config", str(conf), "--data", str(part["csv"]), "--sink", f"candump:{part['root'] / 'one.log'}")
    assert done.returncode == 6, done.stderr
    load = float(re.search(r"bus can0 load ([\d.]+) %", done.stdout).group(1))
    assert abs(load - (46.9 + 47.9 + 61.5)) < 0.3
    assert done.stderr.strip() == (f"boards: error: bus can0 is loaded at {load:.0f} % (70 % or more at 1 Mbit/s): move "
                                   "frames to another bus, or raise its bitrate")
