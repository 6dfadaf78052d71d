"""The robot's bus description (dynid.config.bus) as cantools databases: the DBC `dynid export --dbc` writes, and the
codec every frame dynid reads or writes goes through.

Built with cantools' API (`Database`, `Message`, `Signal`, `Node`), never as DBC text: one message per frame, named
as the frame, sent by its node and received by `rt_monitor`, its signals with their start bit, length, byte order,
sign (IEEE float where described), scale and offset, and a comment naming the target (`q.r_elbow`). A frame's long
form (the iCub strain board's 7-byte saturation variant) is a second message of the same ID kept beside the
database: a DBC holds one length per ID and `cantools decode` checks it, so the DBC documents the long form in the
message comment and the attribute `DynidLongDlc` instead, and `dynid import` decodes both lengths with cantools.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from functools import lru_cache
from typing import Any

from ..config.bus import BusDescription, BusFrame, BusSignal
from ..errors import DataError

MONITOR_NODE = "rt_monitor"


class FrameProblem(Enum):
    """Why a frame is not data: each is a counter in the monitor's status (docs/design.md §5 "Bad input")."""

    UNKNOWN_ID = "unknown id"  # extended, remote, or no frame of the description on that bus
    BAD_LENGTH = "wrong length"
    RESERVED_BITS = "reserved bits set"


class FrameError(Exception):
    def __init__(self, problem: FrameProblem, can_id: int, dlc: int) -> None:
        super().__init__(f"frame 0x{can_id:03X} (DLC {dlc}): {problem.value}")
        self.problem = problem


@dataclass(frozen=True)
class Codec:
    """One frame's cantools messages: the nominal one (the DBC's) and its long form, if any."""

    frame: BusFrame
    message: Any  # cantools.database.can.Message
    long: Any | None

    def message_for(self, dlc: int) -> Any | None:
        if dlc == self.frame.dlc:
            return self.message
        if self.long is not None and dlc == self.frame.long_dlc:
            return self.long
        return None


def _signal(s: BusSignal) -> Any:
    from cantools.database.can import Signal
    from cantools.database.conversion import BaseConversion

    lo, hi = s.physical_range
    return Signal(s.name, s.start, s.length, byte_order="little_endian" if s.byte_order == "little" else "big_endian",
                  is_signed=s.is_signed, conversion=BaseConversion.factory(s.scale, s.offset, None, s.type == "float"),
                  minimum=lo if abs(lo) < 1e300 else None, maximum=hi if abs(hi) < 1e300 else None, unit=s.unit,
                  comment=f"target {s.target}" if s.target else "carried, not read", receivers=[MONITOR_NODE])


def _message(frame: BusFrame, long: bool, dbc: Any = None) -> Any:
    from cantools.database.can import Message

    signals = [_signal(s) for s in frame.signals if long or s.end_byte <= frame.dlc]
    comment = f"bus {frame.bus}" + (f"; every {frame.period_ms:g} ms" if frame.period_ms else "; every sample")
    if frame.long_dlc and not long:
        extra = ", ".join(f"{s.name} ({s.start}|{s.length})" for s in frame.signals if s.end_byte > frame.dlc)
        comment += (f"; also sent as {frame.long_dlc} bytes (DynidLongDlc), which adds {extra}: "
                    "`cantools decode --no-strict` reads its first bytes")
    return Message(frame.id, frame.name, frame.long_dlc if long else frame.dlc, signals, senders=[frame.node],
                   cycle_time=int(round(frame.period_ms)) if frame.period_ms else None, comment=comment,
                   bus_name=frame.bus, dbc_specifics=dbc)


def _specifics(frames: list[BusFrame]) -> tuple[Any, dict[str, Any]]:
    """The database's DBC specifics (the DynidLongDlc attribute's definition) and each long-form frame's message
    specifics (its value)."""
    from collections import OrderedDict

    from cantools.database.can.formats.dbc import DbcSpecifics
    from cantools.database.can.formats.dbc.dbc_attribute import DbcAttribute
    from cantools.database.can.formats.dbc.dbc_attribute_definition import DbcAttributeDefinition

    definition = DbcAttributeDefinition("DynidLongDlc", default_value=0, kind="BO_", type_name="INT", minimum=0,
                                        maximum=8)
    per_message = {f.name: DbcSpecifics(attributes=OrderedDict(DynidLongDlc=DbcAttribute(f.long_dlc, definition)))
                   for f in frames if f.long_dlc}
    return DbcSpecifics(attribute_definitions=OrderedDict(DynidLongDlc=definition)), per_message


