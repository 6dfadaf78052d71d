"""The candump -L log: the boards' frames read into a `Dataset`, and a `Dataset` written as the boards send it.

Reading, decoded in bulk with the DBC's signal layouts.

Each DBC signal (start bit, length, signedness, scale, offset, all little-endian) is applied with numpy to every
frame of its (class, type) at once, so a 2-minute, 2-million-frame log imports in seconds. Sample assembly is the
monitor's (rt_monitor/README.md): one sample per strain torque half whose force half came at most 500 µs before
with no other force half between; encoders, PWMs and skin at their latest values before the sample. Frames of
unknown IDs, wrong lengths and error frames are skipped; a log with no complete sample, or a joint or motor of
the configuration that never appears, is refused with one line.

Writing, per sample k (time t_k) and bus, in this order within the sample's period:
- t_k − 300 µs: every motor board's POSITION and PID_VAL (so the monitor's sample sees fresh values);
- t_k − 200 µs: every skin board's TAXELS: bit 0 = the dataset's `contact` on that board's patch (the
  simulator's `skin.patch` column; without it, all contact on the first skin board);
- t_k − 100 µs and t_k: the strain board's force and torque halves (the torque half closes the sample);
- every 10th sample, each motor board's STATUS (sequence counter, no faults).
Encodings are the protocol's (docs/design.md §5), and the same as `dynid.io.can_protocol` decodes: strain counts
round(value · 32768 / FS) clamped to int16 with the saturation flags byte, ticks round((deg + zero)·tpd), PWM
round(duty · full scale).
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError
from .can_protocol import MESSAGE_NAMES, default_protocol, make_id
from .dataset import Dataset

PAIR_US = 500
# A frame line. At most 12 digits of seconds (31 700 years), so that the stamp in µs fits int64; whole bytes of
# payload only (an odd hex digit would shift every later frame's bytes in the bulk decode). Any other line is skipped.
_LINE = re.compile(rb"^\((\d{1,12})\.(\d{6})\)\s+(\S+)\s+([0-9A-Fa-f]{3})#((?:[0-9A-Fa-f]{2}){0,8})\s*$", re.M)


def _signals(name: str, payload: np.ndarray) -> dict[str, np.ndarray]:
    """Every signal of message `name` from payloads (n, 8) uint8, with the DBC's layout."""
    msg = default_protocol().message(name)
    word = payload.view("<u8")[:, 0]
    out = {}
    for s in msg.signals:
        v = (word >> np.uint64(s.start)) & np.uint64((1 << s.length) - 1)
        v = v.astype(np.int64)
        if s.is_signed:
            v = np.where(v >= 1 << (s.length - 1), v - (1 << s.length), v)
        out[s.name] = v * s.scale + s.offset
    return out


