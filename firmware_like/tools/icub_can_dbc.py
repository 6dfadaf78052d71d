#!/usr/bin/env python3
"""icub_can_dbc.py - the iCub CAN protocol's DBC for the boards of one robot.

    python3 firmware_like/tools/icub_can_dbc.py MONITOR.conf [--out FILE] [--names same|addressed]

A DBC names messages by their full 11-bit ID, and the protocol's IDs carry the board address
(ID = class<<8 | address<<4 | type), so a DBC decodes a bus only if it lists every board address on it. The
boards, their buses and addresses come from an rt_monitor configuration (rt_monitor/README.md, "Configuration";
dynid writes it from the robot configuration); for each board, one message per frame it sends:
  strain board          STRAIN_FORCE (type 0xA), STRAIN_TORQUE (0xB)
  motor-control board   MC_POSITION (1), MC_PID_VAL (2), MC_STATUS (3)  (every board sends all three)
  skin board            SKIN_TAXELS (0)
The layout of a message is the same at every address; its name is the protocol's with the board address
appended (MC_POSITION_2; --names addressed, the default), so that every name is unique, as a DBC's must be
(cantools warns on every load otherwise). --names same writes the protocol's name at every address, for a
decoder that wants one name per (class, type); dynid.io.can_protocol reads both.

Strain messages are 6 bytes, the board's nominal frame. The saturation variant (7 bytes: byte 6 holds the
flags) is documented by the message comment and the SatFlagsByte / SatFlagsMask attributes, not by signals:
`cantools decode` checks lengths exactly, so one message cannot decode both lengths there. A log of the 7-byte
variant decodes with `cantools decode --no-strict` (or cantools' Message.decode, whose allow_excess is on by
default) to the same counts, without byte 6.

firmware_like/icub_can.dbc is this program's output for rt_monitor/config/icub_right_arm.conf (the default arm;
tools/tests/test_dbc_decode.py checks that it is current). Standard library only. Bad input: exit 2, one line.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

STRAIN, MC, SKIN = 3, 1, 4
NODE = {STRAIN: "STRAIN", MC: "MC", SKIN: "SKIN"}


class ConfError(Exception):
    pass


def read_boards(path: Path) -> tuple[str, dict[tuple[int, int], tuple[list[str], list[str]]]]:
    """(robot name, {(class, address): (buses, what it serves)}) of an rt_monitor configuration (keys in any
    order). What a board serves, for the message comments: its axes' joints, or its skin patch."""
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise ConfError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    robot, buses, found = "", None, []
    for n, raw in enumerate(lines, 1):
        tok = raw.split("#", 1)[0].split()
        if not tok:
            continue
        if tok[0] == "robot" and len(tok) == 2:
            robot = tok[1]
        elif tok[0] == "buses":
            if buses is not None:
                raise ConfError(f"{path}:{n}: a second 'buses' line")
            buses = tok[1:]
        elif tok[0] in ("strain", "axis", "pwm", "skin"):
            if len(tok) < 3:
                raise ConfError(f"{path}:{n}: a '{tok[0]}' line needs a bus and a board address: {raw}")
            cls = {"strain": STRAIN, "skin": SKIN}.get(tok[0], MC)
            what = (f"axis {tok[3]} {tok[4]}" if tok[0] == "axis" and len(tok) > 4 else
                    f"patch {tok[3]}" if tok[0] == "skin" and len(tok) > 3 else "")
            found.append((n, tok[1], cls, tok[2], what))
    if not buses:
        raise ConfError(f"{path}: no 'buses' line")
    boards: dict[tuple[int, int], tuple[list[str], list[str]]] = {}
    for n, bus, cls, text, what in found:
        if bus not in buses:
            raise ConfError(f"{path}:{n}: bus '{bus}' is not in the 'buses' line ({' '.join(buses)})")
        if not (text.isascii() and text.isdigit() and 0 <= int(text) <= 15):
            raise ConfError(f"{path}:{n}: board address must be 0..15, got '{text}'")
        on, serves = boards.setdefault((cls, int(text)), ([], []))
        on += [bus] if bus not in on else []
        serves += [what] if what and what not in serves else []
    if not any(cls == STRAIN for cls, _ in boards):
        raise ConfError(f"{path}: no 'strain' line")
    return robot, boards


