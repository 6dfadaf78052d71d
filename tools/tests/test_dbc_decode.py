"""The DBC decodes the bus the boards drive: `python -m cantools decode firmware_like/icub_can.dbc < LOG`.

A simulated contact run goes through the C board emulators (`boards`, the bundled arm's configuration: boards
at addresses 1-4, 8-13 on three buses) into a candump log; cantools' own command decodes every frame of it, and
the values it prints are the bytes' by hand and the run's data within the protocol's quantisation (full scales,
ticks per degree and PWM scales from the configuration). The strain board's 7-byte saturation variant decodes
with `--no-strict` and its flags byte is where the DBC's attributes say. firmware_like/icub_can.dbc is what
firmware_like/tools/icub_can_dbc.py writes for that configuration, whatever the order of its keys.

Command lines only (dynid, boards, cantools' CLI); cantools is imported only to read the DBC's attributes.
"""

from __future__ import annotations

import logging
import re
import math
import struct
import subprocess
import sys
from pathlib import Path

import cantools
import pytest

ROOT = Path(__file__).resolve().parents[2]
BOARDS = ROOT / "build" / "firmware_like" / "boards"
DYNID = Path(sys.executable).with_name("dynid")
DBC = ROOT / "firmware_like" / "icub_can.dbc"
GENERATOR = ROOT / "firmware_like" / "tools" / "icub_can_dbc.py"
CONF = ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"
T0_US = 1_700_000_000_000_000  # boards' default --t0
FIRST, LAST = 4500, 7600  # rows of the 8 s default contact run: its first contact (5.078-7.403 s) and around
NAMES = {"STRAIN_FORCE", "STRAIN_TORQUE", "MC_POSITION", "MC_PID_VAL", "MC_STATUS", "SKIN_TAXELS"}


def run(*args: object, stdin: Path | None = None) -> subprocess.CompletedProcess:
    with open(stdin or "/dev/null", "rb") as f:
        done = subprocess.run([str(a) for a in args], stdin=f, capture_output=True, timeout=300)
    return subprocess.CompletedProcess(done.args, done.returncode, done.stdout.decode(), done.stderr.decode())


def cantools_decode(log: Path, *opts: str, dbc: Path = DBC) -> subprocess.CompletedProcess:
    return run(sys.executable, "-m", "cantools", "decode", *opts, dbc, stdin=log)


def configuration() -> dict:
    """The board map of the bundled arm's monitor configuration, read as text."""
    c: dict = {"axis": {}, "pwm": {}, "skin": []}
    for line in CONF.read_text().splitlines():
        t = line.split("#")[0].split()
        if t and t[0] == "strain":
            c["strain"] = (int(t[2]), [float(x) for x in t[3:9]])
        elif t and t[0] == "axis":
            c["axis"][(int(t[2]), int(t[3]))] = (t[4], float(t[5]), float(t[6]))
        elif t and t[0] == "pwm":
            c["pwm"][(int(t[2]), int(t[3]))] = (t[4], float(t[5]))
        elif t and t[0] == "skin":
            c["skin"].append(int(t[2]))  # the n-th skin line is patch n (skin.patch in the data)
    return c


