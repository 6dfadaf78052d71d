"""The robot's CAN bus described as data: which frame carries which signal, and how a sample is clocked.

A robot configuration gives it in its `bus:` section (docs/formats.md, "Bus description"), or in the iCub
protocol's own terms (`can:`, expanded by `dynid.config.icub_bus`). Everything downstream reads this one
description: the DBC (`dynid export --dbc`, written through cantools), `dynid import` of a candump log and its
writer (`dynid.io.candump`, through cantools), the monitor's compiled table (`dynid.export.monitor_config`) and the
player (`dynid play`, firmware_like's `boards`). A robot whose bus speaks another protocol needs a configuration,
never code.

Per frame: its name (the DBC message name), bus, 11-bit ID, DLC, node (the board that sends it: a restart drops
that node's values), period (absent: every sample), the time it is sent at relative to its sample, and its
signals. Per signal: start bit and length as a DBC has them (little-endian: the least significant bit; big-endian,
Motorola: the most significant bit in the DBC's sawtooth numbering), byte order, `unsigned`, `signed` or `float`
(IEEE, 32 or 64 bits), scale and offset (physical = raw · scale + offset) and what it is, its target:

    q.<joint> dq.<joint>            rad or m, rad/s or m/s
    pwm.<motor> current.<motor>     duty, A
    tau.<joint>                     Nm
    ft.<sensor>.<fx|fy|fz|tx|ty|tz> N, Nm
    skin.<patch>                    non-zero: contact on that patch (ground truth)
    saturated[.<target>]            non-zero: the frame's values were clamped (a saturated sample is stale);
                                    with a target, the player sets it when that target's value clamps
    fault[.<target>]                non-zero: a board fault (counted); the player sets it when the target clamps
    restart                         non-zero: the node restarted (its values are dropped until fresh ones come)
    seq                             the node's sequence counter (+1 per frame, wraps; back to 0: a restart)
    reserved                        must be 0: a frame with it set is refused (counted with wrong lengths)
    (none)                          carried on the bus, read by nobody

Signals that lie beyond `dlc` bytes are optional: they exist only in the frame's long form (`long_dlc`, e.g. the
iCub strain board's 7-byte saturation variant), which readers accept beside the nominal length.
"""

from __future__ import annotations

import difflib

import math
import re
from dataclasses import dataclass, field
from typing import Any

from ..errors import ConfigError
from .fields import Fields

FT_COMPONENTS = ("fx", "fy", "fz", "tx", "ty", "tz")
SIGNAL_TYPES = ("unsigned", "signed", "float")
BYTE_ORDERS = ("little", "big")
VALUE_FAMILIES = ("q", "dq", "pwm", "current", "tau", "ft")
HEALTH_TARGETS = ("saturated", "fault", "restart", "seq", "reserved")
# The monitor's limits on the clock settings (rt_monitor/include/rt_monitor/assembler.hpp): refused beyond them.
STALE_MS_RANGE = (0.1, 1000.0)
PAIR_US_RANGE = (1, 10000)
DEFAULT_BITRATE = 1_000_000
LOAD_LIMIT = 0.70  # every bus stays under 70 % (worst-case bit stuffing), docs/design.md §5
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,63}$")  # a DBC identifier
_BUS = re.compile(r"^[A-Za-z0-9_.:-]{1,15}$")  # a network interface name (IFNAMSIZ - 1)


@dataclass(frozen=True)
class BusSignal:
    name: str
    start: int  # DBC start bit: LSB for little-endian, MSB (sawtooth numbering) for big-endian
    length: int
    byte_order: str  # little | big
    type: str  # unsigned | signed | float
    scale: float
    offset: float
    target: str  # "" when read by nobody
    unit: str = ""

    @property
    def is_signed(self) -> bool:
        return self.type == "signed"

    @property
    def raw_range(self) -> tuple[float, float]:
        """The raw values the signal can hold (floats: ± the largest finite value)."""
        if self.type == "float":
            return (-3.4028234663852886e38, 3.4028234663852886e38) if self.length == 32 else (-math.inf, math.inf)
        if self.type == "signed":
            return -(2.0 ** (self.length - 1)), 2.0 ** (self.length - 1) - 1
        return 0.0, 2.0 ** self.length - 1

    @property
    def physical_range(self) -> tuple[float, float]:
        lo, hi = (v * self.scale + self.offset for v in self.raw_range)
        return (lo, hi) if lo <= hi else (hi, lo)

    def bits(self) -> set[int]:
        """The payload bits the signal occupies, numbered byte · 8 + bit (bit 0 the least significant)."""
        if self.byte_order == "little":
            return set(range(self.start, self.start + self.length))
        out, pos = set(), self.start
        for _ in range(self.length):
            out.add(pos)
            pos = pos - 1 if pos % 8 else pos + 15  # Motorola: down within a byte, then the next byte's bit 7
        return out

    @property
    def end_byte(self) -> int:
        """1 + the last payload byte the signal touches."""
        return max(self.bits()) // 8 + 1


