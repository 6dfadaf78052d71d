"""A ROS 2 bag (rosbag2, MCAP or SQLite storage) read through the configuration's `ros2:` field, with `rosbags`.

`sensor_msgs/msg/JointState` gives the joints (position; velocity and effort as the configuration says) and
`geometry_msgs/msg/WrenchStamped` the F/T sensors (config/ros2_topics.py). Topics arrive at their own rates and
times, so samples are formed one of two ways:

- **the joint-state clock** (the default): one sample per message of the `joint_states` topic, at its stamp, in
  seconds (ROS time: since the epoch, or since the simulation's start). A wrench topic is sampled at each stamp:
  `linear` (the default) interpolates between the two wrench messages around it, and refuses where they are more
  than `wrench_tolerance` apart; `nearest` takes the closest message, refusing where it is more than
  `wrench_tolerance` away. A wrench message at the very stamp is taken as it is, bit for bit. Joint states before
  the first or after the last message of a wrench topic are left out, and counted. A message that names none of
  the configured joints is another publisher's on the same topic (a gripper's): left out, and counted; one that
  names some but not all is refused. The rows are then a table's: a bad one (dynid.io.bad_rows: not finite, out
  of range, time negative or not increasing) is refused, or skipped with `--bad-rows skip`.
- **a uniform grid** (`ros2.rate` set): every topic, joint states included, is interpolated onto one grid at
  `rate` over the span all of them cover, time 0 at the earliest stamp of any JointState or WrenchStamped topic
  of the bag, exactly as a YARP folder is read (dynid.io.align); `joint_states` may list several topics.

What was done is recorded in `meta["ros2"]` (docs/formats.md): the storage, the clock, per topic the messages
read and left out.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import RobotConfig
from ..config.ros2_topics import IGNORE, JOINT_STATE, WRENCH, Ros2Topics
from ..errors import DataError
from .align import Stream, keep_increasing, on_grid, uniform_grid
from .bad_rows import DEFAULT_POLICY
from .csv_format import check_columns, table_dataset
from .dataset import FT_CHANNELS, Dataset

MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
BAG_SUFFIXES = (".mcap", ".db3")


def is_bag(path: Path) -> bool:
    """A rosbag2 folder (metadata.yaml beside its storage files), or one storage file (.mcap, .db3)."""
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix.lower() in BAG_SUFFIXES


def looks_like_bag_file(head: bytes) -> bool:
    """A file that is MCAP or SQLite whatever its name (the readers tell a storage by its suffix)."""
    return head.startswith(MCAP_MAGIC) or head.startswith(SQLITE_MAGIC)


@dataclass
class _Topic:
    """One topic's messages as read: stamps (s), names of the joints or the frame, the fields."""

    name: str
    stamps: list[float] = field(default_factory=list)
    ns: list[int] = field(default_factory=list)
    names: list[tuple[str, ...]] = field(default_factory=list)  # JointState: per message
    frames: list[str] = field(default_factory=list)  # WrenchStamped: per message
    position: list[np.ndarray] = field(default_factory=list)
    velocity: list[np.ndarray] = field(default_factory=list)
    effort: list[np.ndarray] = field(default_factory=list)
    wrench: list[tuple[float, ...]] = field(default_factory=list)


def read_bag(path: str | Path, config: RobotConfig, joint_limits: Mapping[str, tuple[float, float]] | None = None,
             require_all: bool = True, bad_rows: str = DEFAULT_POLICY) -> Dataset:
    """Import a ROS 2 bag described by `config.ros2` as a `Dataset` (module docstring)."""
    path = Path(path)
    spec = config.ros2
    if spec is None:
        raise DataError(f"{path}: a ROS 2 bag, but the configuration {config.name} has no 'ros2' field naming its "
                        "topics (docs/formats.md, Robot configuration)")
    topics, firsts, storage = _read(path, spec)
    if spec.rate is None:
        names, data, rows, info = _on_joint_state_clock(path, spec, config, topics)
        label = _message_label(spec.joint_states[0])
    else:
        names, data, rows, info = _on_grid(path, spec, config, topics, firsts)
        label = _sample_label
    try:
        columns = check_columns(names, config, require_all=require_all, source=str(path))
    except DataError as e:
        empty = [f for f in ("velocity", "effort") if getattr(spec, f) != IGNORE
                 and not any(n.startswith(f"{getattr(spec, f)}.") for n in names)]
        if not empty:
            raise
        raise DataError(f"{e} (the messages of {', '.join(spec.joint_states)} carry no {' and no '.join(empty)}, "
                        f"which the configuration's ros2 field maps to {', '.join(getattr(spec, f) for f in empty)})"
                        ) from None
    dataset = table_dataset(path, b"", names, columns, data, config, joint_limits, "ros2 bag", label,
                            table=_Rows(data, rows), bad_rows=bad_rows)
    dataset.meta["source_sha256"] = bag_digest(path)
    dataset.meta["ros2"] = {"storage": storage, **info}
    return dataset


