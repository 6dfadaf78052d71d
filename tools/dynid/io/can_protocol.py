"""The iCub CAN-era protocol (docs/design.md §5) decoded from its DBC, firmware_like/icub_can.dbc, with cantools.

The DBC lists each message at every board address of the robot (firmware_like/tools/icub_can_dbc.py writes it
from the monitor's configuration), named after its (class, type), optionally with the address appended
(MC_POSITION_2); the layout is the same at every address, so frames are matched on (class, type) and the address
is returned beside the signals. Strain frames are 6 bytes; their saturation variant adds a flags byte, which
the DBC describes by the SatFlagsByte / SatFlagsMask attributes (cantools decode checks lengths exactly, so one
message cannot carry both); it decodes here to SatFx, SatFy, SatFz (SatTx, … on the torque half).
Physical conversions need the robot configuration's CAN mapping (full scales, ticks per degree, PWM scale):
- strain: value = count · FS[ch] / 32768;
- encoders: joint angle in degrees = ticks / ticks_per_degree − zero_deg (zero_deg: the reading at joint zero);
- PWM: duty = count / pwm_full_scale.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from enum import Enum
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..errors import DataError

STRAIN_COUNTS = 32768
# Messages whose layout is in the DBC, by (class, type); the DBC itself is checked against these names.
MESSAGE_NAMES: dict[tuple[int, int], str] = {
    (3, 0xA): "STRAIN_FORCE",
    (3, 0xB): "STRAIN_TORQUE",
    (1, 1): "MC_POSITION",
    (1, 2): "MC_PID_VAL",
    (1, 3): "MC_STATUS",
    (4, 0): "SKIN_TAXELS",
}
# The saturation flags of the strain frames' 7-byte variant, bit by bit (docs/design.md §5).
SATURATION_FLAGS = {"STRAIN_FORCE": ("SatFx", "SatFy", "SatFz"), "STRAIN_TORQUE": ("SatTx", "SatTy", "SatTz")}


class FrameProblem(Enum):
    """Why a frame is not a sample: each is a counter in the monitor's status (docs/design.md §5 "Bad input")."""

    UNKNOWN_ID = "unknown id"  # extended ID, or a (class, type) the protocol does not define
    BAD_LENGTH = "wrong length"
    RESERVED_BITS = "reserved bits set"


@dataclass(frozen=True)
class Frame:
    """One decoded frame: the message name, its source address and its raw signal values (counts, ticks)."""

    name: str
    address: int
    signals: dict[str, int]


class FrameError(Exception):
    def __init__(self, problem: FrameProblem, can_id: int, dlc: int) -> None:
        super().__init__(f"frame 0x{can_id:03X} (DLC {dlc}): {problem.value}")
        self.problem = problem


def split_id(can_id: int) -> tuple[int, int, int]:
    """(class, source address, type) of an 11-bit ID: ID = class<<8 | source<<4 | type."""
    return (can_id >> 8) & 0x7, (can_id >> 4) & 0xF, can_id & 0xF


def make_id(cls: int, address: int, typ: int) -> int:
    if not (0 <= cls <= 7 and 0 <= address <= 15 and 0 <= typ <= 15):
        raise ValueError(f"CAN ID field out of range: class {cls}, address {address}, type {typ}")
    return cls << 8 | address << 4 | typ


def dbc_path() -> Path:
    """The protocol's DBC: $DYNID_DBC, else firmware_like/icub_can.dbc of the source tree dynid runs from."""
    env = os.environ.get("DYNID_DBC")
    path = Path(env) if env else Path(__file__).resolve().parents[3] / "firmware_like" / "icub_can.dbc"
    if not path.is_file():
        raise DataError(f"CAN protocol file not found: {path} (set DYNID_DBC to firmware_like/icub_can.dbc)")
    return path