@dataclass(frozen=True)
class BusFrame:
    name: str
    bus: str
    id: int
    dlc: int
    signals: tuple[BusSignal, ...]
    node: str
    period_ms: float | None = None  # None: sent with every sample
    offset_us: int = 0  # when, relative to its sample's time, it is sent (<= 0)
    long_dlc: int = 0  # the long form's DLC (its optional signals), 0: none

    def signal(self, target: str) -> BusSignal | None:
        return next((s for s in self.signals if s.target == target), None)

    def every(self, sample_period_s: float) -> int:
        """Samples between two frames at this sample period (1: every sample)."""
        if self.period_ms is None:
            return 1
        return max(1, round(self.period_ms * 1e-3 / sample_period_s))


@dataclass(frozen=True)
class Patch:
    name: str
    sides: tuple[tuple[str, str], ...]  # (sensor, distal|proximal) for each F/T sensor


NOMINAL_TOLERANCE = 0.05  # a run's median step within 5 % of the bus's period is taken as that period


@dataclass(frozen=True)
class BusDescription:
    buses: tuple[str, ...]
    rate: float  # Hz: the rate the nodes send at (the bus load is computed at it)
    frames: tuple[BusFrame, ...]
    clock: str  # the frame that completes a sample
    pairs: tuple[tuple[str, str], ...] = ()  # frames committed together: the second within pair_us of the first
    patches: tuple[Patch, ...] = ()
    stale_ms: float = 5.0
    pair_us: int = 500
    bitrate: int = DEFAULT_BITRATE
    origin: str = "bus"  # "bus" (the configuration's own section) or "can" (the iCub protocol, expanded)
    by_name: dict[str, BusFrame] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        self.by_name.update({f.name: f for f in self.frames})

    def frame(self, name: str) -> BusFrame:
        return self.by_name[name]

    def targets(self) -> dict[str, tuple[BusFrame, BusSignal]]:
        """Every value and skin target, with the frame and signal carrying it."""
        return {s.target: (f, s) for f in self.frames for s in f.signals if is_value_target(s.target)
                or s.target.startswith("skin.")}

    def pair_of(self, frame: str) -> tuple[str, str] | None:
        return next((p for p in self.pairs if frame in p), None)

    def nominal_period(self, median_step: float) -> float:
        """The period samples come at on this bus: its `rate`'s where a recorded run's median step agrees with it to
        NOMINAL_TOLERANCE (a jittered log's median is off by its stamps' rounding: the Panda's 0.97-1.00 ms by window
        for its 1 kHz), else the run's median step."""
        period = 1.0 / self.rate
        return period if abs(median_step / period - 1.0) <= NOMINAL_TOLERANCE else median_step

    def send_order(self) -> list[BusFrame]:
        """The frames of one sample in the order they are sent: by time, then as listed."""
        return sorted(self.frames, key=lambda f: f.offset_us)  # stable: equal times keep the list's order

    def load(self) -> dict[str, float]:
        """Each bus's load at `rate`, worst-case bit stuffing (an upper bound), as a fraction of its bitrate."""
        bits = {b: 0.0 for b in self.buses}
        for f in self.frames:
            per_s = self.rate / f.every(1.0 / self.rate)
            bits[f.bus] += frame_bits_worst(f.dlc) * per_s
        return {b: v / self.bitrate for b, v in bits.items()}


