"""A dataset as the boards would have sent it: a candump -L log, and the rt_monitor configuration that reads it.

Per sample k (time t_k) and bus, in this order within the sample's period:
- t_k − 300 µs: every motor board's POSITION and PID_VAL (so the monitor's sample sees fresh values);
- t_k − 200 µs: every skin board's TAXELS: bit 0 = the dataset's `contact` on that board's patch (the
  simulator's `skin.patch` column; without it, all contact on the first skin board);
- t_k − 100 µs and t_k: the strain board's force and torque halves (the torque half closes the sample);
- every 10th sample, each motor board's STATUS (sequence counter, no faults).
Encodings are the protocol's (DESIGN.md §5), and the same as `dynid.can_protocol` decodes: strain counts
round(value · 32768 / FS) clamped to int16 with the saturation flags byte, ticks round((deg + zero)·tpd), PWM
round(duty · full scale).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .can_protocol import make_id
from .config import RobotConfig
from .dataset import Dataset
from .errors import DataError

STATUS_EVERY = 10


def monitor_config_text(config: RobotConfig, lcm_url: str | None = None) -> str:
    """The rt_monitor configuration (rt_monitor/README.md, "Configuration") for a robot configuration."""
    can = config.can
    if not can or len(can.get("strain", [])) != 1:
        raise DataError(f"robot configuration {config.name}: rt_monitor needs a 'can' mapping with one strain board")
    lines = [f"# rt_monitor configuration for {config.name} (written by dynid from its robot configuration)",
             f"robot {config.name}", "buses " + " ".join(can["buses"])]
    if lcm_url:
        lines.append(f"lcm_url {lcm_url}")
    lines += ["stale_ms 5", "pair_us 500", "status_hz 10", "residual_every 10"]
    s = can["strain"][0]
    lines.append(f"strain {s['bus']} {s['address']} " + " ".join(repr(float(x)) for x in s["full_scale"]))
    for b in can["motor_control"]:
        for slot, ax in enumerate(b["axes"]):
            lines.append(f"axis {b['bus']} {b['address']} {slot} {ax['joint']} {float(ax['ticks_per_degree'])!r} "
                         f"{float(ax.get('zero_deg', 0.0))!r}")
            if ax.get("motor"):
                lines.append(f"pwm {b['bus']} {b['address']} {slot} {ax['motor']} {float(b['pwm_full_scale'])!r}")
    for k in can.get("skin", []):
        lines.append(f"skin {k['bus']} {k['address']} {k['patch']} {k['side']}")
    return "\n".join(lines) + "\n"


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