class Protocol:
    """The DBC's message layouts, keyed by (class, type)."""

    def __init__(self, path: Path | None = None) -> None:
        import cantools  # only the CAN commands pay for it

        path = path or dbc_path()
        try:
            self.db = cantools.database.load_file(str(path), strict=True)
        except (OSError, cantools.database.UnsupportedDatabaseFormatError) as e:
            raise DataError(f"{path}: not a readable DBC: {' '.join(str(e).split())}") from None
        self.templates: dict[tuple[int, int], Any] = {}
        for msg in self.db.messages:
            cls, address, typ = split_id(msg.frame_id)
            base = MESSAGE_NAMES.get((cls, typ))
            if base is None or msg.name not in (base, f"{base}_{address}") or msg.is_extended_frame:
                raise DataError(f"{path}: message {msg.name} (0x{msg.frame_id:03X}) is not in the iCub protocol")
            first = self.templates.setdefault((cls, typ), msg)
            if _layout(first) != _layout(msg):
                raise DataError(f"{path}: message {msg.name} has another layout than {first.name}")
        missing = set(MESSAGE_NAMES.values()) - {MESSAGE_NAMES[k] for k in self.templates}
        if missing:
            raise DataError(f"{path}: messages missing: {', '.join(sorted(missing))}")
        self.by_name = {MESSAGE_NAMES[k]: m for k, m in self.templates.items()}

    def message(self, name: str) -> Any:
        """The layout of a message by its protocol name (STRAIN_FORCE, MC_POSITION, …)."""
        return self.by_name[name]

    @staticmethod
    def saturation(msg: Any) -> tuple[int, int] | None:
        """(byte, mask) of the flags of a message's saturation variant, or None."""
        attributes = msg.dbc.attributes if msg.dbc is not None else {}
        byte, mask = attributes.get("SatFlagsByte"), attributes.get("SatFlagsMask")
        if byte is None:
            return None
        return int(byte.value), int(mask.value) if mask is not None else 0

    def decode(self, can_id: int, data: bytes, extended: bool = False) -> Frame:
        """Decode one frame; raises `FrameError` for an unknown ID, a wrong length or reserved bits set."""
        cls, address, typ = split_id(can_id)
        msg = None if extended or can_id > 0x7FF else self.templates.get((cls, typ))
        if msg is None:
            raise FrameError(FrameProblem.UNKNOWN_ID, can_id, len(data))
        name = MESSAGE_NAMES[(cls, typ)]
        sat = self.saturation(msg)
        if len(data) != msg.length and not (sat is not None and len(data) == sat[0] + 1):
            raise FrameError(FrameProblem.BAD_LENGTH, can_id, len(data))
        values = msg.decode(bytes(data[: msg.length]), decode_choices=False, scaling=True)
        signals = {k: int(v) for k, v in values.items()}
        if any(v for k, v in signals.items() if k.endswith("Reserved")):
            raise FrameError(FrameProblem.RESERVED_BITS, can_id, len(data))
        if sat is not None and len(data) == sat[0] + 1:
            flags = data[sat[0]]
            if flags & ~sat[1] & 0xFF:
                raise FrameError(FrameProblem.RESERVED_BITS, can_id, len(data))
            signals |= {n: (flags >> i) & 1 for i, n in enumerate(SATURATION_FLAGS[name])}
        return Frame(name, address, signals)

    def encode(self, name: str, address: int, signals: dict[str, int], dlc: int | None = None) -> tuple[int, bytes]:
        """(ID, payload) of a message at a board address; a strain frame with dlc=7 carries its saturation flags
        (SatFx, … in `signals`)."""
        msg = self.message(name)
        cls, _, typ = split_id(msg.frame_id)
        flags = {k: signals[k] for k in SATURATION_FLAGS.get(name, ()) if k in signals}
        full = {s.name: 0 for s in msg.signals} | {k: v for k, v in signals.items() if k not in flags}
        data = bytes(msg.encode(full, scaling=True, strict=True))
        sat = self.saturation(msg)
        if sat is not None and dlc == sat[0] + 1:
            data += bytes([sum(int(flags.get(n, 0)) << i for i, n in enumerate(SATURATION_FLAGS[name]))])
        elif dlc is not None and dlc != msg.length:
            raise ValueError(f"{name} is {msg.length} bytes" + (f" or {sat[0] + 1}" if sat else "") + f", not {dlc}")
        return make_id(cls, address, typ), data


def _layout(msg: Any) -> tuple:
    """What must agree between the addresses of one message: its length and every signal's bit layout."""
    return msg.length, tuple((s.name, s.start, s.length, s.is_signed, s.scale, s.offset) for s in msg.signals)


@lru_cache(maxsize=1)
def default_protocol() -> Protocol:
    return Protocol()
