"""The DBC decodes the bus the boards drive: `python -m cantools decode firmware_like/icub_can.dbc < LOG`.

A simulated contact run goes through the C board emulators (`boards`, the bundled arm's configuration: boards
at addresses 1-4, 8-13 on three buses) into a candump log; cantools' own command decodes every frame of it with the
DBC `dynid export --dbc` writes (committed as firmware_like/icub_can.dbc), and the values it prints are the bytes'
by hand and the run's data within the protocol's quantisation (full scales, ticks per degree and PWM scales from the
configuration), in physical units. The strain board's 7-byte saturation variant is the frame's long form: it decodes
with `--no-strict`, its flags byte where the DBC's DynidLongDlc attribute says; a strain board configured with
`saturation_flags: true` sends it as its only form, and then its DBC decodes it strictly. A description the monitor
cannot hold, or a wrong one, is refused with one line and nothing written.

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
from conftest import dynid

from dynid.config.robot_config import load_config

ROOT = Path(__file__).resolve().parents[2]
BOARDS = ROOT / "build" / "firmware_like" / "boards"
DBC = ROOT / "firmware_like" / "icub_can.dbc"
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
    """The board map of the bundled arm (its robot configuration's `can:` section)."""
    can = load_config("icub_right_arm").can
    c: dict = {"axis": {}, "pwm": {}, "skin": [b["address"] for b in can["skin"]]}  # skin n: patch n (skin.patch)
    s = can["strain"][0]
    c["strain"] = (s["address"], [float(x) for x in s["full_scale"]])
    for b in can["motor_control"]:
        for slot, ax in enumerate(b["axes"]):
            c["axis"][(b["address"], slot)] = (ax["joint"], float(ax["ticks_per_degree"]), float(ax.get("zero_deg", 0)))
            if ax.get("motor"):
                c["pwm"][(b["address"], slot)] = (ax["motor"], float(b["pwm_full_scale"]))
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
            out[-1]["signals"][name] = float(value.split()[0])
    return out


@pytest.fixture(scope="module")
def bus(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("dbc")
    # 8 s: the 4 s run has no contact, so its skin frames would all be zero.
    done = dynid("simulate", "--kind", "contact", "--duration", "8", "--out", root / "run")
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
            for i, n in enumerate(names):
                scale = fs[3 * half + i] / 32768
                assert sig[n] == pytest.approx(counts[i] * scale, abs=1e-12 * fs[3 * half + i])
                assert abs(sig[n] - row["ft.r_arm_ft." + n.lower()]) <= scale / 2 * 1.0001
        elif cls == 1 and typ == 1:
            ticks = struct.unpack("<2i", data)
            for slot in (0, 1):
                if (address, slot) in c["axis"]:
                    joint, tpd, zero = c["axis"][(address, slot)]
                    assert sig[f"Axis{slot}Position"] == pytest.approx(math.radians(ticks[slot] / tpd - zero), abs=1e-12)
                    assert abs(sig[f"Axis{slot}Position"] - row[f"q.{joint}"]) <= math.radians(0.5 / tpd) * 1.0001, joint
                else:
                    assert sig[f"Axis{slot}Position"] == ticks[slot]  # an unused slot: raw ticks
        elif cls == 1 and typ == 2:
            counts = struct.unpack("<2h", data)
            for slot in (0, 1):
                if (address, slot) in c["pwm"]:
                    motor, full = c["pwm"][(address, slot)]
                    assert sig[f"Axis{slot}Pwm"] == pytest.approx(counts[slot] / full, abs=1e-15)
                    assert abs(sig[f"Axis{slot}Pwm"] - row[f"pwm.{motor}"]) <= 0.5 / full + 1e-12, motor
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


def _saturated_csv(bus: dict, tmp_path: Path) -> Path:
    lines = bus["csv"].read_text().splitlines()
    i = lines[0].split(",").index("ft.r_arm_ft.fy")
    rows = [l.split(",") for l in lines[1:101]]
    rows[50][i] = "250.0"  # beyond the 200 N full scale: clamped, flagged
    csv = tmp_path / "sat.csv"
    csv.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    return csv


def test_the_seven_byte_saturation_variant(bus: dict, tmp_path: Path) -> None:
    csv = _saturated_csv(bus, tmp_path)
    log = tmp_path / "sat.log"
    assert run(BOARDS, "--config", CONF, "--data", csv, "--sink", f"candump:{log}").returncode == 0
    # cantools decode checks lengths exactly: the 6-byte strain message does not take its 7-byte long form ...
    strict = parse_decoded(cantools_decode(log).stdout)
    assert {f["error"] for f in strict if f["id"] >> 8 == 3} == {"Wrong data size: 7 instead of 6 bytes"}
    assert all(f["name"] for f in strict if f["id"] >> 8 != 3)
    # ... --no-strict does: every frame, the counts of the first 6 bytes.
    frames = parse_decoded(cantools_decode(log, "--no-strict").stdout)
    assert len(frames) == len(strict) and [f for f in frames if f["error"] or not f["name"]] == []
    strain = [f for f in frames if f["id"] == 0x3DA]
    assert {len(f["data"]) for f in strain} == {7}
    for f in strain:
        counts = [r - 0x8000 for r in struct.unpack("<3H", f["data"][:6])]
        assert [round(f["signals"][n] * 32768 / 200) for n in ("Fx", "Fy", "Fz")] == counts
    assert strain[50]["signals"]["Fy"] == pytest.approx(200 * 32767 / 32768)
    # The flags byte, as the DBC documents the long form: its length in DynidLongDlc, its signals in the comment.
    msg = cantools.database.load_file(str(DBC)).get_message_by_frame_id(0x3DA)
    assert msg.dbc.attributes["DynidLongDlc"].value == 7 and "SatFy (49|1)" in msg.comment
    flags = [f["data"][6] for f in strain]
    assert flags[50] == 0b010 and flags[:50] + flags[51:] == [0] * 99


def test_a_board_configured_with_its_flags_decodes_strictly(bus: dict, tmp_path: Path) -> None:
    """`saturation_flags: true`: the 7-byte frame is the board's only form, in the DBC and on the bus."""
    arm = Path(load_config("icub_right_arm").source).read_text()
    robot = tmp_path / "arm_flags.yaml"
    robot.write_text(arm.replace("full_scale: [200.0, 200.0, 200.0, 10.0, 10.0, 10.0]}",
                                 "full_scale: [200.0, 200.0, 200.0, 10.0, 10.0, 10.0], saturation_flags: true}")
                     .replace("urdf: {icub_models: iCubGenova04}", "urdf: {icub_models: iCubGenova04}"))
    dbc, conf, log = tmp_path / "flags.dbc", tmp_path / "flags.conf", tmp_path / "flags.log"
    done = dynid("export", "--robot", robot, "--dbc", dbc, "--monitor-config", conf)
    assert done.returncode == 0, done.stderr
    assert run(BOARDS, "--config", conf, "--data", _saturated_csv(bus, tmp_path), "--sink", f"candump:{log}").returncode == 0
    frames = parse_decoded(cantools_decode(log, dbc=dbc).stdout)
    assert [f for f in frames if f["error"] or not f["name"]] == []
    strain = [f for f in frames if f["id"] == 0x3DA]
    assert {len(f["data"]) for f in strain} == {7}
    assert [f["signals"]["SatFy"] for f in strain].count(1) == 1 and strain[50]["signals"]["SatFy"] == 1


def test_a_bus_the_monitor_cannot_hold_or_a_wrong_one_is_refused_before_writing(tmp_path: Path) -> None:
    base = Path(load_config("icub_right_arm").source).read_text()
    many = "".join(f"    - {{bus: {'can2' if k < 15 else 'can1'}, address: {k % 15 + 1}, patch: p{k}, side: distal}}\n"
                   for k in range(17))
    cases = {
        # 17 skin patches: the monitor's kMaxSkins is 16 (rt_monitor/include/rt_monitor/capacity.hpp).
        "capacity": base.split("  skin:")[0] + "  skin:\n" + many,
        "address": base.replace("{bus: can2, address: 8,", "{bus: can2, address: 16,"),
    }
    want = {"capacity": "its bus has 17 skin patches, the monitor holds at most 16 (kMaxSkins in "
                        "rt_monitor/include/rt_monitor/capacity.hpp)",
            "address": "field 'can.skin[0].address' must be an integer board address in 1..15, got 16"}
    for name, text in cases.items():
        robot = tmp_path / f"{name}.yaml"
        robot.write_text(text)
        out = tmp_path / f"{name}.dbc"
        done = dynid("export", "--robot", robot, "--dbc", out, "--monitor-config", tmp_path / f"{name}.conf")
        assert done.returncode == 2, done.stderr
        assert len(done.stderr.splitlines()) == 1 and want[name] in done.stderr, done.stderr
        assert not out.exists() and not (tmp_path / f"{name}.conf").exists()
