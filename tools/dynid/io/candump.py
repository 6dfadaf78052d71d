"""The candump -L log: a robot's frames read into a `Dataset`, and a `Dataset` written as its nodes send it.

Both go through the robot's bus description (dynid.config.bus) and cantools (dynid.io.can_database): every frame is
decoded and encoded by cantools with the messages built from the description, for any robot whose configuration
describes a bus (the iCub protocol's `can:` section is one such description).

Reading. Frames are taken in stamp order (as the monitor's frame sources hand them over); each distinct payload of a
frame is decoded once. Sample assembly is the monitor's (rt_monitor/README.md): one sample per clock frame; where
the clock frame is the second half of a pair (the iCub strain board's torque half), only when its first half came at
most `pair_us` before with no other first half between (halves of two samples are never mixed); every other pair's
values are its latest complete pair; every other value, and the skin, is the latest before the sample. The dataset
has a contact column (any skin bit set) only where the log carries the frames of the description's skin targets, every
patch's: a bus without skin (the iCub leg's) or a log without those frames gives a run with no contact ground truth,
never one known to be contact-free (a log with some patches' frames only: left out, with a note). Frames of
unknown IDs or buses, wrong lengths, reserved bits set, extended, remote and error frames are skipped (bus traffic, as
the monitor counts it); blank lines and `#` comments are no lines of the log. Any other line (garbage, an odd number
of hex digits, a CAN FD frame, a last line cut short) is a bad row of the log (dynid.io.bad_rows: `not_a_frame`, or
`cut_short` for a last line with no line end): refused with its line number by default, dropped and counted in
`meta.bad_rows` (and `meta.skipped_lines`) with `bad_rows="skip"`, as a CSV's bad rows are. A log with no frame at
all, no complete sample, or a frame the samples need that never comes before the last one, is refused with one line.

Writing, per sample k at t_k (t0 + the data's time) and frame, in the description's send order: at t_k + the
frame's `offset_us` (the iCub boards: POSITION and PID_VAL at −300 µs, STATUS −250 µs every 10 ms, skin −200 µs,
strain force −100 µs and torque at t_k, which closes the sample); a frame with a period every round(period /
the run's mean sample period) samples from sample 0. Values come from the data (`dq.J`: the run's dq, else its
`velocity.J` column, the controllers' measured velocities); skin bits are the data's `contact` on the patch the
simulator's `skin.patch` column names (without it: all contact on the first patch; a run without a `contact` column
sends no frame that carries skin bits and no value, so that it reads back without contact ground truth, as `boards`
plays it); a sequence counter counts its
frame; fault and saturation flags of a target are set where its value clamps at the signal's range (a frame's long
form, the iCub strain board's 7-byte variant, is sent for the whole run when one of its flags would be set: `auto`).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config.bus import BusDescription, BusFrame, BusSignal, is_value_target
from ..config.robot_config import RobotConfig
from ..errors import DataError, DataNote
from .bad_rows import DEFAULT_POLICY, BadRows, Malformed, apply_policy
from .can_database import BusCodec, codec_of
from .dataset import FT_CHANNELS, Dataset, atomic_write

# A frame line. At most 12 digits of seconds (31 700 years), so that the stamp in µs fits int64; whole bytes of
# payload only (an odd hex digit would shift every later frame's bytes). Fields are separated within the line.
_STAMP = rb"^[ \t]*\((\d{1,12})\.(\d{6})\)[ \t]+(\S+)[ \t]+"
_LINE = re.compile(_STAMP + rb"([0-9A-Fa-f]{3})#((?:[0-9A-Fa-f]{2}){0,8})[ \t\r]*$", re.M)
# A well-formed line of a frame no bus description holds: an extended or error frame (8-digit ID, candump prints an
# error frame with its flag in the ID) or a remote frame. Bus traffic, skipped as a frame of an unknown ID is (and as
# rt_monitor --replay takes them), not a damaged log.
_OTHER = re.compile(_STAMP + rb"(?:[0-9A-Fa-f]{8}#(?:[Rr][0-8]?|(?:[0-9A-Fa-f]{2}){0,8})|[0-9A-Fa-f]{3}#[Rr][0-8]?)"
                    rb"[ \t\r]*$", re.M)
_FD = re.compile(_STAMP + rb"[0-9A-Fa-f]+##")
_CONTENT = re.compile(rb"^(?=[ \t\r\x0b\x0c]*[^ \t\r\n\x0b\x0c#])", re.M)  # a line not blank nor a comment: b"" each
SHOW_CHARS = 60  # of a bad line, in its refusal


def _bad_lines(text: bytes, frames: int, first_line: int = 0) -> tuple[list[Malformed], int]:
    """The lines of the log (`text`, whose first line is the log's `first_line`, 0-based) that are neither a frame
    (`frames` of them matched `_LINE`), another frame (`_OTHER`), blank nor a `#` comment, each a `Malformed` of
    its 0-based line number; and how many lines are not blank."""
    # The clean log, the usual case, told without splitting it into lines (a list of them is twice a long log): every
    # line a frame (a count of line ends), else every line not blank nor a comment a frame or another frame's
    lines_in_text = text.count(b"\n") + (0 if not text or text.endswith(b"\n") else 1)
    if lines_in_text == frames:
        return [], frames
    content_lines = len(_CONTENT.findall(text))
    if content_lines == frames + len(_OTHER.findall(text)):
        return [], content_lines
    lines = text.split(b"\n")
    content = [k for k, line in enumerate(lines) if line.strip() and not line.lstrip().startswith(b"#")]
    cut = len(lines) - 1 if not text.endswith(b"\n") else -1  # a last line with no line end: the logger stopped
    bad = []
    for k in content:
        line = lines[k]
        if _LINE.match(line) or _OTHER.match(line):
            continue
        cut_short = k == cut
        k += first_line
        shown = line.decode("utf-8", "backslashreplace").strip()
        shown = repr(shown if len(shown) <= SHOW_CHARS else shown[: SHOW_CHARS - 3] + "...")
        if cut_short:
            bad.append(Malformed(k, "cut_short", f"line {k + 1}, the last, has no line end and is no frame: {shown} "
                                 "(the log was cut short)"))
        elif _FD.match(line):
            bad.append(Malformed(k, "not_a_frame", f"line {k + 1} is a CAN FD frame, {shown}: the log of a classic-CAN "
                                 "bus has none"))
        else:
            bad.append(Malformed(k, "not_a_frame", f"line {k + 1} is no classic-CAN candump -L frame "
                                 f"'(SECONDS.MICROSECONDS) IFACE ID#HEXDATA': {shown}"))
    return bad, len(content)


@dataclass(frozen=True)
class _Frames:
    """The log's frames in stamp order (stable: frames of one stamp in the log's order)."""
    t_us: np.ndarray  # int64 stamps, µs
    bus: np.ndarray  # index into `buses`
    buses: list[str]  # the bus names seen (a name that is no UTF-8 kept by surrogateescape: no configured bus)
    can_id: np.ndarray
    dlc: np.ndarray
    payload: np.ndarray  # (n, 8) uint8, zero past the DLC
    bad: list[Malformed]  # the lines that are no frame
    lines: int  # the log's lines that are not blank nor a comment


_CHUNK = 16 << 20  # bytes of the log parsed at a time: the text of a whole log as Python objects is ~13 times its size


def _read_frames(path: Path) -> _Frames:
    """The frames of the log at `path`, read and parsed a chunk of whole lines at a time."""
    parts: list[tuple[np.ndarray, ...]] = []
    buses: dict[bytes, int] = {}
    bad: list[Malformed] = []
    lines = first_line = 0
    carry = b""
    try:
        with open(path, "rb") as f:
            while True:
                block = f.read(_CHUNK)
                text = carry + block
                end = len(text) if not block else text.rfind(b"\n") + 1  # the file's end, or its last whole line
                if block and end == 0:
                    carry = text
                    continue
                text, carry = text[:end], text[end:]
                if text:
                    rows = _LINE.findall(text)
                    chunk_bad, chunk_lines = _bad_lines(text, len(rows), first_line)
                    bad += chunk_bad
                    lines += chunk_lines
                    first_line += text.count(b"\n")
                    parts.append(_parse(rows, buses))
                if not block:
                    break
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror or e}") from None
    t_us, bus, can_id, dlc, payload = (np.concatenate(a) for a in zip(*parts)) if parts else \
        (np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0, np.int64), np.zeros(0, np.int64),
         np.zeros((0, 8), np.uint8))
    order = np.argsort(t_us, kind="stable")
    return _Frames(t_us[order], bus[order], [b.decode("utf-8", "surrogateescape") for b in buses], can_id[order],
                   dlc[order], payload[order], bad, lines)


def _parse(rows: list[tuple[bytes, ...]], buses: dict[bytes, int]) -> tuple[np.ndarray, ...]:
    """Stamps (µs), bus indices (`buses` grows by the names first seen), IDs, DLCs and payloads of `_LINE`'s matches."""
    t_us = np.array([int(a) * 1_000_000 + int(b) for a, b, *_ in rows], np.int64)
    bus = np.array([buses.setdefault(r[2], len(buses)) for r in rows], np.int32)
    can_id = np.array([int(r[3], 16) for r in rows], np.int64)
    hexes = [r[4] for r in rows]
    dlc = np.array([len(h) // 2 for h in hexes], np.int64)
    payload = np.zeros((len(rows), 8), np.uint8)
    for n in np.unique(dlc):
        sel = np.flatnonzero(dlc == n)
        if n:
            payload[sel, :n] = np.frombuffer(bytes.fromhex(b"".join(hexes[i] for i in sel).decode()), np.uint8).reshape(-1, n)
    return t_us, bus, can_id, dlc, payload


def _decode_rows(codec: BusCodec, frame: BusFrame, payload: np.ndarray, dlc: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Every signal of `frame` for its rows (payload (n, 8), their DLCs), decoded by cantools once per distinct
    payload; and which rows are good (reserved bits clear). Optional signals absent from a short frame are 0."""
    c = codec.codec(frame.bus, frame.id)
    assert c is not None
    values = {s.name: np.zeros(dlc.size) for s in frame.signals}
    good = np.ones(dlc.size, bool)
    word = np.ascontiguousarray(payload).view("<u8")[:, 0]
    reserved = [s.name for s in frame.signals if s.target == "reserved"]
    for length in np.unique(dlc).tolist():
        rows = np.flatnonzero(dlc == length)
        uniq, inverse = np.unique(word[rows], return_inverse=True)
        msg = c.message_for(length)
        decoded = [msg.decode(w.to_bytes(8, "little")[:length], decode_choices=False, scaling=True)
                   for w in uniq.tolist()]
        for name in decoded[0]:
            values[name][rows] = np.array([d[name] for d in decoded], float)[inverse.reshape(-1)]
        bad = np.array([any(d.get(r) for r in reserved) for d in decoded], bool)
        good[rows] = ~bad[inverse.reshape(-1)]
    return values, good


def read_candump(path: str | Path, config: RobotConfig, bad_rows: str = DEFAULT_POLICY) -> Dataset:
    """The log's samples (module docstring); its bad lines refused or, with `bad_rows="skip"`, dropped and recorded
    in `meta["bad_rows"]` (dynid.io.bad_rows)."""
    path = Path(path)
    bus = config.bus
    if bus is None:
        raise DataError(f"{path}: the robot configuration {config.name} describes no CAN bus ('bus' or 'can')")
    codec = codec_of(bus, config.name)
    frames = _read_frames(path)
    t_us, can_id, dlc, payload = frames.t_us, frames.can_id, frames.dlc, frames.payload
    if not t_us.size:
        raise DataError(f"{path}: no classic-CAN candump -L frame in the file")
    # Lines that are no frame (garbage, a line cut short): bad rows, refused or dropped and counted as a CSV's are.
    bad = frames.bad
    found = BadRows(np.array([m.row for m in bad], np.int64), tuple(m.kind for m in bad), bad[0].detail,
                    frames.lines) if bad else None
    dropped = apply_policy(found, np.ones(1, bool), bad_rows, str(path), lambda k: f"line {k + 1}")

    # Per frame of the description: its rows (stamp order) and decoded values.
    got: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
    for f in bus.frames:
        lengths = (f.dlc, f.long_dlc) if f.long_dlc else (f.dlc,)
        on_bus = frames.buses.index(f.bus) if f.bus in frames.buses else -1
        sel = np.flatnonzero((frames.bus == on_bus) & (can_id == f.id) & np.isin(dlc, lengths))
        values, good = _decode_rows(codec, f, payload[sel], dlc[sel])
        got[f.name] = (sel[good], {k: v[good] for k, v in values.items()})

    def where(f: BusFrame) -> str:
        return f"frame {f.name} (0x{f.id:03X} on {f.bus})"

    # The samples: the clock frames, each with its pair's first half when it has one.
    clock = bus.frame(bus.clock)
    t_clock = t_us[got[clock.name][0]]
    if not t_clock.size:
        raise DataError(f"{path}: no {where(clock)}, which completes every sample: not this robot's log?")
    committed = {}  # pair frame name -> (commit times, index into the frame's rows)

    def complete(first: str, second: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Indices into each half's rows of the complete pairs, and their times (the second half's)."""
        ta, tb = t_us[got[first][0]], t_us[got[second][0]]
        j = np.searchsorted(ta, tb, side="right") - 1
        ok = j >= 0
        ok[ok] &= (tb[ok] - ta[j[ok]]) <= bus.pair_us
        ok &= np.r_[True, j[1:] != j[:-1]]
        keep = np.flatnonzero(ok)
        return j[keep], keep, tb[keep]

    sample_rows = np.arange(t_clock.size)
    for first, second in bus.pairs:
        ia, ib, tt = complete(first, second)
        if second == clock.name:
            if not tt.size:
                raise DataError(f"{path}: no complete sample ({first} and {second} within {bus.pair_us} µs)")
            sample_rows, t = ib, tt
            committed[first], committed[second] = (tt, ia), (tt, ib)
        else:
            committed[first], committed[second] = (tt, ia), (tt, ib)
    if clock.name not in committed:
        t = t_clock
        committed[clock.name] = (t, sample_rows)

    n = t.size
    valid = np.ones(n, bool)

    def latest(f: BusFrame) -> np.ndarray:
        """Per sample, the index into f's rows of its latest value (committed pairs: the latest complete pair)."""
        nonlocal valid
        times, idx = committed.get(f.name, (t_us[got[f.name][0]], np.arange(got[f.name][0].size)))
        if f.name == clock.name or (bus.pair_of(clock.name) and f.name in bus.pair_of(clock.name)):
            return idx
        if not times.size:
            raise DataError(f"{path}: no {where(f)}")
        k = np.searchsorted(times, t, side="right") - 1
        if k[-1] < 0:
            raise DataError(f"{path}: no {where(f)} before the last sample")
        valid &= k >= 0
        return idx[np.maximum(k, 0)]

    q = np.full((n, len(config.joints)), np.nan)
    dq = np.full((n, len(config.joints)), np.nan)
    jidx = {name: i for i, name in enumerate(config.joints)}
    families: dict[str, dict[str, np.ndarray]] = {"pwm": {}, "current": {}, "tau": {}}
    ft: dict[str, np.ndarray] = {}
    # Contact ground truth only where the log carries it: the frames of every skin target (contact bits) of the
    # description. A bus with none (the iCub leg's), or a log without their frames, records no contact, not "no
    # contact"; a log with some patches' frames but not others' knows contact on part of the robot only: left out.
    skin_frames = [f for f in bus.frames if any(s.target.startswith("skin.") for s in f.signals)]
    silent = [f for f in skin_frames if not got[f.name][0].size]
    contact = np.zeros(n, np.uint8) if skin_frames and not silent else None
    if skin_frames and silent and len(silent) < len(skin_frames):
        patches = sorted({s.target[5:] for f in silent for s in f.signals if s.target.startswith("skin.")})
        warnings.warn(DataNote(
            f"{path}: no {', '.join(where(f) for f in silent)} in the log: the contact of skin patch"
            f"{'es' * (len(patches) != 1)} {', '.join(patches)} is unknown, so the run has no contact ground truth "
            "(its contact column is left out)"), stacklevel=2)
    for f in bus.frames:
        targets = [s for s in f.signals if is_value_target(s.target)
                   or (contact is not None and s.target.startswith("skin."))]
        if not targets:
            continue
        at = latest(f)
        values = got[f.name][1]
        for s in targets:
            v = values[s.name][at]
            family, _, name = s.target.partition(".")
            if family == "q":
                q[:, jidx[name]] = v
            elif family == "dq":
                dq[:, jidx[name]] = v
            elif family == "ft":
                sensor, _, comp = name.rpartition(".")
                ft.setdefault(sensor, np.full((n, 6), np.nan))[:, FT_CHANNELS.index(comp)] = v
            elif family == "skin":
                assert contact is not None
                contact |= (v != 0).astype(np.uint8)
            else:
                families[family][name] = v
    missing = [name for name in config.joints if np.isnan(q[:, jidx[name]]).all()]
    if missing:
        raise DataError(f"{path}: joints {', '.join(missing)} are carried by no frame of {config.name}'s bus")
    keep = np.flatnonzero(valid)
    if keep.size < 2:
        raise DataError(f"{path}: fewer than two complete samples")
    with_dq = not np.isnan(dq).all()
    extra = {}
    if with_dq and np.isnan(dq).any(axis=0).any():  # some joints only: kept by name, not as a partial dq
        extra = {f"dq.{j}": dq[keep, i] for j, i in jidx.items() if not np.isnan(dq[:, i]).all()}
        with_dq = False
    tt = (t[keep] - t[keep][0]) / 1e6
    return Dataset(t=tt, joints=tuple(config.joints), q=q[keep], dq=dq[keep] if with_dq else None,
                   pwm={m: v[keep] for m, v in families["pwm"].items()},
                   current={m: v[keep] for m, v in families["current"].items()},
                   tau={j: v[keep] for j, v in families["tau"].items()},
                   ft={s: v[keep] for s, v in ft.items()}, contact=None if contact is None else contact[keep],
                   extra=extra,
                   meta={"source": str(path), "source_format": "candump", "robot": config.name,
                         "messages": sorted(f.name for f in bus.frames), "skipped_lines": len(bad),
                         **({"bad_rows": dropped} if dropped is not None else {})})


# ---- writing ----


def target_values(data: Dataset, target: str) -> np.ndarray | None:
    """The data's (N,) values of a value target (q.J, dq.J, pwm.M, current.M, tau.J, ft.S.C), None if absent.
    dq.J is the run's `velocity.J` column (the controller's measured velocity, what the observer takes offline:
    dynid.detect.momentum.measured_velocity), else its dq."""
    family, _, name = target.partition(".")
    if family in ("q", "dq"):
        if name not in data.joints:
            return None
        if family == "dq" and f"velocity.{name}" in data.extra:
            return data.extra[f"velocity.{name}"]
        values = data.q if family == "q" else data.dq
        if values is None:
            return None
        return values[:, data.joints.index(name)]
    if family == "ft":
        sensor, _, comp = name.rpartition(".")
        return data.ft[sensor][:, FT_CHANNELS.index(comp)] if sensor in data.ft else None
    return getattr(data, family).get(name)


def skin_values(data: Dataset, bus: BusDescription, patch: str) -> np.ndarray:
    """1 where the data's contact is on `patch`: the simulator's `skin.patch` (1 + the patch's index), else every
    contact on the first patch."""
    n = data.n_samples
    contact = data.contact if data.contact is not None else np.zeros(n, np.uint8)
    index = [p.name for p in bus.patches].index(patch)
    on = contact != 0
    where = data.extra.get("skin.patch")
    return (on & (where == index + 1) if where is not None else on & (index == 0)).astype(float)


def _clamps(s: BusSignal, v: np.ndarray) -> np.ndarray:
    """Where cantools' raw value, round((v − offset) / scale) (half to even), falls outside the signal's range."""
    if s.type == "float":
        return np.zeros(v.shape, bool)
    lo, hi = s.raw_range
    r = np.round((v - s.offset) / s.scale)
    return (r < lo) | (r > hi)


def _limit(s: BusSignal, v: np.ndarray, clamped: np.ndarray) -> np.ndarray:
    """The values with the clamped ones at the physical end of the signal's range they went past."""
    lo, hi = s.raw_range
    r = np.round((v - s.offset) / s.scale)
    return np.where(clamped, np.where(r > hi, hi, lo) * s.scale + s.offset, v)


def frame_values(data: Dataset, bus: BusDescription, f: BusFrame, rows: np.ndarray, long: bool) -> tuple[list[str], np.ndarray]:
    """The signal names and (len(rows), signals) physical values of frame `f` for the samples `rows` (counters
    counting the frames sent), clamped to each signal's range with the flags that say so."""
    signals = [s for s in f.signals if long or s.end_byte <= f.dlc]
    out = np.zeros((rows.size, len(signals)))
    values: dict[str, np.ndarray] = {}
    clamped: dict[str, np.ndarray] = {}
    for s in f.signals:
        if is_value_target(s.target):
            v = target_values(data, s.target)
            if v is None:
                raise DataError(f"the data have no {s.target} for frame {f.name} of the bus")
            clamped[s.target] = _clamps(s, v)
            values[s.target] = _limit(s, v, clamped[s.target])
    flag_of = {s.target: s for fr in bus.frames for s in fr.signals}
    for i, s in enumerate(signals):
        base, _, of = s.target.partition(".")
        if is_value_target(s.target):
            out[:, i] = values[s.target][rows]
        elif base == "skin":
            out[:, i] = skin_values(data, bus, of)[rows]
        elif base in ("saturated", "fault") and of:
            vf, sf = target_values(data, of), flag_of[of]
            out[:, i] = _clamps(sf, vf)[rows] if vf is not None else 0
        elif s.target == "seq":
            out[:, i] = np.arange(rows.size) % (1 << s.length)
    return [s.name for s in signals], out


def _skin_only(f: BusFrame) -> bool:
    """The frame carries skin bits and no value: it says only where contact is."""
    return any(s.target.startswith("skin.") for s in f.signals) and not any(is_value_target(s.target) for s in f.signals)


def write_candump(data: Dataset, config: RobotConfig, path: str | Path, t0: float = 1_700_000_000.0,
                  long_form: str = "auto") -> int:
    """Write `data` as the robot's nodes send it on its bus, atomically; returns the number of frames. `long_form`:
    auto (a frame's long form when one of its flags would be set in the run), on, off."""
    bus = config.bus
    if bus is None:
        raise DataError(f"robot configuration {config.name} describes no CAN bus ('bus' or 'can')")
    codec = codec_of(bus, config.name)
    n = data.n_samples
    t_us = np.round((data.t - data.t[0] + t0) * 1e6).astype(np.int64)
    period = (data.t[-1] - data.t[0]) / (n - 1) if n > 1 else 1.0 / bus.rate
    lines: list[str] = []
    times: list[np.ndarray] = []
    # The long form, per node (a board sends one variant): on, or where one of its optional flags is set in the run.
    long_nodes = set()
    for f in bus.frames:
        if f.long_dlc and long_form != "off":
            _, values = frame_values(data, bus, f, np.arange(0, n, f.every(period)), True)
            optional = [i for i, s in enumerate(f.signals) if s.end_byte > f.dlc]
            if long_form == "on" or values[:, optional].any():
                long_nodes.add(f.node)
    for f in bus.send_order():
        if data.contact is None and _skin_only(f):
            continue  # a run without contact labels has no skin to send: read back, it has no contact ground truth
        rows = np.arange(0, n, f.every(period))
        long = bool(f.long_dlc) and f.node in long_nodes
        names, vals = frame_values(data, bus, f, rows, long)
        uniq, inverse = np.unique(vals, axis=0, return_inverse=True)
        encoded = [codec.encode(f.bus, f.id, dict(zip(names, row.tolist())), long).hex().upper() for row in uniq]
        head = f" {f.bus} {f.id:03X}#"
        stamps = t_us[rows] + f.offset_us
        lines.extend(f"({t // 1_000_000}.{t % 1_000_000:06d}){head}{encoded[i]}"
                     for t, i in zip(stamps.tolist(), inverse.reshape(-1).tolist()))
        times.append(stamps)
    order = np.argsort(np.concatenate(times), kind="stable")  # the send order breaks ties between equal stamps
    text = "\n".join(lines[i] for i in order) + "\n"
    atomic_write(path, lambda f: f.write(text.encode()))
    return len(lines)
