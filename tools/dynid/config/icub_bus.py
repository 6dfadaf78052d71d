"""The iCub CAN-era protocol (docs/design.md §5) as a bus description: the `can:` section expanded into `bus:` terms.

`icub_bus(can, sensors)` gives exactly the frames the iCub boards send (and firmware_like's emulators):
- IDs `class << 8 | address << 4 | type`; every frame named after its message and board address, as the DBC has
  always named them (`MC_POSITION_2`; with the bus too, `MC_POSITION_can1_2`, where one address is used on two
  buses);
- strain boards (class 3): force half 0xA, torque half 0xB, three little-endian uint16 in offset binary, physical
  value (raw − 0x8000) · FS / 32768 (scale FS/32768, offset −FS); a pair, the first listed board's torque half
  clocks the sample; byte 6 carries the saturation flags (bit i: channel i clamped) in the 7-byte variant: the
  frame's long form, or its only form with `saturation_flags: true`;
- motor-control boards (class 1): POSITION, two int32 encoder ticks (rad = (ticks / ticks_per_degree − zero_deg)
  · π/180), PID_VAL two int16 PWM counts (duty = count / pwm_full_scale), STATUS every 10 ms with per-axis fault bits
  (over-current, over-temperature, encoder, external, PWM limit), the restart flag, TX overrun and a sequence;
- skin boards (class 4): TAXELS, a uint16 bitmask of taxel groups, non-zero = contact on the board's patch.
Sent per sample k at t_k − 300 µs (POSITION, PID_VAL), t_k − 250 µs (STATUS), t_k − 200 µs (skin), t_k − 100 µs
and t_k (the clocking strain pair; further strain boards in between), the order dynid.io.candump and the boards
have always used.
"""

from __future__ import annotations

import math
from typing import Any

CLASS_MC, CLASS_STRAIN, CLASS_SKIN = 1, 3, 4
MC_POSITION, MC_PID_VAL, MC_STATUS = 1, 2, 3
STRAIN_FORCE, STRAIN_TORQUE = 0xA, 0xB
SKIN_TAXELS = 0
RATE_HZ = 1000.0  # the boards' period
STATUS_PERIOD_MS = 10.0
STRAIN_COUNTS = 32768
FAULTS = ("OverCurrent", "OverTemp", "EncoderFault", "ExternalFault", "PwmLimit")


def make_id(cls: int, address: int, typ: int) -> int:
    """ID = class << 8 | source address << 4 | type."""
    if not (0 <= cls <= 7 and 0 <= address <= 15 and 0 <= typ <= 15):
        raise ValueError(f"CAN ID field out of range: class {cls}, address {address}, type {typ}")
    return cls << 8 | address << 4 | typ


def split_id(can_id: int) -> tuple[int, int, int]:
    """(class, source address, type) of an 11-bit ID."""
    return (can_id >> 8) & 0x7, (can_id >> 4) & 0xF, can_id & 0xF


def _node(kind: str, bus: str, address: int) -> str:
    return f"icub_{kind}_{''.join(c if c.isalnum() else '_' for c in bus)}_{address}"


def _sig(name: str, start: int, length: int, target: str = "", kind: str = "unsigned", scale: float = 1.0,
         offset: float = 0.0, unit: str = "") -> dict[str, Any]:
    s = {"name": name, "start": start, "length": length, "type": kind, "scale": scale, "offset": offset}
    if target:
        s["target"] = target
    if unit:
        s["unit"] = unit
    return s


