"""The iCub arm's bus description (its DBC, generated through cantools) and the C header (icub_can.h) describe one
protocol.

The C side speaks through `icub_can_vectors`, built from the header and the pack functions: its constants must
match the database's IDs, lengths and bit positions, and every frame it packs must decode, with cantools, to the
values it packed, and re-encode to the same bytes. The committed firmware_like/icub_can.dbc is `dynid export --dbc`'s
for the arm, compared by what it decodes, not byte for byte.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import cantools
import pytest
from conftest import dynid

from dynid.config.icub_bus import make_id, split_id
from dynid.config.robot_config import load_config
from dynid.io.can_database import BusCodec, FrameError, FrameProblem, database

ROOT = Path(__file__).resolve().parents[2]
VECTORS = ROOT / "build" / "firmware_like" / "icub_can_vectors"
DBC = ROOT / "firmware_like" / "icub_can.dbc"


@pytest.fixture(scope="module")
def codec() -> BusCodec:
    return BusCodec(load_config("icub_right_arm").bus)


def message(codec: BusCodec, cls: int, typ: int, long: bool = False):
    """A message of the arm's bus by (class, type): its layout is the same at every address."""
    c = next(c for (bus, i), c in codec.codecs.items() if split_id(i)[0] == cls and split_id(i)[2] == typ)
    return c.long if long else c.message


@pytest.fixture(scope="module")
def c_side() -> tuple[dict[str, int], list[tuple[int, bytes, dict[str, int]]]]:
    if not VECTORS.is_file():
        pytest.fail(f"{VECTORS} is not built: run scripts/setup")
    out = subprocess.run([str(VECTORS)], capture_output=True, text=True, check=True).stdout
    consts: dict[str, int] = {}
    frames = []
    for line in out.splitlines():
        kind, *rest = line.split()
        if kind == "const":
            consts[rest[0]] = int(rest[1])
        else:
            can_id, dlc, payload, *kv = rest
            data = bytes.fromhex(payload)
            assert len(data) == int(dlc)
            frames.append((int(can_id, 16), data, {k: int(v) for k, v in (x.split("=") for x in kv)}))
    return consts, frames


def _bits(msg, prefix: str) -> dict[str, int]:
    """Single-bit signals of a message as masks relative to their byte (name without prefix -> mask)."""
    return {s.name[len(prefix):]: 1 << (s.start % 8) for s in msg.signals if s.name.startswith(prefix) and s.length == 1}