def read_candump(path: str | Path, config: RobotConfig) -> Dataset:
    path = Path(path)
    can = config.can
    if not can or len(can.get("strain", [])) != 1:
        raise DataError(f"{path}: the robot configuration {config.name} has no CAN mapping with one strain board")
    try:
        text = path.read_bytes()
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror or e}") from None
    rows = _LINE.findall(text)
    skipped = sum(1 for line in text.split(b"\n") if line.strip()) - len(rows)  # malformed lines, told by import
    if not rows:
        raise DataError(f"{path}: no classic-CAN candump -L frame in the file")
    # In stamp order, as the monitor's frame sources hand frames over (rt_monitor/README.md): the pairing and the
    # latest-value look-ups below search sorted stamps, and lines out of order made time run backwards.
    rows.sort(key=lambda r: int(r[0]) * 1_000_000 + int(r[1]))
    t_us = np.array([int(a) * 1_000_000 + int(b) for a, b, *_ in rows], np.int64)
    # A bus name that is no UTF-8 is no configured bus: its frames are skipped like those of any other bus.
    bus = np.array([r[2].decode("utf-8", "surrogateescape") for r in rows])
    can_id = np.array([int(r[3], 16) for r in rows], np.int64)
    hexes = [r[4] for r in rows]
    dlc = np.array([len(h) // 2 for h in hexes])
    payload = np.zeros((len(rows), 8), np.uint8)
    for n in np.unique(dlc):
        sel = np.flatnonzero(dlc == n)
        if n:
            payload[sel, :n] = np.frombuffer(bytes.fromhex(b"".join(hexes[i] for i in sel).decode()), np.uint8).reshape(-1, n)
    cls, addr, typ = can_id >> 8, (can_id >> 4) & 0xF, can_id & 0xF

    def frames(bus_name: str, c: int, a: int, ty: int, lengths: tuple[int, ...]) -> np.ndarray:
        return np.flatnonzero((bus == bus_name) & (cls == c) & (addr == a) & (typ == ty) & np.isin(dlc, lengths))

    s = can["strain"][0]
    fs = np.asarray(s["full_scale"], float)
    force = frames(s["bus"], 3, s["address"], 0xA, (6, 7))
    torque = frames(s["bus"], 3, s["address"], 0xB, (6, 7))
    if not force.size or not torque.size:
        raise DataError(f"{path}: no strain frames of board {s['address']} on {s['bus']}: not this robot's log?")
    # Pair each torque half with the latest force half before it, if within PAIR_US and not used already.
    j = np.searchsorted(t_us[force], t_us[torque], side="right") - 1
    ok = j >= 0
    ok[ok] &= (t_us[torque[ok]] - t_us[force[j[ok]]]) <= PAIR_US
    ok &= np.r_[True, j[1:] != j[:-1]]
    if not ok.any():
        raise DataError(f"{path}: no complete strain sample (force and torque halves within {PAIR_US} µs)")
    torque, force = torque[ok], force[j[ok]]
    t = t_us[torque]
    fsig, tsig = _signals("STRAIN_FORCE", payload[force]), _signals("STRAIN_TORQUE", payload[torque])
    ft = np.column_stack([fsig[c] for c in ("Fx", "Fy", "Fz")] + [tsig[c] for c in ("Tx", "Ty", "Tz")]) * fs / 32768

    def latest(idx: np.ndarray, what: str) -> np.ndarray:
        if not idx.size:
            raise DataError(f"{path}: no {what} frames")
        k = np.searchsorted(t_us[idx], t, side="right") - 1
        if k[-1] < 0:
            raise DataError(f"{path}: no {what} frame before the last strain sample")
        return idx[np.maximum(k, 0)], k >= 0

    q = np.full((t.size, len(config.joints)), np.nan)
    pwm: dict[str, np.ndarray] = {}
    valid = np.ones(t.size, bool)
    jidx = {name: i for i, name in enumerate(config.joints)}
    for b in can["motor_control"]:
        where = f"motor board {b['address']} on {b['bus']}"
        pos, ok_p = latest(frames(b["bus"], 1, b["address"], 1, (8,)), f"POSITION of {where}")
        valid &= ok_p
        sig = _signals("MC_POSITION", payload[pos])
        pid_idx = frames(b["bus"], 1, b["address"], 2, (4,))
        has_motor = any(ax.get("motor") for ax in b["axes"])
        if has_motor:
            pid, ok_w = latest(pid_idx, f"PID_VAL of {where}")
            valid &= ok_w
            wsig = _signals("MC_PID_VAL", payload[pid])
        for slot, ax in enumerate(b["axes"]):
            deg = sig[f"Axis{slot}Position"] / float(ax["ticks_per_degree"]) - float(ax.get("zero_deg", 0.0))
            q[:, jidx[ax["joint"]]] = np.radians(deg)
            if ax.get("motor"):
                pwm[ax["motor"]] = wsig[f"Axis{slot}Pwm"] / float(b["pwm_full_scale"])
    missing = [name for name in config.joints if np.isnan(q[:, jidx[name]]).all()]
    if missing:
        raise DataError(f"{path}: joints {', '.join(missing)} are on no motor board of the configuration")
    contact = np.zeros(t.size, np.uint8)
    for k in can.get("skin", []):
        idx = frames(k["bus"], 4, k["address"], 0, (2,))
        if idx.size:
            kk = np.searchsorted(t_us[idx], t, side="right") - 1
            taxels = _signals("SKIN_TAXELS", payload[idx])["Taxels"]
            contact |= ((kk >= 0) & (taxels[np.maximum(kk, 0)] != 0)).astype(np.uint8)
    keep = np.flatnonzero(valid)
    if keep.size < 2:
        raise DataError(f"{path}: fewer than two complete samples")
    tt = (t[keep] - t[keep][0]) / 1e6
    return Dataset(t=tt, joints=tuple(config.joints), q=q[keep], pwm={m: v[keep] for m, v in pwm.items()},
                   ft={s["sensor"]: ft[keep]}, contact=contact[keep],
                   meta={"source": str(path), "source_format": "candump", "robot": config.name,
                         "messages": sorted(MESSAGE_NAMES.values()), "skipped_lines": skipped})


# ---- writing ----

STATUS_EVERY = 10


def _strain_counts(values: np.ndarray, fs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """int16 counts (half away from zero, clamped) and a per-channel saturation mask."""
    x = values * 32768.0 / fs
    s = np.sign(x) * np.floor(np.abs(x) + 0.5)
    sat = (s > 32767) | (s < -32768)
    return np.clip(s, -32768, 32767).astype(np.int64), sat


def write_candump(data: Dataset, config: RobotConfig, path: str | Path, t0: float = 1_700_000_000.0) -> int:
    """Write `data` as the boards' frames, atomically; returns the number of frames."""
    can = config.can
    if not can or len(can.get("strain", [])) != 1:
        raise DataError(f"robot configuration {config.name}: no CAN mapping with one strain board")
    s = can["strain"][0]
    if s["sensor"] not in data.ft:
        raise DataError(f"the data have no F/T sensor '{s['sensor']}' to send as strain frames")
    n = data.n_samples
    t_us = np.round((data.t - data.t[0] + t0) * 1e6).astype(np.int64)
    events: list[tuple[np.ndarray, str, int, np.ndarray, int]] = []  # (times, bus, id, payload bytes (n, dlc))
    counts, sat = _strain_counts(data.ft[s["sensor"]], np.asarray(s["full_scale"], float))
    raw = np.ascontiguousarray(counts + 0x8000, dtype="<u2")  # ft may be column-major (CSV-loaded data)
    dlc = 7 if sat.any() else 6  # the board's saturation variant (7-byte frames) when a channel clamps in the run
    for half, typ, offset in ((0, 0xA, -100), (1, 0xB, 0)):
        flags = (sat[:, 3 * half:3 * half + 3] * np.array([1, 2, 4])).sum(axis=1).astype(np.uint8)
        payload = np.concatenate([raw[:, 3 * half:3 * half + 3].view(np.uint8).reshape(n, 6), flags[:, None]], axis=1)
        events.append((t_us + offset, s["bus"], make_id(3, s["address"], typ), payload[:, :dlc], n))
    jidx = {j: i for i, j in enumerate(data.joints)}
    for b in can["motor_control"]:
        ticks = np.zeros((n, 2), np.int64)
        pwm = np.zeros((n, 2), np.int64)
        for slot, ax in enumerate(b["axes"]):
            if ax["joint"] not in jidx:
                raise DataError(f"the data have no joint '{ax['joint']}' for board {b['address']} on {b['bus']}")
            deg = np.degrees(data.q[:, jidx[ax["joint"]]]) + float(ax.get("zero_deg", 0.0))
            ticks[:, slot] = np.round(deg * float(ax["ticks_per_degree"]))
            if ax.get("motor"):
                if ax["motor"] not in data.pwm:
                    raise DataError(f"the data have no PWM of motor '{ax['motor']}'")
                pwm[:, slot] = np.clip(np.round(data.pwm[ax["motor"]] * float(b["pwm_full_scale"])), -32768, 32767)
        events.append((t_us - 300, b["bus"], make_id(1, b["address"], 1),
                       ticks.astype("<i4").view(np.uint8).reshape(n, 8), n))
        events.append((t_us - 300, b["bus"], make_id(1, b["address"], 2),
                       pwm.astype("<i2").view(np.uint8).reshape(n, 4), n))
        k = np.arange(0, n, STATUS_EVERY)
        status = np.zeros((k.size, 4), np.uint8)
        status[:, 3] = np.arange(k.size) % 256
        events.append((t_us[k] - 250, b["bus"], make_id(1, b["address"], 3), status, k.size))
    contact = data.contact if data.contact is not None else np.zeros(n, np.uint8)
    patch = data.extra.get("skin.patch")  # the simulator's: 1 + index of the touched skin board, 0 none
    for i, k in enumerate(can.get("skin", [])):
        on = contact != 0
        on = on & (patch == i + 1) if patch is not None else on & (i == 0)
        taxels = on.astype("<u2")
        events.append((t_us - 200, k["bus"], make_id(4, k["address"], 0), taxels.view(np.uint8).reshape(n, 2), n))

    times = np.concatenate([e[0] for e in events])
    order = np.argsort(times, kind="stable")
    lines = []
    for times_e, bus, can_id, payload, _ in events:
        w = 2 * payload.shape[1]
        flat = np.ascontiguousarray(payload, np.uint8).tobytes().hex().upper()
        hexes = [flat[i:i + w] for i in range(0, len(flat), w)] if w else [""] * len(times_e)
        head = f" {bus} {can_id:03X}#"
        lines.extend(f"({t // 1_000_000}.{t % 1_000_000:06d}){head}{h}" for t, h in zip(times_e.tolist(), hexes))
    text = "\n".join(lines[i] for i in order) + "\n"
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 is not what a log should be
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return len(lines)