def frame_bits_worst(dlc: int) -> int:
    """Bits on the wire of a standard-ID frame with worst-case stuffing and the interframe space (firmware_like's
    board_frame_bits_worst: 135 bits for 8 bytes)."""
    return 34 + 8 * dlc + 13 + (34 + 8 * dlc - 1) // 4


def is_value_target(target: str) -> bool:
    return target.split(".", 1)[0] in VALUE_FAMILIES


def _value_target_ok(target: str, joints: tuple[str, ...], motors: dict[str, str], sensors: tuple[str, ...]) -> str:
    """'' if `target` names a value of this robot, else what is wrong with it."""
    family, _, rest = target.partition(".")
    if family in ("q", "dq", "tau"):
        if rest in joints:
            return ""
        # the bus may be right and 'joints' misspelt: a walkthrough's typo there was blamed on the bus alone
        near = difflib.get_close_matches(rest, joints, n=1)
        return f"names joint '{rest}', which is not in 'joints'" + (
            f" ('joints' has '{near[0]}': is one of the two misspelt?)" if near else "")
    if family in ("pwm", "current"):
        if rest not in motors:
            return f"names motor '{rest}', which is not under 'motors'"
        return "" if motors[rest] == family else f"names motor '{rest}', whose input is {motors[rest]}, not {family}"
    sensor, _, component = rest.rpartition(".")
    if sensor not in sensors:
        return f"names F/T sensor '{sensor}', which is not in 'ft_sensors'"
    return "" if component in FT_COMPONENTS else f"names component '{component}' (one of {', '.join(FT_COMPONENTS)})"