def test_header_constants_are_the_databases(codec: BusCodec, c_side) -> None:
    c, _ = c_side
    expect = {
        "STRAIN_FORCE": (c["ICUB_CAN_CLASS_STRAIN"], c["ICUB_CAN_STRAIN_FORCE"], c["ICUB_CAN_STRAIN_DLC"]),
        "STRAIN_TORQUE": (c["ICUB_CAN_CLASS_STRAIN"], c["ICUB_CAN_STRAIN_TORQUE"], c["ICUB_CAN_STRAIN_DLC"]),
        "MC_POSITION": (c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_POSITION"], c["ICUB_CAN_MC_POSITION_DLC"]),
        "MC_PID_VAL": (c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_PID_VAL"], c["ICUB_CAN_MC_PID_VAL_DLC"]),
        "MC_STATUS": (c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_STATUS"], c["ICUB_CAN_MC_STATUS_DLC"]),
        "SKIN_TAXELS": (c["ICUB_CAN_CLASS_SKIN"], c["ICUB_CAN_SKIN_TAXELS"], c["ICUB_CAN_SKIN_TAXELS_DLC"]),
    }
    db = database(codec.bus)
    assert {re.sub(r"_\d+$", "", m.name) for m in db.messages} == set(expect)  # MC_POSITION_2: the address
    for m in db.messages:  # every message's ID is its name's (class, type) at its address
        cls, address, typ = split_id(m.frame_id)
        base = re.sub(r"_\d+$", "", m.name)
        assert (cls, typ, m.length) == expect[base], m.name
        assert m.name.endswith(f"_{address}")
    # One layout per (class, type) at every address, up to the physical scales of each board's axes.
    for base in expect:
        shapes = {tuple((s.name, s.start, s.length, s.byte_order, s.is_signed) for s in m.signals)
                  for m in db.messages if m.name.startswith(base + "_")}
        assert len(shapes) == 1, base
    # Saturation flags: the 7-byte variant's byte 6, bit i = channel i of the frame; the strain frames' long form,
    # which the DBC documents by the message attribute DynidLongDlc (one message cannot decode both lengths in
    # `cantools decode`).
    for typ in (c["ICUB_CAN_STRAIN_FORCE"], c["ICUB_CAN_STRAIN_TORQUE"]):
        long = message(codec, c["ICUB_CAN_CLASS_STRAIN"], typ, long=True)
        assert long.length == c["ICUB_CAN_STRAIN_DLC_SAT"]
        flags = sum(1 << (s.start - 48) for s in long.signals if s.name.startswith("Sat") and s.length == 1)
        assert flags == c["ICUB_CAN_STRAIN_SAT_MASK"]
        assert {s.start // 8 for s in long.signals if s.name.startswith("Sat")} == {6}
    for m in db.messages:
        if m.name.startswith("STRAIN"):
            assert m.dbc.attributes["DynidLongDlc"].value == c["ICUB_CAN_STRAIN_DLC_SAT"], m.name
    status = message(codec, c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_STATUS"])
    faults = {"OverCurrent": "OVERCURRENT", "OverTemp": "OVERTEMP", "EncoderFault": "ENCODER",
              "ExternalFault": "EXTERNAL", "PwmLimit": "PWM_LIMIT"}
    for axis, byte in (("Axis0", 0), ("Axis1", 1)):
        bits = _bits(status, axis)
        assert {k: bits[k] for k in faults} == {k: c[f"ICUB_CAN_MC_FAULT_{v}"] for k, v in faults.items()}
        assert {s.start // 8 for s in status.signals if s.name.startswith(axis)} == {byte}
        assert sum(bits[k] for k in faults) == c["ICUB_CAN_MC_FAULT_MASK"]
    board = _bits(status, "Board")
    assert board == {"Restarted": c["ICUB_CAN_MC_BOARD_RESTARTED"], "TxOverrun": c["ICUB_CAN_MC_BOARD_TX_OVERRUN"]}
    assert sum(board.values()) == c["ICUB_CAN_MC_BOARD_MASK"]


def _expected(cls: int, typ: int, v: dict[str, int]) -> dict[str, int]:
    """What the C side packed, as raw values in the database's signal names."""
    if cls == 3:
        ch = ("Fx", "Fy", "Fz") if typ == 0xA else ("Tx", "Ty", "Tz")
        out = {c: v[f"s{i}"] + 0x8000 for i, c in enumerate(ch)}  # offset binary
        return out | {f"Sat{c}": (v["flags"] >> i) & 1 for i, c in enumerate(ch)} | {"SatReserved": 0}
    if cls == 1 and typ in (1, 2):
        sig = "Position" if typ == 1 else "Pwm"
        return {f"Axis0{sig}": v["axis0"], f"Axis1{sig}": v["axis1"]}
    if cls == 1:
        names = ("OverCurrent", "OverTemp", "EncoderFault", "ExternalFault", "PwmLimit")
        out = {f"Axis{a}{n}": (v[f"faults{a}"] >> i) & 1 for a in (0, 1) for i, n in enumerate(names)}
        out |= {f"Axis{a}Reserved": 0 for a in (0, 1)} | {"BoardReserved": 0}
        return out | {"BoardRestarted": v["board"] & 1, "BoardTxOverrun": v["board"] >> 1 & 1, "Sequence": v["seq"]}
    return {"Taxels": v["taxels"]}


def test_every_c_frame_decodes_and_reencodes_with_the_database(codec: BusCodec, c_side) -> None:
    _, frames = c_side
    assert len(frames) == 64 * 5
    seen = set()
    for can_id, data, values in frames:
        cls, _, typ = split_id(can_id)
        msg = message(codec, cls, typ, long=cls == 3 and len(data) == 7)
        want = _expected(cls, typ, values)
        if len(data) == 6:  # a strain frame without the flags byte
            want = {k: v for k, v in want.items() if not k.startswith("Sat")}
        assert msg.decode(data, scaling=False) == want, (hex(can_id), data.hex())
        assert bytes(msg.encode(want, scaling=False)) == data, hex(can_id)
        seen.add((re.sub(r"_\d+$", "", msg.name), len(data)))
    assert seen == {("STRAIN_FORCE", 6), ("STRAIN_FORCE", 7), ("STRAIN_TORQUE", 6), ("STRAIN_TORQUE", 7),
                    ("MC_POSITION", 8), ("MC_PID_VAL", 4), ("MC_STATUS", 4), ("SKIN_TAXELS", 2)}


def test_offset_binary_and_physical_reference_values(codec: BusCodec) -> None:
    # docs/design.md §5, by hand: raw 0x8000 is 0, 0x0000 is -FS, 0xFFFF is FS · 32767/32768, little-endian.
    frame, v = codec.decode("can0", 0x3DA, bytes([0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF]))
    assert (frame.name, v) == ("STRAIN_FORCE_13", {"Fx": 0.0, "Fy": -200.0, "Fz": 200.0 * 32767 / 32768})
    frame, v = codec.decode("can1", make_id(1, 2, 1), (-2).to_bytes(4, "little", signed=True) + (70000).to_bytes(4, "little"))
    tick = 3.141592653589793 / 180 / 182.04444444444445
    assert frame.name == "MC_POSITION_2"
    assert v["Axis0Position"] == pytest.approx(-2 * tick, rel=1e-15) and v["Axis1Position"] == pytest.approx(70000 * tick, rel=1e-15)


def test_seven_byte_strain_frames_decode_with_their_flags(codec: BusCodec) -> None:
    _, v = codec.decode("can0", 0x3DA, bytes([0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF, 0b101]))
    assert {k: v[k] for k in ("SatFx", "SatFy", "SatFz")} == {"SatFx": 1, "SatFy": 0, "SatFz": 1}
    assert codec.encode("can0", 0x3DA, v, long=True) == bytes([0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF, 0b101])


@pytest.mark.parametrize("bus,can_id,data,problem", [
    ("can0", 0x3DC, bytes(6), FrameProblem.UNKNOWN_ID),             # strain type 0xC is not defined
    ("can0", 0x514, bytes(2), FrameProblem.UNKNOWN_ID),             # class 5
    ("can1", 0x3DA, bytes(6), FrameProblem.UNKNOWN_ID),             # the strain board is on can0
    ("can0", 0x3DA, bytes(5), FrameProblem.BAD_LENGTH),
    ("can0", 0x3DA, bytes(8), FrameProblem.BAD_LENGTH),
    ("can0", 0x111, bytes(4), FrameProblem.BAD_LENGTH),
    ("can0", 0x112, bytes(8), FrameProblem.BAD_LENGTH),
    ("can2", 0x480, bytes(1), FrameProblem.BAD_LENGTH),
    ("can0", 0x3DA, bytes(6) + b"\x08", FrameProblem.RESERVED_BITS),  # flag bit 3
    ("can0", 0x113, bytes([0x20, 0, 0, 0]), FrameProblem.RESERVED_BITS),
    ("can0", 0x113, bytes([0, 0, 0x04, 0]), FrameProblem.RESERVED_BITS),
])
def test_bad_frames_are_named(codec: BusCodec, bus: str, can_id: int, data: bytes, problem: FrameProblem) -> None:
    with pytest.raises(FrameError) as e:
        codec.decode(bus, can_id, data)
    assert e.value.problem is problem


def test_extended_ids_are_unknown(codec: BusCodec) -> None:
    with pytest.raises(FrameError) as e:
        codec.decode("can0", 0x111, bytes(8), extended=True)
    assert e.value.problem is FrameProblem.UNKNOWN_ID


def _content(db) -> list:
    """What a database decodes with: per message its ID, name, length and every signal's layout and conversion."""
    return sorted((m.frame_id, m.name, m.length, sorted((s.name, s.start, s.length, s.byte_order, s.is_signed,
                                                         s.is_float, s.scale, s.offset) for s in m.signals))
                  for m in db.messages)


def test_the_committed_dbc_is_dynid_exports(tmp_path: Path) -> None:
    """firmware_like/icub_can.dbc is `dynid export --robot icub_right_arm --dbc` (regenerate it if not)."""
    out = tmp_path / "arm.dbc"
    done = dynid("export", "--robot", "icub_right_arm", "--dbc", str(out))
    assert done.returncode == 0, done.stderr
    fresh, committed = (cantools.database.load_file(str(p), strict=True) for p in (out, DBC))
    assert _content(committed) == _content(fresh) == _content(database(load_config("icub_right_arm").bus))
    assert len(fresh.messages) == 19


def test_example_monitor_config_is_current() -> None:
    """rt_monitor/config/icub_right_arm.conf is what dynid writes for the bundled arm (regenerate it if not)."""
    from dynid.export.monitor_config import monitor_config_text

    text = (ROOT / "rt_monitor" / "config" / "icub_right_arm.conf").read_text()
    assert text == monitor_config_text(load_config("icub_right_arm"))


def test_a_user_configurations_monitor_config_names_its_file(tmp_path: Path) -> None:
    """The monitor configuration's first line says how to write it again: for a user's own robot configuration, its
    file (a walkthrough's `--robot my_panda` was refused: no bundled robot of that name)."""
    from dynid.config.robot_config import BUNDLED_DIR

    mine = tmp_path / "my_panda.yaml"
    mine.write_text((BUNDLED_DIR / "panda.yaml").read_text().replace("name: panda", "name: my_panda", 1))
    first = tmp_path / "first.conf"
    assert dynid("export", "--robot", str(mine), "--monitor-config", str(first)).returncode == 0
    header = first.read_text().splitlines()[0]
    assert header.endswith(f"dynid export --robot {mine.resolve()} --monitor-config FILE)"), header
    again = tmp_path / "again.conf"
    done = dynid("export", "--robot", header.split("--robot ")[1].split(" ")[0], "--monitor-config", str(again))
    assert done.returncode == 0 and again.read_text() == first.read_text(), done.stderr


def test_the_bus_exports_without_a_supplied_urdf(tmp_path: Path) -> None:
    """The DBC and the monitor configuration come from the configuration alone: a robot whose URDF the user supplies
    (the UR10e's) exports them with no DYNID_URDF_PATH; what needs the chain still refuses, in one line."""
    env = {"DYNID_URDF_PATH": ""}
    dbc, conf = tmp_path / "ur.dbc", tmp_path / "ur.conf"
    done = dynid("export", "--robot", "ur10e", "--dbc", str(dbc), "--monitor-config", str(conf), env=env)
    assert done.returncode == 0, done.stderr
    assert _content(cantools.database.load_file(str(dbc), strict=True)) == _content(database(load_config(
        "ur10e", need_urdf=False).bus))
    assert conf.read_text().startswith("# rt_monitor configuration for ur10e")
    done = dynid("export", "--robot", "ur10e", "--cad", "--out", str(tmp_path / "ur.dcoef"), env=env)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "a URDF you supply" in done.stderr, done.stderr


def test_the_bus_of_a_models_configuration_edited_since_the_fit_is_written(default_model: Path, tmp_path: Path) -> None:
    """`export --model M --robot CFG --dbc` with CFG the model's robot edited since the fit (its F/T full scale): the
    DBC and monitor configuration were the model's copy, the edit silently unwritten (a walkthrough: the monitor then
    refused the model at start, with no hint why). Now the edited bus, with a note; the coefficient file the fit's."""
    from dynid.config.robot_config import BUNDLED_DIR

    edited = tmp_path / "icub_right_arm.yaml"
    text = (BUNDLED_DIR / "icub_right_arm.yaml").read_text()
    assert text.count("full_scale: [200.0, 200.0, 200.0,") == 1
    edited.write_text(text.replace("full_scale: [200.0, 200.0, 200.0,", "full_scale: [400.0, 400.0, 400.0,"))
    dbc, conf, coef = tmp_path / "arm.dbc", tmp_path / "arm.conf", tmp_path / "arm.dcoef"
    done = dynid("export", "--model", str(default_model), "--robot", str(edited), "--dbc", str(dbc),
                 "--monitor-config", str(conf), "--out", str(coef))
    assert done.returncode == 0, done.stderr
    assert f"note: {edited} is not the configuration {default_model} was fitted with (edited since): its bus" in done.stdout
    scale = {s.name: s.scale for m in cantools.database.load_file(str(dbc)).messages for s in m.signals}
    own = {s.name: s.scale for m in database(load_config("icub_right_arm").bus).messages for s in m.signals}
    changed = {k for k in own if scale[k] != own[k]}
    assert changed == {"Fx", "Fy", "Fz"} and all(scale[k] == pytest.approx(2 * own[k]) for k in changed)
    plain = dynid("export", "--model", str(default_model), "--dbc", str(tmp_path / "own.dbc"))
    assert plain.returncode == 0 and "note:" not in plain.stdout
    assert {s.name: s.scale for m in cantools.database.load_file(str(tmp_path / "own.dbc")).messages
            for s in m.signals} == own
