"""The DBC (firmware_like/icub_can.dbc, read by cantools) and the C header (icub_can.h) describe one protocol.

The C side speaks through `icub_can_vectors`, built from the header and the pack functions: its constants must
match the DBC's IDs, lengths and bit positions, and every frame it packs must decode, with cantools, to the
values it packed, and re-encode to the same bytes.
"""

from __future__ import annotations

import re

import subprocess
from pathlib import Path

import pytest

from dynid.errors import DataError
from dynid.io.can_protocol import FrameError, FrameProblem, Protocol, make_id, split_id

ROOT = Path(__file__).resolve().parents[2]
VECTORS = ROOT / "build" / "firmware_like" / "icub_can_vectors"


@pytest.fixture(scope="module")
def proto() -> Protocol:
    return Protocol()


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
    """Single-bit signals of a DBC message as masks relative to their byte (name without prefix -> mask)."""
    return {s.name[len(prefix):]: 1 << (s.start % 8) for s in msg.signals if s.name.startswith(prefix) and s.length == 1}


def test_header_constants_are_the_dbcs(proto: Protocol, c_side) -> None:
    c, _ = c_side
    expect = {
        "STRAIN_FORCE": (c["ICUB_CAN_CLASS_STRAIN"], c["ICUB_CAN_STRAIN_FORCE"], c["ICUB_CAN_STRAIN_DLC"]),
        "STRAIN_TORQUE": (c["ICUB_CAN_CLASS_STRAIN"], c["ICUB_CAN_STRAIN_TORQUE"], c["ICUB_CAN_STRAIN_DLC"]),
        "MC_POSITION": (c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_POSITION"], c["ICUB_CAN_MC_POSITION_DLC"]),
        "MC_PID_VAL": (c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_PID_VAL"], c["ICUB_CAN_MC_PID_VAL_DLC"]),
        "MC_STATUS": (c["ICUB_CAN_CLASS_MC"], c["ICUB_CAN_MC_STATUS"], c["ICUB_CAN_MC_STATUS_DLC"]),
        "SKIN_TAXELS": (c["ICUB_CAN_CLASS_SKIN"], c["ICUB_CAN_SKIN_TAXELS"], c["ICUB_CAN_SKIN_TAXELS_DLC"]),
    }
    assert {re.sub(r"_\d+$", "", m.name) for m in proto.db.messages} == set(expect)  # MC_POSITION_2: the address
    for name, (cls, typ, dlc) in expect.items():
        msg = proto.message(name)
        got_cls, _, got_typ = split_id(msg.frame_id)
        assert (got_cls, got_typ, msg.length) == (cls, typ, dlc), name
    # The DBC lists each message at every board address of the bus: one layout per (class, type).
    layout = {name: _layout(proto.message(name)) for name in expect}
    for msg in proto.db.messages:
        assert _layout(msg) == layout[re.sub(r"_\d+$", "", msg.name)], hex(msg.frame_id)
    assert c["ICUB_CAN_STRAIN_DLC"] == 6
    # Saturation flags: the 7-byte variant's byte 6, bit i = channel i of the frame; documented by attributes of
    # the 6-byte strain messages (one message cannot decode both lengths in `cantools decode`).
    for msg in proto.db.messages:
        if msg.name.startswith("STRAIN"):
            attrs = {k: a.value for k, a in msg.dbc.attributes.items()}
            assert attrs["SatFlagsByte"] + 1 == c["ICUB_CAN_STRAIN_DLC_SAT"], hex(msg.frame_id)
            assert attrs["SatFlagsMask"] == c["ICUB_CAN_STRAIN_SAT_MASK"], hex(msg.frame_id)
    status = proto.message("MC_STATUS")
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


def _layout(msg) -> tuple:
    return msg.length, [(s.name, s.start, s.length, s.byte_order, s.is_signed, s.scale, s.offset) for s in msg.signals]


def _expected(name: str, v: dict[str, int]) -> dict[str, int]:
    """What the C side packed, in the DBC's signal names."""
    if name.startswith("STRAIN"):
        ch = ("Fx", "Fy", "Fz") if name == "STRAIN_FORCE" else ("Tx", "Ty", "Tz")
        out = {c: v[f"s{i}"] for i, c in enumerate(ch)}
        return out | {f"Sat{c}": (v["flags"] >> i) & 1 for i, c in enumerate(ch)}
    if name in ("MC_POSITION", "MC_PID_VAL"):
        sig = "Position" if name == "MC_POSITION" else "Pwm"
        return {f"Axis0{sig}": v["axis0"], f"Axis1{sig}": v["axis1"]}
    if name == "MC_STATUS":
        names = ("OverCurrent", "OverTemp", "EncoderFault", "ExternalFault", "PwmLimit")
        out = {f"Axis{a}{n}": (v[f"faults{a}"] >> i) & 1 for a in (0, 1) for i, n in enumerate(names)}
        return out | {"BoardRestarted": v["board"] & 1, "BoardTxOverrun": v["board"] >> 1 & 1, "Sequence": v["seq"]}
    return {"Taxels": v["taxels"]}


def test_every_c_frame_decodes_and_reencodes_with_the_dbc(proto: Protocol, c_side) -> None:
    _, frames = c_side
    assert len(frames) == 64 * 5
    seen = set()
    strain = {0xA: "STRAIN_FORCE", 0xB: "STRAIN_TORQUE"}
    for can_id, data, values in frames:
        cls, address, typ = split_id(can_id)
        if cls == 3 and len(data) == 7:
            # The saturation variant: the 6-byte message's counts (cantools' Message.decode allows the excess
            # byte), then byte 6 as the strain messages' SatFlagsByte / SatFlagsMask document it.
            msg = proto.message(strain[typ])
            attrs = {k: a.value for k, a in msg.dbc.attributes.items()}
            want = _expected(strain[typ], values)
            counts = {k: v for k, v in want.items() if not k.startswith("Sat")}
            assert msg.decode(data) == counts, (hex(can_id), data.hex())
            flags = data[attrs["SatFlagsByte"]]
            assert flags & ~attrs["SatFlagsMask"] == 0
            assert {k: (flags >> i) & 1 for i, k in enumerate(k for k in want if k.startswith("Sat"))} == \
                {k: v for k, v in want.items() if k.startswith("Sat")}, (hex(can_id), data.hex())
            name, payload = proto.encode(strain[typ], address, counts)
            assert (name, payload + bytes([flags])) == (can_id, data)
            seen.add((strain[typ], len(data)))
            assert proto.decode(can_id, data).signals == want  # the package reads byte 6 too
            continue
        f = proto.decode(can_id, data)
        seen.add((f.name, len(data)))
        assert f.address == address
        want = _expected(f.name, values)
        got = {k: v for k, v in f.signals.items() if not k.endswith("Reserved")}
        if len(data) == 6:  # a strain frame without the flags byte
            want = {k: v for k, v in want.items() if not k.startswith("Sat")}
        assert got == want, (hex(can_id), data.hex())
        assert proto.encode(f.name, f.address, want, dlc=len(data)) == (can_id, data)
    assert seen == {("STRAIN_FORCE", 6), ("STRAIN_FORCE", 7), ("STRAIN_TORQUE", 6), ("STRAIN_TORQUE", 7),
                    ("MC_POSITION", 8), ("MC_PID_VAL", 4), ("MC_STATUS", 4), ("SKIN_TAXELS", 2)}


def test_offset_binary_reference_values(proto: Protocol) -> None:
    # docs/design.md §5, by hand: raw 0x8000 is 0, 0x0000 is -32768, 0xFFFF is 32767, little-endian.
    f = proto.decode(0x3DA, bytes([0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF]))
    assert f.signals | {} == {"Fx": 0, "Fy": -32768, "Fz": 32767}
    f = proto.decode(make_id(1, 2, 1), (-2).to_bytes(4, "little", signed=True) + (70000).to_bytes(4, "little"))
    assert (f.name, f.address, f.signals) == ("MC_POSITION", 2, {"Axis0Position": -2, "Axis1Position": 70000})


def test_seven_byte_strain_frames_decode_with_their_flags(proto: Protocol) -> None:
    f = proto.decode(0x3DA, bytes([0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF, 0b101]))
    assert f.signals | {} == {"Fx": 0, "Fy": -32768, "Fz": 32767, "SatFx": 1, "SatFy": 0, "SatFz": 1}
    assert proto.encode("STRAIN_FORCE", 13, f.signals, dlc=7) == (0x3DA, bytes([0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF, 0b101]))


@pytest.mark.parametrize("can_id,data,problem", [
    (0x3DC, bytes(6), FrameProblem.UNKNOWN_ID),             # strain type 0xC is not defined
    (0x514, bytes(2), FrameProblem.UNKNOWN_ID),             # class 5
    (0x3DA, bytes(5), FrameProblem.BAD_LENGTH),
    (0x3DA, bytes(8), FrameProblem.BAD_LENGTH),
    (0x111, bytes(4), FrameProblem.BAD_LENGTH),
    (0x112, bytes(8), FrameProblem.BAD_LENGTH),
    (0x480, bytes(1), FrameProblem.BAD_LENGTH),
    (0x3DA, bytes(6) + b"\x08", FrameProblem.RESERVED_BITS),  # flag bit 3
    (0x113, bytes([0x20, 0, 0, 0]), FrameProblem.RESERVED_BITS),
    (0x113, bytes([0, 0, 0x04, 0]), FrameProblem.RESERVED_BITS),
])
def test_bad_frames_are_named(proto: Protocol, can_id: int, data: bytes, problem: FrameProblem) -> None:
    with pytest.raises(FrameError) as e:
        proto.decode(can_id, data)
    assert e.value.problem is problem


def test_extended_ids_are_unknown(proto: Protocol) -> None:
    with pytest.raises(FrameError) as e:
        proto.decode(0x111, bytes(8), extended=True)
    assert e.value.problem is FrameProblem.UNKNOWN_ID


def test_a_foreign_dbc_is_refused(tmp_path: Path) -> None:
    text = (ROOT / "firmware_like" / "icub_can.dbc").read_text().replace("BO_ 1152 SKIN_TAXELS_8", "BO_ 1153 SKIN_TAXELS_8")
    text = text.replace('BO_ 1152 1;', 'BO_ 1153 1;').replace("CM_ BO_ 1152", "CM_ BO_ 1153")
    (tmp_path / "x.dbc").write_text(text)
    with pytest.raises(DataError, match="SKIN_TAXELS_8 .0x481. is not in the iCub protocol"):
        Protocol(tmp_path / "x.dbc")
    (tmp_path / "y.dbc").write_text("not a dbc")
    with pytest.raises(DataError, match="y.dbc"):
        Protocol(tmp_path / "y.dbc")


def test_example_monitor_config_is_current() -> None:
    """rt_monitor/config/icub_right_arm.conf is what dynid writes for the bundled arm (regenerate it if not)."""
    from dynid.config.robot_config import load_config
    from dynid.export.monitor_config import monitor_config_text

    text = (ROOT / "rt_monitor" / "config" / "icub_right_arm.conf").read_text()
    assert text == monitor_config_text(load_config("icub_right_arm"))