def parse_bus(f: Fields, joints: tuple[str, ...], motors: dict[str, str], sensors: tuple[str, ...],
              origin: str = "bus", torques: tuple[str, ...] = ()) -> BusDescription:
    """Validate a `bus:` mapping (fields as docs/formats.md has them); `motors` maps each motor to its input kind,
    `torques` names the joints a torque sensor drives the model from."""
    f.only("buses", "bitrate", "rate", "stale_ms", "pair_us", "clock", "pairs", "patches", "frames")
    buses = f.strings("buses")
    if not buses:
        raise f.fail("buses", "must list at least one bus")
    for b in buses:
        if not _BUS.match(b):
            raise f.fail("buses", f"names '{b}', which is no interface name (letters, digits, _ . : -, at most 15)")
    rate = f.number("rate", positive=True)
    bitrate = f.number("bitrate", DEFAULT_BITRATE, positive=True)
    if bitrate != int(bitrate) or not 10_000 <= bitrate <= 1_000_000:
        raise f.fail("bitrate", f"must be a classic-CAN bit rate in bit/s, 10000 to 1000000, got {bitrate:g}")
    stale_ms = f.number("stale_ms", 5.0)
    if not STALE_MS_RANGE[0] <= stale_ms <= STALE_MS_RANGE[1]:
        raise f.fail("stale_ms", f"must be {STALE_MS_RANGE[0]:g} to {STALE_MS_RANGE[1]:g} ms, got {stale_ms:g}")
    pair_us = f.number("pair_us", 500)
    if pair_us != int(pair_us) or not PAIR_US_RANGE[0] <= pair_us <= PAIR_US_RANGE[1]:
        raise f.fail("pair_us", f"must be a whole number of µs, {PAIR_US_RANGE[0]} to {PAIR_US_RANGE[1]}, got {pair_us:g}")

    patches = []
    for p in f.items("patches", []):
        p.only("name", "sides")
        name = p.string("name")
        if not _NAME.match(name):
            raise p.fail("name", f"must be an identifier (letters, digits, _), got '{name}'")
        s = p.sub("sides", {}).only(*sensors)
        sides = []
        for sensor in sensors:
            side = s.string(sensor)
            if side not in ("distal", "proximal"):
                raise s.fail(sensor, f"must be 'distal' or 'proximal' of the sensor, got '{side}'")
            sides.append((sensor, side))
        patches.append(Patch(name, tuple(sides)))
    patch_names = [p.name for p in patches]
    if len(set(patch_names)) != len(patch_names):
        raise f.fail("patches", "names a patch twice")

    frames: list[BusFrame] = []
    seen_ids: dict[tuple[str, int], str] = {}
    seen_targets: dict[str, str] = {}
    for fr in f.items("frames"):
        frames.append(_frame(fr, buses, rate, joints, motors, sensors, patch_names, seen_ids, seen_targets))
    names = [fr.name for fr in frames]
    if not frames:
        raise f.fail("frames", "must list at least one frame")
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup:
        raise f.fail("frames", f"names frame '{dup}' twice (a DBC's message names are unique)")
    for target in seen_targets:  # a health target's own target must be a value the bus carries
        base, _, of = target.partition(".")
        if base in ("saturated", "fault") and of and of not in seen_targets:
            raise f.fail("frames", f"has a '{target}' signal, but no signal carries '{of}'")
    # What every reader needs (dynid import, play, the monitor): a bus without it was exported and played (the column
    # left out) and refused only at the monitor's start
    needed = ([f"q.{j}" for j in joints] + [f"{kind}.{m}" for m, kind in motors.items() if kind in ("pwm", "current")]
              + [f"tau.{j}" for j in torques] + [f"ft.{s}.{c}" for s in sensors for c in FT_COMPONENTS])
    missing = [t for t in needed if t not in seen_targets]
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise f.fail("frames", f"carries no signal with target '{missing[0]}'{more}: every joint's position, motor input "
                     "and F/T component must be on the bus")
    for p in patch_names:
        if f"skin.{p}" not in seen_targets:
            raise f.fail("patches", f"lists patch '{p}', which no signal carries (target skin.{p})")

    by_name = {fr.name: fr for fr in frames}
    clock = f.string("clock")
    if clock not in by_name:
        raise f.fail("clock", f"names frame '{clock}', which is not in 'frames'")
    pairs = []
    paired: set[str] = set()
    raw_pairs = f.raw("pairs", [])
    if not isinstance(raw_pairs, list):
        raise f.fail("pairs", "must be a list of [FIRST, SECOND] frame names")
    for i, pair in enumerate(raw_pairs):
        where = f"pairs[{i}]"
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
            raise f.fail(where, f"must be [FIRST, SECOND], two frame names, got {pair!r}")
        first, second = pair
        for x in pair:
            if x not in by_name:
                raise f.fail(where, f"names frame '{x}', which is not in 'frames'")
            if x in paired:
                raise f.fail(where, f"names frame '{x}', which is in another pair already")
        if first == second:
            raise f.fail(where, "pairs a frame with itself")
        a, b = by_name[first], by_name[second]
        if not a.offset_us < b.offset_us or b.offset_us - a.offset_us > pair_us:
            raise f.fail(where, f"sends '{second}' {b.offset_us - a.offset_us} µs after '{first}': the second "
                         f"half follows the first within pair_us ({int(pair_us)} µs)")
        if a.period_ms != b.period_ms:
            raise f.fail(where, "pairs frames of different periods")
        paired.update(pair)
        pairs.append((first, second))
    if clock in paired and next(p for p in pairs if clock in p)[1] != clock:
        raise f.fail("clock", f"names '{clock}', the first half of a pair: the second half completes a sample")
    c = by_name[clock]
    if c.period_ms is not None:
        raise f.fail("clock", f"names '{clock}', which is not sent with every sample (period_ms)")
    late = next((fr for fr in frames if fr.name != clock and fr.offset_us >= c.offset_us), None)
    if late:
        raise f.fail("clock", f"names '{clock}', but frame '{late.name}' is sent at or after it (offset_us): the "
                     "frame that completes a sample is its last")
    for fr in frames:
        if fr.offset_us <= c.offset_us - 1e6 / rate:
            raise f.fail("frames", f"sends '{fr.name}' {c.offset_us - fr.offset_us} µs before the clock frame: a "
                         f"sample's frames fit in one period ({1e6 / rate:g} µs at {rate:g} Hz)")
    return BusDescription(buses=buses, rate=rate, frames=tuple(frames), clock=clock, pairs=tuple(pairs),
                          patches=tuple(patches), stale_ms=stale_ms, pair_us=int(pair_us), bitrate=int(bitrate),
                          origin=origin)