def parse_decoded(text: str) -> list[dict]:
    """cantools decode's multi-line output: per candump line its ID, payload, error or message and signals."""
    out: list[dict] = []
    for line in text.splitlines():
        if line.startswith("("):
            head, _, rest = line.partition(" ::")
            can_id, payload = head.split()[2].split("#")
            out.append({"id": int(can_id, 16), "data": bytes.fromhex(payload), "error": rest.strip(), "name": None,
                        "signals": {}, "k": (int(head[1:].split(")")[0].replace(".", "")) - T0_US + 300) // 1000})
        elif line.endswith("("):
            out[-1]["name"] = line[:-1]
            out[-1]["base"] = re.sub(r"_\d+$", "", line[:-1])  # MC_POSITION_2 -> MC_POSITION
        elif line != ")":
            name, value = line.strip().rstrip(",").split(": ")
            out[-1]["signals"][name] = int(value.split()[0])
    return out


@pytest.fixture(scope="module")
def bus(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("dbc")
    # 8 s: the 4 s run has no contact, so its skin frames would all be zero.
    done = run(DYNID, "simulate", "--kind", "contact", "--duration", "8", "--out", root / "run")
    assert done.returncode == 0, done.stderr
    lines = (root / "run" / "data.csv").read_text().splitlines()
    csv = root / "data.csv"
    csv.write_text("\n".join([lines[0]] + lines[1 + FIRST:1 + LAST]) + "\n")
    header = lines[0].split(",")
    rows = [dict(zip(header, map(float, l.split(",")))) for l in lines[1 + FIRST:1 + LAST]]
    log = root / "bus.log"
    done = run(BOARDS, "--config", CONF, "--data", csv, "--sink", f"candump:{log}")
    assert done.returncode == 0, done.stderr
    decoded = cantools_decode(log)
    assert decoded.returncode == 0, decoded.stderr
    return {"root": root, "csv": csv, "rows": rows, "log": log, "decoded": decoded}


def test_every_frame_the_boards_send_decodes(bus: dict) -> None:
    out = bus["decoded"].stdout
    assert "Unknown frame id" not in out and "Wrong data size" not in out
    frames = parse_decoded(out)
    log_lines = bus["log"].read_text().splitlines()
    assert len(frames) == len(log_lines) == (LAST - FIRST) * (2 + 4 * 2 + 5) + 4 * (LAST - FIRST) // 10
    assert [f for f in frames if f["error"] or not f["name"]] == []
    c = configuration()
    boards = [(3, c["strain"][0], (0xA, 0xB))] + [(1, a, (1, 2, 3)) for a in {a for a, _ in c["axis"]}] + \
        [(4, a, (0,)) for a in c["skin"]]
    want = {cls << 8 | a << 4 | typ for cls, a, types in boards for typ in types}
    assert {f["id"] for f in frames} == want  # motor boards 2-4 (0x121-0x143) and skin 9-12 (0x490-0x4C0) too
    assert {0x121, 0x143, 0x490, 0x4C0} <= want
    assert {f["base"] for f in frames} == NAMES
    assert {len(f["data"]) for f in frames if f["id"] >> 8 == 3} == {6}  # the nominal strain frames


def test_decoded_values_are_the_bytes_and_the_data(bus: dict) -> None:
    c = configuration()
    fs = c["strain"][1]
    rows, seen, seq = bus["rows"], {n: 0 for n in NAMES}, {}
    on = [0] * len(c["skin"])
    for f in parse_decoded(bus["decoded"].stdout):
        cls, address, typ = f["id"] >> 8, (f["id"] >> 4) & 0xF, f["id"] & 0xF
        row, sig, data = rows[f["k"]], f["signals"], f["data"]
        seen[f["base"]] += 1
        if cls == 3:  # offset binary: count = raw - 0x8000, value = count * FS / 32768
            half = typ - 0xA
            names = ("Fx", "Fy", "Fz") if half == 0 else ("Tx", "Ty", "Tz")
            counts = [raw - 0x8000 for raw in struct.unpack("<3H", data)]
            assert [sig[n] for n in names] == counts
            for i, n in enumerate(names):
                column = "ft.r_arm_ft." + n.lower()
                assert abs(counts[i] * fs[3 * half + i] / 32768 - row[column]) <= fs[3 * half + i] / 65536 * 1.0001
        elif cls == 1 and typ == 1:
            ticks = struct.unpack("<2i", data)
            for slot in (0, 1):
                assert sig[f"Axis{slot}Position"] == ticks[slot]
                if (address, slot) in c["axis"]:
                    joint, tpd, zero = c["axis"][(address, slot)]
                    deg = ticks[slot] / tpd - zero
                    assert abs(deg - math.degrees(row[f"q.{joint}"])) <= 0.5 / tpd * 1.0001, joint
        elif cls == 1 and typ == 2:
            counts = struct.unpack("<2h", data)
            for slot in (0, 1):
                assert sig[f"Axis{slot}Pwm"] == counts[slot]
                if (address, slot) in c["pwm"]:
                    motor, full = c["pwm"][(address, slot)]
                    assert abs(counts[slot] / full - row[f"pwm.{motor}"]) <= 0.5 / full + 1e-12, motor
        elif cls == 1:
            assert sig["Sequence"] == data[3] == (seq.get(address, data[3] - 1) + 1) % 256
            seq[address] = data[3]
            assert sum(v for k, v in sig.items() if k != "Sequence") == 0  # no fault in this run
        else:
            patch = c["skin"].index(address) + 1
            assert sig["Taxels"] == struct.unpack("<H", data)[0]
            assert (sig["Taxels"] != 0) == (row["contact"] != 0 and row["skin.patch"] == patch)
            on[patch - 1] += sig["Taxels"] != 0
    assert min(seen.values()) > 0
    assert sum(on) > 1000 and on.count(0) == len(on) - 1  # one patch touched, for over a second


def test_the_seven_byte_saturation_variant(bus: dict, tmp_path: Path) -> None:
    lines = bus["csv"].read_text().splitlines()
    i = lines[0].split(",").index("ft.r_arm_ft.fy")
    rows = [l.split(",") for l in lines[1:101]]
    rows[50][i] = "250.0"  # beyond the 200 N full scale: clamped, flagged
    csv = tmp_path / "sat.csv"
    csv.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    log = tmp_path / "sat.log"
    assert run(BOARDS, "--config", CONF, "--data", csv, "--sink", f"candump:{log}").returncode == 0
    # cantools decode checks lengths exactly: the 6-byte strain message does not take 7 bytes ...
    strict = parse_decoded(cantools_decode(log).stdout)
    assert {f["error"] for f in strict if f["id"] >> 8 == 3} == {"Wrong data size: 7 instead of 6 bytes"}
    assert all(f["name"] for f in strict if f["id"] >> 8 != 3)
    # ... --no-strict does: every frame, the counts of the first 6 bytes.
    frames = parse_decoded(cantools_decode(log, "--no-strict").stdout)
    assert len(frames) == len(strict) and [f for f in frames if f["error"] or not f["name"]] == []
    strain = [f for f in frames if f["id"] == 0x3DA]
    assert {len(f["data"]) for f in strain} == {7}
    for f in strain:
        assert [f["signals"][n] for n in ("Fx", "Fy", "Fz")] == [r - 0x8000 for r in struct.unpack("<3H", f["data"][:6])]
    assert strain[50]["signals"]["Fy"] == 32767
    # The flags byte, as the DBC's attributes document it: bit 1 (Fy) of sample 50, nothing else.
    msg = cantools.database.load_file(str(DBC)).get_message_by_frame_id(0x3DA)
    attrs = {k: a.value for k, a in msg.dbc.attributes.items()}
    assert (attrs["SatFlagsByte"], attrs["SatFlagsMask"]) == (6, 0b111)
    flags = [f["data"][attrs["SatFlagsByte"]] for f in strain]
    assert flags[50] == 0b010 and flags[:50] + flags[51:] == [0] * 99
    assert msg.decode(strain[50]["data"]) == strain[50]["signals"]  # the API allows the excess byte by default


def test_the_checked_in_dbc_is_the_generators_for_the_arm(tmp_path: Path) -> None:
    done = run(sys.executable, GENERATOR, CONF)
    assert done.returncode == 0, done.stderr
    assert done.stdout == DBC.read_text()
    # The configuration's keys in another order (buses last, skins first): the same DBC.
    lines = CONF.read_text().splitlines()
    order = ("#", "robot", "skin", "pwm", "axis", "strain", "stale_ms", "pair_us", "status_hz", "residual_every",
             "buses")
    moved = sorted(lines, key=lambda l: order.index(l.split(" ", 1)[0]))
    assert moved[-1].startswith("buses ")
    (tmp_path / "moved.conf").write_text("\n".join(moved) + "\n")
    assert run(sys.executable, GENERATOR, tmp_path / "moved.conf").stdout == DBC.read_text()


def test_generator_refuses_a_bad_configuration_with_one_line(tmp_path: Path) -> None:
    conf = tmp_path / "bad.conf"
    conf.write_text(CONF.read_text().replace("skin can2 9 ", "skin can5 9 "))
    done = run(sys.executable, GENERATOR, conf, "--out", tmp_path / "x.dbc")
    line = next(n for n, l in enumerate(conf.read_text().splitlines(), 1) if " can5 " in l)
    assert done.returncode == 2 and not (tmp_path / "x.dbc").exists()
    assert done.stderr.splitlines() == [
        f"icub_can_dbc.py: error: {conf}:{line}: bus 'can5' is not in the 'buses' line (can0 can1 can2)"]


def test_addressed_names_are_unique_and_decode_like_the_same_names(bus: dict, tmp_path: Path,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    """The checked-in DBC names each message with its board address (unique: no duplicate-name warnings);
    --names same writes one name per (class, type), and both decode the bus to the same signals."""
    with caplog.at_level(logging.WARNING, logger="cantools"):
        db = cantools.database.load_file(str(DBC), strict=True)
    assert caplog.records == []
    assert len({m.name for m in db.messages}) == len(db.messages) == 19
    frames = parse_decoded(bus["decoded"].stdout)
    assert [f["name"] for f in frames if f["id"] in (0x121, 0x4C0)][:2] == ["MC_POSITION_2", "SKIN_TAXELS_12"]
    same = tmp_path / "same.dbc"
    assert run(sys.executable, GENERATOR, CONF, "--names", "same", "--out", same).returncode == 0
    plain = parse_decoded(cantools_decode(bus["log"], dbc=same).stdout)
    assert [(f["base"], f["signals"]) for f in frames] == [(f["name"], f["signals"]) for f in plain]
