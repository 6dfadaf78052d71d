"""Writing ROS 2 bags (MCAP or SQLite) with `rosbags`, the library dynid.io.rosbag reads them with.

`write_bag` writes a dataset as the configuration's `ros2:` field maps it (the joint-state clock): one
`sensor_msgs/msg/JointState` per sample and one `geometry_msgs/msg/WrenchStamped` per sample and F/T sensor, at the
sample's time. Reading the bag back gives the dataset's samples bit for bit: a stamp is a whole number of
nanoseconds, and a `t` that is not (a time computed on a grid) is refused rather than moved. `BagWriter` writes
single messages (tests/realdata/to_bag.py writes a YARP folder's ports with it, one topic per port).
"""

from __future__ import annotations

import shutil
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import RobotConfig
from ..config.ros2_topics import IGNORE, JOINT_STATE, WRENCH
from ..errors import DataError
from .dataset import Dataset

STORAGES = ("mcap", "sqlite3")
_EMPTY = np.empty(0)


def stamp_ns(t: float) -> int:
    """`t` (s) as whole nanoseconds, such that ns / 1e9 is `t` again; a `DataError` where no such number exists."""
    ns = int((Decimal(repr(float(t))) * 1_000_000_000).to_integral_value())
    if ns / 1_000_000_000 != t:
        raise DataError(f"t = {t!r} s is not a whole number of nanoseconds: a bag's stamps could not give it back")
    return ns


class BagWriter:
    """A rosbag2 being written: `with BagWriter(path, "mcap") as bag: bag.joint_state(...)`."""

    def __init__(self, path: str | Path, storage: str = "mcap") -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore

        if storage not in STORAGES:
            raise ValueError(f"storage must be one of {STORAGES}, got {storage!r}")
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        self.store = get_typestore(Stores.LATEST)
        self.writer = Writer(Path(path), version=Writer.VERSION_LATEST, storage_plugin=plugin)
        self.connections: dict[str, Any] = {}
        t = self.store.types
        self._time, self._header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
        self._joint_state, self._vector = t[JOINT_STATE], t["geometry_msgs/msg/Vector3"]
        self._wrench, self._wrench_stamped = t["geometry_msgs/msg/Wrench"], t[WRENCH]

    def __enter__(self) -> BagWriter:
        self.writer.open()
        return self

    def __exit__(self, kind: object, *rest: object) -> None:
        if kind is None:
            self.writer.close()
            return
        self.writer.abort()  # nothing half-written is left behind: the folder did not exist before
        shutil.rmtree(self.writer.path, ignore_errors=True)

    def _connection(self, topic: str, msgtype: str) -> Any:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        return self.connections[topic]

    def _head(self, ns: int, frame: str) -> Any:
        return self._header(stamp=self._time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)

    def joint_state(self, topic: str, ns: int, names: list[str], position: np.ndarray,
                    velocity: np.ndarray = _EMPTY, effort: np.ndarray = _EMPTY, log_ns: int | None = None) -> None:
        msg = self._joint_state(header=self._head(ns, ""), name=list(names), position=_array(position),
                                velocity=_array(velocity), effort=_array(effort))
        self._write(topic, JOINT_STATE, msg, ns if log_ns is None else log_ns)

    def wrench(self, topic: str, ns: int, frame: str, values: np.ndarray, log_ns: int | None = None) -> None:
        fx, fy, fz, tx, ty, tz = (float(v) for v in values)
        msg = self._wrench_stamped(header=self._head(ns, frame), wrench=self._wrench(
            force=self._vector(x=fx, y=fy, z=fz), torque=self._vector(x=tx, y=ty, z=tz)))
        self._write(topic, WRENCH, msg, ns if log_ns is None else log_ns)

    def _write(self, topic: str, msgtype: str, msg: Any, log_ns: int) -> None:
        self.writer.write(self._connection(topic, msgtype), log_ns, self.store.serialize_cdr(msg, msgtype))


def _array(values: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.float64)  # a row of a column-sliced table is strided


def write_bag(dataset: Dataset, path: str | Path, config: RobotConfig, storage: str = "mcap") -> None:
    """`dataset` as the bag a ROS 2 user of `config`'s robot records (module docstring); `path` must not exist."""
    spec = config.ros2
    if spec is None or spec.rate is not None:
        raise DataError(f"the configuration {config.name} has no 'ros2' field with a joint-state clock to write")
    stamps = [stamp_ns(t) for t in dataset.t.tolist()]
    joints = list(dataset.joints)
    names = [spec.message_name(j) for j in joints]
    velocity = _joint_field(dataset, spec.velocity, joints, dict(spec.effort_motors))
    effort = _joint_field(dataset, spec.effort, joints, dict(spec.effort_motors))
    sensors = [(w, dataset.ft[w.sensor]) for w in spec.wrenches if w.sensor in dataset.ft]
    with BagWriter(path, storage) as bag:
        for k, ns in enumerate(stamps):
            bag.joint_state(spec.joint_states[0], ns, names, dataset.q[k],
                            _EMPTY if velocity is None else velocity[k], _EMPTY if effort is None else effort[k])
            for w, wrench in sensors:
                bag.wrench(w.topic, ns, w.frame, wrench[k])


def _joint_field(dataset: Dataset, use: str, joints: list[str], motors: dict[str, str]) -> np.ndarray | None:
    """(N, J) of what a JointState field carries (`use`: dq, tau, current, pwm or an extra's prefix), or None."""
    if use == IGNORE:
        return None
    if use == "dq":
        return dataset.dq
    family = {"tau": dataset.tau, "current": dataset.current, "pwm": dataset.pwm}.get(use)
    keys = [motors.get(j, "") for j in joints] if use in ("current", "pwm") else joints
    columns = [(family or {}).get(k) if family is not None else dataset.extra.get(f"{use}.{k}") for k in keys]
    if any(c is None for c in columns):
        return None
    return np.column_stack(columns)
