"""The C board emulators (firmware_like/, the `boards` program) against the Python side.

- Cross-language: the frames `boards` writes for a slice of the default contact run are the frames
  dynid.io.candump writes for the same data, byte for byte, and they decode with the DBC (cantools) to the CSV's
  values within the protocol's quantisation.
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
from dynid.io.can_protocol import Protocol
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


def test_frames_match_the_python_writer_and_decode_to_the_csv(part: dict) -> None:
    log = part["root"] / "c.log"
    done = boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{log}")
    assert done.returncode == 0, done.stderr
    data = load_data(part["csv"], part["config"])
    py_log = part["root"] / "py.log"
    n = write_candump(data, part["config"], py_log)
    assert log.read_text() == py_log.read_text()  # same frames, same order, same times
    assert f"{N} samples, {n} frames" in done.stdout

    # Independently of both writers: the DBC decodes every frame to the CSV's values within quantisation.
    proto, can = Protocol(), part["config"].can
    fs = np.asarray(can["strain"][0]["full_scale"], float)
    ft = np.full((N, 6), np.nan)
    q = {ax["joint"]: np.full(N, np.nan) for b in can["motor_control"] for ax in b["axes"]}
    pwm = {ax["motor"]: np.full(N, np.nan) for b in can["motor_control"] for ax in b["axes"] if ax.get("motor")}
    skin = np.zeros(N, int)
    boards_by_addr = {b["address"]: b for b in can["motor_control"]}
    for t, _, can_id, payload in _frames(log):
        f = proto.decode(can_id, payload)
        k = (t - T0_US + 300) // 1000  # every frame of sample k lies in (t_k − 1 ms, t_k]
        if f.name == "STRAIN_FORCE":
            ft[k, :3] = [f.signals[c] for c in ("Fx", "Fy", "Fz")]
        elif f.name == "STRAIN_TORQUE":
            ft[k, 3:] = [f.signals[c] for c in ("Tx", "Ty", "Tz")]
        elif f.name in ("MC_POSITION", "MC_PID_VAL"):
            b = boards_by_addr[f.address]
            for slot, ax in enumerate(b["axes"]):
                if f.name == "MC_POSITION":
                    deg = f.signals[f"Axis{slot}Position"] / ax["ticks_per_degree"] - ax.get("zero_deg", 0.0)
                    q[ax["joint"]][k] = np.radians(deg)
                elif ax.get("motor"):
                    pwm[ax["motor"]][k] = f.signals[f"Axis{slot}Pwm"] / b["pwm_full_scale"]
        elif f.name == "SKIN_TAXELS" and f.signals["Taxels"]:
            skin[k] = 1
    ft = ft * fs / 32768
    assert (np.abs(ft - data.ft["r_arm_ft"]).max(axis=0) <= fs / 65536 * 1.0001).all()  # every channel, not a list order
    for j, v in q.items():
        tick = np.radians(1 / 182.04444444444445)
        assert np.abs(v - data.q[:, data.joints.index(j)]).max() <= tick / 2 * 1.0001, j
    for m, v in pwm.items():
        assert np.abs(v - data.pwm[m]).max() <= 0.5 / 1333 + 1e-12, m
    assert (skin == (data.contact != 0)).all() and skin.any() and not skin.all()


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
    assert printed.keys() == want.keys() == set(part["config"].can["buses"])
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


def test_board_restart_sends_the_flag_and_restarts_the_sequence(part: dict) -> None:
    log = part["root"] / "restart.log"
    done = boards("--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{log}",
                  "--restart", "2@1005")
    assert done.returncode == 0, done.stderr
    proto = Protocol()
    status = [((t - T0_US + 250) // 1000, proto.decode(i, p).signals) for t, _, i, p in _frames(log) if i == 0x123]
    seqs = [(k, s["Sequence"], s["BoardRestarted"]) for k, s in status]
    assert seqs[:3] == [(0, 0, 0), (10, 1, 0), (20, 2, 0)]
    after = [x for x in seqs if x[0] >= 1005]
    assert after[:3] == [(1005, 0, 1), (1015, 1, 0), (1025, 2, 0)]


@pytest.mark.parametrize("case, code, words", [
    ("flag", 2, "unknown argument"),
    ("missing", 3, "No such file"),
    ("badcsv", 4, "not a finite number"),
    ("nocolumn", 4, "no column 'q.r_elbow'"),
    ("time", 4, "not strictly increasing"),
    # A time far after the first (issue 22): its µs stamp overflowed int64 (undefined behaviour) before.
    ("span", 4, "s after the first row, more than the 1e+07 s a run may span"),
    ("socketcan", 5, "socketcan"),
])
def test_bad_input_one_line_and_a_distinct_exit_code(part: dict, case: str, code: int, words: str) -> None:
    root, head = part["root"], part["header"]
    row = part["csv"].read_text().splitlines()[1]
    args = ["--config", str(part["conf"]), "--data", str(part["csv"]), "--sink", f"candump:{root / 'bad.log'}"]
    if case == "flag":
        args.append("--fast")
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
    assert done.stderr.strip() == "boards: error: a bus is loaded at 70 % or more: move boards to another bus"