@dataclass(frozen=True)
class _Rows:
    """The rows a bag gives `table_dataset`: all parsed, numbered as the reader labels them."""

    data: np.ndarray
    rows: np.ndarray
    malformed: tuple = ()

    @property
    def total(self) -> int:
        return int(self.rows.size)


def _message_label(topic: str):  # noqa: ANN202 - a row's name in messages
    return lambda i: f"message {i + 1} of {topic}"


def _sample_label(i: int) -> str:
    return f"sample {i + 1}"


def bag_digest(path: Path) -> str:
    """sha256 of a bag: its file's bytes, or each file of its folder with its name, in sorted order."""
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for p in files:
        h.update(p.relative_to(path).as_posix().encode() + b"\0" if path.is_dir() else b"")
        with open(p, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


# ----------------------------------------------------------------------------------------------------------
# Reading the messages


def _read(path: Path, spec: Ros2Topics) -> tuple[dict[str, _Topic], list[float], str]:
    """The configured topics' messages; the first stamp of every JointState and WrenchStamped topic of the bag (the
    grid's origin); the storage's name."""
    from rosbags.rosbag2 import Reader  # the ecosystem's reader: loaded only for bags
    from rosbags.typesys import Stores, get_typestore

    wanted = {t: JOINT_STATE for t in spec.joint_states} | {w.topic: WRENCH for w in spec.wrenches}
    try:
        reader = Reader(path)
        reader.open()
    except Exception as e:  # noqa: BLE001 - rosbags raises many kinds on a foreign or corrupt file: one line
        raise DataError(f"{path}: not a readable ROS 2 bag (MCAP or SQLite): {_why(e)}") from None
    try:
        by_topic = {c.topic: c for c in reader.connections}
        for topic, msgtype in wanted.items():
            conn = by_topic.get(topic)
            if conn is None:
                have = ", ".join(sorted(by_topic)) or "no topic"
                raise DataError(f"{path}: no topic {topic} (the configuration's ros2 field names it); the bag has: {have}")
            if conn.msgtype != msgtype:
                raise DataError(f"{path}: topic {topic} carries {conn.msgtype}, not {msgtype}")
        store = get_typestore(Stores.LATEST)
        topics = {t: _Topic(t) for t in wanted}
        use_log = spec.stamp == "log"
        try:
            for conn, logtime, raw in reader.messages(connections=[by_topic[t] for t in wanted]):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                ns = int(logtime) if use_log else int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
                _append(topics[conn.topic], conn.msgtype, msg, ns)
            firsts = [] if spec.rate is None else _first_stamps(reader, store, set(wanted), use_log)
        except DataError:
            raise
        except Exception as e:  # noqa: BLE001 - a corrupt chunk or message: one line, not a traceback
            raise DataError(f"{path}: a message of the bag cannot be read: {_why(e)}") from None
        storage = "mcap" if _is_mcap(path) else "sqlite3"
    finally:
        reader.close()
    for topic in topics.values():
        if not topic.ns:
            raise DataError(f"{path}: topic {topic.name} has no message")
        if not use_log and not any(topic.ns):
            raise DataError(f"{path}: every header stamp of {topic.name} is zero; set the configuration's ros2.stamp "
                            "to 'log' to use the times the recorder received the messages")
    return topics, firsts, storage


def _is_mcap(path: Path) -> bool:
    return any(path.glob("*.mcap")) if path.is_dir() else path.suffix.lower() == ".mcap"


def _why(e: Exception) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text[:160]}" if text else type(e).__name__