def _flags(prefix: str, start: int, names: tuple[str, ...], reserved: int) -> list[str]:
    out = [f' SG_ {prefix}{name} : {start + i}|1@1+ (1,0) [0|1] "" RT_MONITOR' for i, name in enumerate(names)]
    return out + [f' SG_ {prefix}Reserved : {start + len(names)}|{reserved}@1+ (1,0) [0|0] "" RT_MONITOR']


def _strain(names: tuple[str, str, str]) -> list[str]:
    return [f' SG_ {c} : {16 * i}|16@1+ (1,-32768) [-32768|32767] "count" RT_MONITOR' for i, c in enumerate(names)]


_FAULTS = ("OverCurrent", "OverTemp", "EncoderFault", "ExternalFault", "PwmLimit")
# (class, type): name, DLC, cycle time in ms, signals
LAYOUT: dict[tuple[int, int], tuple[str, int, int, list[str]]] = {
    (STRAIN, 0xA): ("STRAIN_FORCE", 6, 1, _strain(("Fx", "Fy", "Fz"))),
    (STRAIN, 0xB): ("STRAIN_TORQUE", 6, 1, _strain(("Tx", "Ty", "Tz"))),
    (MC, 1): ("MC_POSITION", 8, 1, [
        f' SG_ Axis{a}Position : {32 * a}|32@1- (1,0) [-2147483648|2147483647] "tick" RT_MONITOR' for a in (0, 1)]),
    (MC, 2): ("MC_PID_VAL", 4, 1, [
        f' SG_ Axis{a}Pwm : {16 * a}|16@1- (1,0) [-32768|32767] "count" RT_MONITOR' for a in (0, 1)]),
    (MC, 3): ("MC_STATUS", 4, 10, _flags("Axis0", 0, _FAULTS, 3) + _flags("Axis1", 8, _FAULTS, 3)
              + _flags("Board", 16, ("Restarted", "TxOverrun"), 6)
              + [' SG_ Sequence : 24|8@1+ (1,0) [0|255] "" RT_MONITOR']),
    (SKIN, 0): ("SKIN_TAXELS", 2, 1, [' SG_ Taxels : 0|16@1+ (1,0) [0|65535] "" RT_MONITOR']),
}
TYPES = {STRAIN: (0xA, 0xB), MC: (1, 2, 3), SKIN: (0,)}
SAT_BYTE, SAT_MASK = 6, 0x07  # the 7-byte strain variant: flags in byte 6, bit i = channel i of the frame

_SAT_TEXT = ("DLC 6. The saturation variant (boards --strain-sat) sends 7 bytes: byte 6 (attribute SatFlagsByte) "
             "bit i set = channel i of this frame was clamped to the int16 range (defined bits: SatFlagsMask), "
             "bits 3-7 reserved, zero (a frame with any set is malformed). cantools decode checks lengths "
             "exactly: decode a 7-byte log with --no-strict (the counts, without byte 6).")
MESSAGE_TEXT = {
    (STRAIN, 0xA): "Strain type 0xA, channels 0-2 (Fx Fy Fz), three little-endian uint16 in offset binary "
                   "(raw = count + 0x8000). " + _SAT_TEXT,
    (STRAIN, 0xB): "Strain type 0xB, channels 3-5 (Tx Ty Tz); as type 0xA. " + _SAT_TEXT,
    (MC, 1): "Motor-control type 1 POSITION: joint encoders of axes 0 and 1, little-endian int32 ticks; ticks per "
             "degree and zero from the configuration.",
    (MC, 2): "Motor-control type 2 PID_VAL: PWM of axes 0 and 1, little-endian int16 counts; duty = count / "
             "pwm_full_scale of the configuration.",
    (MC, 3): "Motor-control type 3 STATUS at 100 Hz: per-axis fault bits (bytes 0, 1), board flags (byte 2), a "
             "sequence counter (byte 3, +1 per frame, wraps, 0 after a restart).",
    (SKIN, 0): "Skin type 0 TAXELS: uint16 little-endian bitmask, bit i = taxel group i of the patch in contact "
               "(the tactile ground truth). Any non-zero = contact on the patch.",
}
SIGNAL_TEXT = {
    (MC, 3): [("Axis0EncoderFault", "Encoder/hall reading invalid: the axis' POSITION is not to be trusted."),
              ("BoardRestarted", "Set in the first STATUS frame after the board booted."),
              ("BoardTxOverrun", "The board dropped periodic frames (TX queue full).")],
}