def icub_bus(can: dict[str, Any], sensors: tuple[str, ...]) -> dict[str, Any]:
    """The `bus:` mapping (docs/formats.md) of a validated `can:` section."""
    frames: list[dict[str, Any]] = []
    pairs: list[list[str]] = []
    addresses: dict[tuple[int, int], int] = {}
    for kind, boards in ((CLASS_STRAIN, can.get("strain", [])), (CLASS_MC, can["motor_control"]),
                         (CLASS_SKIN, can.get("skin", []))):
        for b in boards:
            addresses[kind, b["address"]] = addresses.get((kind, b["address"]), 0) + 1

    def name(base: str, cls: int, b: dict[str, Any]) -> str:
        shared = addresses[cls, b["address"]] > 1  # one address on two buses: the bus in the name too
        return f"{base}_{b['bus']}_{b['address']}" if shared else f"{base}_{b['address']}"

    deg = math.pi / 180.0
    for b in can["motor_control"]:
        node, axes = _node("mc", b["bus"], b["address"]), b["axes"]
        pos, pid, status = [], [], []
        for slot in (0, 1):
            ax = axes[slot] if slot < len(axes) else None
            if ax is not None:
                tpd, zero = float(ax["ticks_per_degree"]), float(ax.get("zero_deg", 0.0))
                pos.append(_sig(f"Axis{slot}Position", 32 * slot, 32, f"q.{ax['joint']}", "signed", deg / tpd,
                                -zero * deg + 0.0, "rad"))  # + 0.0: no negative zero in the DBC
            else:
                pos.append(_sig(f"Axis{slot}Position", 32 * slot, 32, "", "signed", unit="tick"))
            motor = ax.get("motor") if ax is not None else None
            if motor:
                pid.append(_sig(f"Axis{slot}Pwm", 16 * slot, 16, f"pwm.{motor}", "signed",
                                1.0 / float(b["pwm_full_scale"]), 0.0, "duty"))
            else:
                pid.append(_sig(f"Axis{slot}Pwm", 16 * slot, 16, "", "signed", unit="count"))
            for bit, fault in enumerate(FAULTS):
                target = "fault"
                if fault == "EncoderFault" and ax is not None:
                    target = f"fault.q.{ax['joint']}"  # the board raises it when the angle does not fit int32 ticks
                elif fault == "PwmLimit" and motor:
                    target = f"fault.pwm.{motor}"  # ... and this one when the duty clamps at the full scale
                status.append(_sig(f"Axis{slot}{fault}", 8 * slot + bit, 1, target))
            status.append(_sig(f"Axis{slot}Reserved", 8 * slot + 5, 3, "reserved"))
        status += [_sig("BoardRestarted", 16, 1, "restart"), _sig("BoardTxOverrun", 17, 1),
                   _sig("BoardReserved", 18, 6, "reserved"), _sig("Sequence", 24, 8, "seq")]
        common = {"bus": b["bus"], "node": node}
        frames.append({"name": name("MC_POSITION", CLASS_MC, b), "id": make_id(CLASS_MC, b["address"], MC_POSITION),
                       "dlc": 8, "offset_us": -300, "signals": pos, **common})
        frames.append({"name": name("MC_PID_VAL", CLASS_MC, b), "id": make_id(CLASS_MC, b["address"], MC_PID_VAL),
                       "dlc": 4, "offset_us": -300, "signals": pid, **common})
        frames.append({"name": name("MC_STATUS", CLASS_MC, b), "id": make_id(CLASS_MC, b["address"], MC_STATUS),
                       "dlc": 4, "offset_us": -250, "period_ms": STATUS_PERIOD_MS, "signals": status, **common})
    patches = []
    for b in can.get("skin", []):
        patches.append({"name": b["patch"], "sides": {s: b["side"] for s in sensors}})
        frames.append({"name": name("SKIN_TAXELS", CLASS_SKIN, b), "bus": b["bus"],
                       "id": make_id(CLASS_SKIN, b["address"], SKIN_TAXELS), "dlc": 2, "offset_us": -200,
                       "node": _node("skin", b["bus"], b["address"]),
                       "signals": [_sig("Taxels", 0, 16, f"skin.{b['patch']}")]})
    for k, b in enumerate(can.get("strain", [])):
        fs = [float(x) for x in b["full_scale"]]
        flags = bool(b.get("saturation_flags", False))
        # The first board clocks the sample: its halves at t − 100 µs and t; the others' pairs before its torque half.
        times = (-100, 0) if k == 0 else (-100 + 15 * k, -95 + 15 * k)
        names = []
        for half, (base, typ, chans) in enumerate((("STRAIN_FORCE", STRAIN_FORCE, ("fx", "fy", "fz")),
                                                   ("STRAIN_TORQUE", STRAIN_TORQUE, ("tx", "ty", "tz")))):
            sig = [_sig(c.title(), 16 * i, 16, f"ft.{b['sensor']}.{c}", "unsigned", fs[3 * half + i] / STRAIN_COUNTS,
                        -fs[3 * half + i], "N" if half == 0 else "Nm") for i, c in enumerate(chans)]
            sig += [_sig(f"Sat{c.title()}", 48 + i, 1, f"saturated.ft.{b['sensor']}.{c}") for i, c in enumerate(chans)]
            sig.append(_sig("SatReserved", 51, 5, "reserved"))
            frame = {"name": name(base, CLASS_STRAIN, b), "bus": b["bus"], "id": make_id(CLASS_STRAIN, b["address"], typ),
                     "dlc": 7 if flags else 6, "offset_us": times[half], "node": _node("strain", b["bus"], b["address"]),
                     "signals": sig}
            if not flags:
                frame["long_dlc"] = 7  # the saturation variant, accepted beside the nominal 6 bytes
            frames.append(frame)
            names.append(frame["name"])
        pairs.append(names)
    return {"buses": list(can["buses"]), "rate": RATE_HZ, "stale_ms": 5.0, "pair_us": 500,
            "clock": pairs[0][1], "pairs": pairs, "patches": patches, "frames": frames}