def _append(topic: _Topic, msgtype: str, msg: Any, ns: int) -> None:
    topic.ns.append(ns)
    topic.stamps.append(ns / 1_000_000_000)  # Python's int division rounds once: the nearest float to the stamp
    if msgtype == JOINT_STATE:
        topic.names.append(tuple(msg.name))
        topic.position.append(np.asarray(msg.position, dtype=float))
        topic.velocity.append(np.asarray(msg.velocity, dtype=float))
        topic.effort.append(np.asarray(msg.effort, dtype=float))
    else:
        f, m = msg.wrench.force, msg.wrench.torque
        topic.wrench.append((f.x, f.y, f.z, m.x, m.y, m.z))
        topic.frames.append(str(msg.header.frame_id))


def _first_stamps(reader: Any, store: Any, read: set[str], use_log: bool) -> list[float]:
    """The first message's stamp of every JointState and WrenchStamped topic the configuration does not read."""
    out = []
    for conn in reader.connections:
        if conn.msgtype not in (JOINT_STATE, WRENCH) or conn.topic in read:
            continue
        for _, logtime, raw in reader.messages(connections=[conn]):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            ns = int(logtime) if use_log else int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            out.append(ns / 1_000_000_000)
            break
    return out


# ----------------------------------------------------------------------------------------------------------
# Joint states: which slot of a message is which configured joint


def _slots(path: Path, spec: Ros2Topics, topic: _Topic, joints: tuple[str, ...], every: bool
           ) -> tuple[list[np.ndarray | None], tuple[str, ...]]:
    """Per message, the index of each of `joints` in it (None: another publisher's message, naming none of them);
    with `every`, a message naming some but not all is refused. Also the joints the topic gives."""
    wanted = [spec.message_name(j) for j in joints]
    cache: dict[tuple[str, ...], np.ndarray | None] = {}
    slots: list[np.ndarray | None] = []
    given: set[str] = set()
    for k, names in enumerate(topic.names):
        if names not in cache:
            where = {n: i for i, n in enumerate(names)}
            found = [where.get(n) for n in wanted]
            if all(i is None for i in found):
                cache[names] = None
            elif every and any(i is None for i in found):
                missing = next(j for j, i in zip(joints, found) if i is None)
                raise DataError(f"{path}: message {k + 1} of {topic.name} has no joint '{spec.message_name(missing)}' "
                                f"(configured joint {missing}); its joints: {', '.join(names)}")
            else:
                cache[names] = np.array([-1 if i is None else i for i in found])
        slot = cache[names]
        slots.append(slot)
        if slot is not None:
            given.update(j for j, i in zip(joints, slot) if i >= 0)
        if len(topic.position[k]) != len(names):
            raise DataError(f"{path}: message {k + 1} of {topic.name} has {len(names)} joint names but "
                            f"{len(topic.position[k])} positions")
    return slots, tuple(j for j in joints if j in given)


def _field(values: list[np.ndarray], keep: list[int], slots: list[np.ndarray | None], n_names: list[int],
           columns: np.ndarray) -> np.ndarray:
    """(len(keep), len(columns)) of a JointState field; a message whose field is empty or not one value per name
    gives NaN (a bad row)."""
    out = np.full((len(keep), columns.size), np.nan)
    for r, k in enumerate(keep):
        v, index = values[k], slots[k][columns]
        if v.size == n_names[k] and (index >= 0).all():
            out[r] = v[index]
    return out


def _joint_columns(spec: Ros2Topics, config: RobotConfig, joints: tuple[str, ...]) -> list[tuple[str, str]]:
    """(field, column name) of every column the joint-state fields give for `joints`: position first."""
    out = [("position", f"q.{j}") for j in joints]
    if spec.velocity != IGNORE:
        out += [("velocity", f"{spec.velocity}.{j}") for j in joints]
    if spec.effort in ("current", "pwm"):
        motor = dict(spec.effort_motors)
        out += [("effort", f"{spec.effort}.{motor[j]}") for j in joints if j in motor]
    elif spec.effort != IGNORE:
        out += [("effort", f"{spec.effort}.{j}") for j in joints]
    return out