def dbc_text(robot: str, boards: dict[tuple[int, int], tuple[list[str], list[str]]], addressed: bool = False) -> str:
    msgs = []  # (id, (class, type), (buses, what the board serves))
    for (cls, address), on in sorted(boards.items(), key=lambda kv: ((STRAIN, MC, SKIN).index(kv[0][0]), kv[0][1])):
        for typ in TYPES[cls]:
            msgs.append((cls << 8 | address << 4 | typ, (cls, typ), on))
    out = ['VERSION "dynid icub_can 2"', "", "", "NS_ :", "\tCM_", "\tBA_DEF_", "\tBA_", "\tVAL_", "\tBA_DEF_DEF_",
           "", "BS_:", "", "BU_: STRAIN MC SKIN RT_MONITOR", "", ""]
    for can_id, key, _ in msgs:
        name, dlc, _, signals = LAYOUT[key]
        name += f"_{(can_id >> 4) & 0xF}" if addressed else ""
        out += [f"BO_ {can_id} {name}: {dlc} {NODE[key[0]]}", *signals, ""]
    out += ["", 'BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;', 'BA_DEF_ BO_ "SatFlagsByte" INT 0 7;',
            'BA_DEF_ BO_ "SatFlagsMask" INT 0 255;', 'BA_DEF_DEF_ "GenMsgCycleTime" 0;',
            'BA_DEF_DEF_ "SatFlagsByte" 0;', 'BA_DEF_DEF_ "SatFlagsMask" 0;']
    for can_id, key, _ in msgs:
        out.append(f'BA_ "GenMsgCycleTime" BO_ {can_id} {LAYOUT[key][2]};')
    for can_id, key, _ in msgs:
        if key[0] == STRAIN:
            out += [f'BA_ "SatFlagsByte" BO_ {can_id} {SAT_BYTE};', f'BA_ "SatFlagsMask" BO_ {can_id} {SAT_MASK};']
    out += ["", f'CM_ "The iCub CAN-era protocol (dynid docs/design.md §5), 1 Mbit/s, 11-bit IDs: ID = class<<8 | '
                f'source_address<<4 | type. The boards of {robot or "the robot"}, one message per frame each board '
                'sends, at its address; a message has the same layout at every address, and the same name'
                f'{" with the address appended" if addressed else ""} (written by firmware_like/tools/icub_can_dbc.py '
                'from the rt_monitor configuration). Must agree with icub_can.h (checked by '
                'tools/tests/test_can_dbc.py).";',
            'CM_ BU_ STRAIN "Strain (F/T) board, class 3. Physical value = count * FS[ch] / 32768 with the full '
            'scales of the robot configuration.";',
            'CM_ BU_ MC "Motor-control board, class 1, two axes per board address.";',
            'CM_ BU_ SKIN "Skin board, class 4, one board per patch (simplified layout: a taxel-group bitmask).";']
    for can_id, key, on in msgs:
        buses, serves = on
        where = f"Board address {(can_id >> 4) & 0xF} on {', '.join(buses)}" + (
            f" ({', '.join(sorted(serves))})." if serves else ".")
        out.append(f'CM_ BO_ {can_id} "{where} {MESSAGE_TEXT[key]}";')
        out += [f'CM_ SG_ {can_id} {sig} "{text}";' for sig, text in SIGNAL_TEXT.get(key, [])]
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="icub_can_dbc.py", description="Write the iCub CAN protocol's DBC for the "
                                 "boards of an rt_monitor configuration (every board address it uses).")
    ap.add_argument("config", type=Path, help="rt_monitor configuration (rt_monitor/config/icub_right_arm.conf)")
    ap.add_argument("--out", type=Path, help="the DBC to write (default: stdout)")
    ap.add_argument("--names", choices=("same", "addressed"), default="addressed",
                    help="message names: with the board address appended (unique; the default), or the protocol's "
                         "name at every address")
    args = ap.parse_args(argv)
    try:
        text = dbc_text(*read_boards(args.config), addressed=args.names == "addressed")
    except ConfError as e:
        print(f"icub_can_dbc.py: error: {e}", file=sys.stderr)
        return 2
    if args.out is None:
        sys.stdout.write(text)
        return 0
    tmp = args.out.with_name(args.out.name + ".tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, args.out)
    except OSError as e:
        print(f"icub_can_dbc.py: error: cannot write {args.out}: {e.strerror or e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