def database(bus: BusDescription, frames: list[BusFrame] | None = None, robot: str = "") -> Any:
    """The cantools Database of the given frames (default: all of the description), as the DBC has it."""
    from cantools.database.can import Database, Node

    frames = list(bus.frames if frames is None else frames)
    spec, per_message = _specifics(frames)
    messages = [_message(f, False, per_message.get(f.name)) for f in frames]
    nodes = [Node(n) for n in dict.fromkeys([f.node for f in frames] + [MONITOR_NODE])]
    return Database(messages=messages, nodes=nodes, version=f"dynid {robot}".strip(), dbc_specifics=spec)


def dbc_files(bus: BusDescription, robot: str) -> dict[str, str]:
    """The DBC text per file suffix: one DBC ("") when the IDs are unique over all buses, else one per bus (the bus
    name): a DBC holds an ID once, and `cantools decode` matches on the ID alone."""
    ids = [f.id for f in bus.frames]
    groups = {"": list(bus.frames)} if len(set(ids)) == len(ids) else \
        {b: [f for f in bus.frames if f.bus == b] for b in bus.buses}
    return {suffix: database(bus, frames, robot).as_dbc_string() for suffix, frames in groups.items() if frames}


class BusCodec:
    """Decode and encode the frames of one robot's bus with cantools, by (bus, ID)."""

    def __init__(self, bus: BusDescription) -> None:
        db = database(bus)
        self.bus = bus
        self.codecs: dict[tuple[str, int], Codec] = {}
        for f, m in zip(bus.frames, db.messages):
            self.codecs[f.bus, f.id] = Codec(f, m, _message(f, True) if f.long_dlc else None)

    def codec(self, bus: str, can_id: int) -> Codec | None:
        return self.codecs.get((bus, can_id))

    def decode(self, bus: str, can_id: int, data: bytes, extended: bool = False) -> tuple[BusFrame, dict[str, float]]:
        """(frame, {signal name: physical value}); raises FrameError for an unknown ID, a wrong length or reserved
        bits set."""
        c = None if extended else self.codecs.get((bus, can_id))
        if c is None:
            raise FrameError(FrameProblem.UNKNOWN_ID, can_id, len(data))
        msg = c.message_for(len(data))
        if msg is None:
            raise FrameError(FrameProblem.BAD_LENGTH, can_id, len(data))
        values = msg.decode(bytes(data), decode_choices=False, scaling=True)
        if any(values[s.name] for s in c.frame.signals if s.target == "reserved" and s.name in values):
            raise FrameError(FrameProblem.RESERVED_BITS, can_id, len(data))
        return c.frame, values

    def encode(self, bus: str, can_id: int, values: dict[str, float], long: bool = False) -> bytes:
        """The payload of a frame from its signals' physical values (absent ones are 0), cantools' rounding (half to
        even); `long`: the long form."""
        c = self.codecs[bus, can_id]
        msg = c.long if long else c.message
        if msg is None:
            raise ValueError(f"frame {c.frame.name} has no long form")
        full = {s.name: 0 for s in msg.signals} | {k: v for k, v in values.items() if k in {s.name for s in msg.signals}}
        return bytes(msg.encode(full, scaling=True, strict=False))


@lru_cache(maxsize=8)
def _codec_cached(key: int, bus: BusDescription) -> BusCodec:
    return BusCodec(bus)


def codec_of(bus: BusDescription | None, robot: str) -> BusCodec:
    """The codec of a configuration's bus; DataError when the configuration describes none."""
    if bus is None:
        raise DataError(f"robot configuration {robot} describes no CAN bus (a 'bus' or 'can' section)")
    return _codec_cached(id(bus), bus)