def _joint_values(path: Path, spec: Ros2Topics, config: RobotConfig, topic: _Topic, every: bool
                  ) -> tuple[list[str], np.ndarray, list[int], int]:
    """The columns of a joint-state topic: names, (M, C) values of the kept messages, their indices, and how many
    messages were another publisher's."""
    slots, joints = _slots(path, spec, topic, config.joints, every)
    keep = [k for k, s in enumerate(slots) if s is not None]
    if not keep:
        raise DataError(f"{path}: no message of {topic.name} names a configured joint ({', '.join(config.joints)})")
    n_names = [len(n) for n in topic.names]
    index = {j: i for i, j in enumerate(config.joints)}
    columns = _joint_columns(spec, config, joints)
    blocks, names = [], []
    for name in ("position", "velocity", "effort"):
        wanted = [c for f, c in columns if f == name]
        if not wanted:
            continue
        ids = np.array([index[c.split(".", 1)[1]] if name != "effort" or spec.effort not in ("current", "pwm")
                        else index[_joint_of_motor(spec, c.split(".", 1)[1])] for c in wanted])
        if name != "position" and not any(topic.__dict__[name][k].size for k in keep):
            continue  # the publisher fills no velocity (effort): the columns are absent, as in a CSV without them
        blocks.append(_field(getattr(topic, name), keep, slots, n_names, ids))
        names += wanted
    return names, np.hstack(blocks), keep, len(slots) - len(keep)


def _joint_of_motor(spec: Ros2Topics, motor: str) -> str:
    return next(j for j, m in spec.effort_motors if m == motor)


# ----------------------------------------------------------------------------------------------------------
# The two ways of forming samples


def _on_joint_state_clock(path: Path, spec: Ros2Topics, config: RobotConfig, topics: dict[str, _Topic]
                          ) -> tuple[list[str], np.ndarray, np.ndarray, dict[str, Any]]:
    clock = topics[spec.joint_states[0]]
    names, values, keep, others = _joint_values(path, spec, config, clock, every=True)
    t = np.asarray(clock.stamps)[keep]
    rows = np.asarray(keep)
    inside = np.ones(t.size, bool)
    wrench_columns, info_topics = [], {clock.name: {"type": JOINT_STATE, "messages": len(clock.ns),
                                                    "other_publishers": others}}
    streams = {}
    for w in spec.wrenches:
        stream, dropped = _wrench_stream(path, topics[w.topic], w.frame)
        streams[w.sensor] = stream
        inside &= (t >= stream.stamps[0]) & (t <= stream.stamps[-1])
        info_topics[w.topic] = {"type": WRENCH, "messages": len(topics[w.topic].ns), "dropped_not_increasing": dropped}
    if not inside.any():
        raise DataError(f"{path}: no joint state of {clock.name} falls inside the time span of every wrench topic")
    lo = max((s.stamps[0] for s in streams.values()), default=-np.inf)
    before, after = int((t < lo).sum()), int((~inside).sum() - (t < lo).sum())
    t, values, rows = t[inside], values[inside], rows[inside]
    for w in spec.wrenches:
        wrench_columns.append(_wrench_at(path, spec, streams[w.sensor], t))
        names += [f"ft.{w.sensor}.{c}" for c in FT_CHANNELS]
    data = np.hstack([t[:, None], values, *wrench_columns])
    info = {"clock": clock.name, "wrench_alignment": spec.wrench_alignment if spec.wrenches else None,
            "wrench_tolerance_s": spec.wrench_tolerance if spec.wrenches else None,
            "outside_wrench_span": {"before": before, "after": after}, "topics": info_topics}
    return ["t", *names], data, rows, info


def _wrench_stream(path: Path, topic: _Topic, frame: str) -> tuple[Stream, int]:
    if frame:
        wrong = next((f for f in topic.frames if f != frame), None)
        if wrong is not None:
            raise DataError(f"{path}: a wrench of {topic.name} is in frame '{wrong}', the configuration's is '{frame}'")
    stamps = np.asarray(topic.stamps)
    keep = keep_increasing(stamps)
    if keep.sum() < 2:
        raise DataError(f"{path}: topic {topic.name} has {int(keep.sum())} message(s) with increasing stamps: a wrench "
                        "needs at least two to be taken at the joint states' times")
    return Stream(topic.name, stamps[keep], np.asarray(topic.wrench, dtype=float)[keep]), int((~keep).sum())