def _frame(fr: Fields, buses: tuple[str, ...], rate: float, joints: tuple[str, ...], motors: dict[str, str],
           sensors: tuple[str, ...], patches: list[str], seen_ids: dict[tuple[str, int], str],
           seen_targets: dict[str, str]) -> BusFrame:
    fr.only("name", "bus", "id", "dlc", "long_dlc", "node", "period_ms", "offset_us", "signals")
    name = fr.string("name")
    if not _NAME.match(name):
        raise fr.fail("name", f"must be an identifier of at most 64 letters, digits or _, got '{name}'")
    bus = fr.string("bus")
    if bus not in buses:
        raise fr.fail("bus", f"names '{bus}', which is not in 'buses'")
    can_id = fr.raw("id")
    if isinstance(can_id, bool) or not isinstance(can_id, int) or not 0 <= can_id <= 0x7FF:
        raise fr.fail("id", f"must be an 11-bit standard CAN ID, 0 to 0x7FF, got {can_id!r}")
    if (bus, can_id) in seen_ids:
        raise fr.fail("id", f"0x{can_id:03X} is frame '{seen_ids[bus, can_id]}''s on {bus} already")
    seen_ids[bus, can_id] = name

    def small_int(key: str, lo: int, hi: int, default: Any = ...) -> int:
        v = fr.raw(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise fr.fail(key, f"must be an integer {lo} to {hi}, got {v!r}")
        return v

    dlc = small_int("dlc", 0, 8)
    long_dlc = small_int("long_dlc", dlc + 1, 8) if fr.has("long_dlc") else 0
    node = fr.string("node", name)
    if not _NAME.match(node):
        raise fr.fail("node", f"must be an identifier (letters, digits, _), got '{node}'")
    period = fr.number("period_ms", None)
    if period is not None and not 1e3 / rate <= period <= 60_000:
        raise fr.fail("period_ms", f"must be one sample period ({1e3 / rate:g} ms) to 60000 ms, got {period:g}")
    offset = fr.number("offset_us", 0.0)
    if offset != int(offset) or offset > 0:
        raise fr.fail("offset_us", f"must be a whole number of µs, 0 or below (before the sample's time), got {offset:g}")

    signals: list[BusSignal] = []
    used: dict[int, str] = {}
    frame_health: set[str] = set()
    for sg in fr.items("signals", []):
        s = _signal(sg, joints, motors, sensors, patches)
        if s.name in {x.name for x in signals}:
            raise sg.fail("name", f"'{s.name}' is a second signal of that name in frame '{name}'")
        bits = s.bits()
        if max(bits) >= 8 * (long_dlc or dlc) or min(bits) < 0:
            raise sg.fail("start", f"puts '{s.name}' outside the frame's {long_dlc or dlc} bytes")
        clash = next((used[b] for b in sorted(bits) if b in used), None)
        if clash:
            raise sg.fail("start", f"overlaps signal '{clash}' in frame '{name}'")
        used.update(dict.fromkeys(bits, s.name))
        _zero_in_middle_half(sg, s)
        if s.target:
            if s.target in ("restart", "seq"):
                if s.target in frame_health:
                    raise sg.fail("target", f"'{s.target}' is given twice in frame '{name}'")
                frame_health.add(s.target)
            elif s.target != "reserved" and s.target != "fault" and s.target != "saturated":
                if s.target in seen_targets:
                    raise sg.fail("target", f"'{s.target}' is carried by '{seen_targets[s.target]}' already")
                seen_targets[s.target] = f"{name}.{s.name}"
        signals.append(s)
    if long_dlc and not any(s.end_byte > dlc for s in signals):
        raise fr.fail("long_dlc", f"is given, but no signal of '{name}' lies beyond its {dlc} bytes")
    if not signals:
        raise fr.fail("signals", f"must list the signals of frame '{name}'")
    return BusFrame(name=name, bus=bus, id=can_id, dlc=dlc, signals=tuple(signals), node=node, period_ms=period,
                    offset_us=int(offset), long_dlc=long_dlc)


def _signal(sg: Fields, joints: tuple[str, ...], motors: dict[str, str], sensors: tuple[str, ...],
            patches: list[str]) -> BusSignal:
    sg.only("name", "start", "length", "byte_order", "type", "scale", "offset", "target", "unit")
    name = sg.string("name")
    if not _NAME.match(name):
        raise sg.fail("name", f"must be an identifier (letters, digits, _), got '{name}'")

    def integer(key: str, lo: int, hi: int) -> int:
        v = sg.raw(key)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise sg.fail(key, f"must be an integer {lo} to {hi}, got {v!r}")
        return v

    start, length = integer("start", 0, 63), integer("length", 1, 64)
    order = sg.string("byte_order", "little")
    if order not in BYTE_ORDERS:
        raise sg.fail("byte_order", f"must be little (Intel) or big (Motorola), got '{order}'")
    kind = sg.string("type", "unsigned")
    if kind not in SIGNAL_TYPES:
        raise sg.fail("type", f"must be one of {', '.join(SIGNAL_TYPES)}, got '{kind}'")
    if kind == "float" and length not in (32, 64):
        raise sg.fail("length", f"must be 32 or 64 for an IEEE float, got {length}")
    scale, offset = sg.number("scale", 1.0), sg.number("offset", 0.0)
    if scale == 0:
        raise sg.fail("scale", "must not be 0")
    target = sg.string("target", "") if sg.raw("target", "") != "" else ""
    base, _, rest = target.partition(".")
    if not target or target in ("restart", "seq", "reserved", "fault", "saturated"):
        pass
    elif base in ("saturated", "fault") and is_value_target(rest):
        if (why := _value_target_ok(rest, joints, motors, sensors)):
            raise sg.fail("target", f"'{target}' {why}")
    elif is_value_target(target):
        if (why := _value_target_ok(target, joints, motors, sensors)):
            raise sg.fail("target", f"'{target}' {why}")
    elif base == "skin":
        if rest not in patches:
            raise sg.fail("target", f"'{target}' names patch '{rest}', which is not in 'patches'")
    else:
        raise sg.fail("target", f"'{target}' is no target: q.J, dq.J, pwm.M, current.M, tau.J, ft.S.C, skin.P, "
                      "saturated[.T], fault[.T], restart, seq or reserved")
    if target in ("restart", "seq", "reserved") or base in ("saturated", "fault", "skin"):
        if kind == "float" or scale != 1 or offset != 0:
            raise sg.fail("target", f"'{target}' is a count or flag: an integer with scale 1 and offset 0")
    if target == "seq" and not 2 <= length <= 32:
        raise sg.fail("length", f"must be 2 to 32 bits for a sequence counter, got {length}")
    unit = sg.raw("unit", "")
    if not isinstance(unit, str) or '"' in unit:
        raise sg.fail("unit", f"must be a string without quotes, got {unit!r}")
    # A value's unit is the project's: the scale and offset convert the raw value into it, and the DBC carries it (a
    # walkthrough's `unit: deg` on a position in rad went into the DBC as written)
    allowed = VALUE_UNITS.get(base, ())
    if unit and allowed and unit not in allowed:
        raise sg.fail("unit", f"'{unit}' is not a unit of {target}: the bus's values are in the project's units, "
                      f"the scale converting to them ({' or '.join(allowed)})")
    return BusSignal(name, start, length, order, kind, scale, offset, target, unit or _default_unit(target))


def _zero_in_middle_half(sg: Fields, s: BusSignal) -> None:
    """A sensor that reads both ways (every value but a position) holds zero in the middle half of its decoded range
    (rt_monitor's rule). Checked once the signal is known to fit its frame: that is the first thing wrong with it."""
    if not is_value_target(s.target) or s.target.startswith("q.") or s.type == "float":
        return
    lo, hi = s.physical_range
    quarter = (hi - lo) / 4
    if not lo + quarter <= 0 <= hi - quarter:
        raise sg.fail("offset", f"{s.offset:g} puts '{s.target}' at {lo:g} to {hi:g}: a sensor that reads both ways "
                      "holds zero in the middle half of its range")


# The project's units of each value family (docs/design.md §4): what a value target's signal decodes to
VALUE_UNITS = {"q": ("rad", "m"), "dq": ("rad/s", "m/s"), "pwm": ("duty", ""), "current": ("A",), "tau": ("Nm",),
               "ft": ("N", "Nm")}


def _default_unit(target: str) -> str:
    family = target.split(".", 1)[0]
    if family == "ft":
        return "N" if target.rsplit(".", 1)[1][0] == "f" else "Nm"
    return {"q": "rad", "dq": "rad/s", "pwm": "duty", "current": "A", "tau": "Nm"}.get(family, "")