def _wrench_at(path: Path, spec: Ros2Topics, stream: Stream, t: np.ndarray) -> np.ndarray:
    """(len(t), 6): the wrench at each stamp of `t` (inside the stream's span), by the configured alignment."""
    ws = stream.stamps
    if spec.wrench_alignment == "nearest":
        j = np.clip(np.searchsorted(ws, t), 1, ws.size - 1)
        nearest = np.where(np.abs(t - ws[j - 1]) <= np.abs(ws[j] - t), j - 1, j)
        distance = np.abs(ws[nearest] - t)
        far = int(np.argmax(distance))
        if distance[far] > spec.wrench_tolerance:
            raise DataError(f"{path}: no message of {stream.name} within {spec.wrench_tolerance:g} s of the joint state "
                            f"at t = {t[far]:.6f} s (the nearest is {distance[far]:.4f} s away; ros2.wrench_tolerance)")
        return stream.values[nearest]
    j = np.clip(np.searchsorted(ws, t, side="right"), 1, ws.size - 1)
    exact = ws[j - 1] == t
    gap = np.where(exact, 0.0, ws[j] - ws[j - 1])
    wide = int(np.argmax(gap))
    if gap[wide] > spec.wrench_tolerance:
        raise DataError(f"{path}: {stream.name} has no message for {gap[wide]:.4f} s around the joint state at t = "
                        f"{t[wide]:.6f} s: too long to interpolate across (ros2.wrench_tolerance is "
                        f"{spec.wrench_tolerance:g} s)")
    return np.column_stack([np.interp(t, ws, stream.values[:, c]) for c in range(6)])


def _on_grid(path: Path, spec: Ros2Topics, config: RobotConfig, topics: dict[str, _Topic], firsts: list[float]
             ) -> tuple[list[str], np.ndarray, np.ndarray, dict[str, Any]]:
    streams, names, info_topics = [], ["t"], {}
    given: dict[str, str] = {}
    for name in spec.joint_states:
        topic = topics[name]
        columns, values, keep, others = _joint_values(path, spec, config, topic, every=False)
        for c in columns:
            if c.startswith("q."):
                joint = c[2:]
                if joint in given:
                    raise DataError(f"{path}: the joint {joint} is in {given[joint]} and in {name}: give each joint once")
                given[joint] = name
        stamps = np.asarray(topic.stamps)[keep]
        order = keep_increasing(stamps)
        streams.append(Stream(name, stamps[order], values[order]))
        names += columns
        info_topics[name] = {"type": JOINT_STATE, "messages": len(topic.ns), "other_publishers": others,
                             "dropped_not_increasing": int((~order).sum())}
    for w in spec.wrenches:
        stream, dropped = _wrench_stream(path, topics[w.topic], w.frame)
        streams.append(stream)
        names += [f"ft.{w.sensor}.{c}" for c in FT_CHANNELS]
        info_topics[w.topic] = {"type": WRENCH, "messages": len(topics[w.topic].ns), "dropped_not_increasing": dropped}
    missing = [j for j in config.joints if j not in given]
    if missing:
        raise DataError(f"{path}: no topic of ros2.joint_states gives the joint {missing[0]}")
    origin = min([*firsts, *(s.stamps[0] for s in streams)])
    assert spec.rate is not None
    grid = uniform_grid(str(path), streams, origin, spec.rate, spec.max_gap, "topic", "ros2.max_gap")
    data = np.hstack([grid[:, None], *(on_grid(grid, s, origin) for s in streams)])
    for s in streams:
        info_topics[s.name].update(first_s=float(s.stamps[0] - origin),
                                   median_interval_s=float(np.median(np.diff(s.stamps))),
                                   max_interval_s=float(np.max(np.diff(s.stamps))))
    info = {"clock": "grid", "rate_hz": spec.rate, "origin_s": float(origin), "topics": info_topics}
    return names, data, np.arange(grid.size), info
