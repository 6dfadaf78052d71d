"""The `ros2:` field of a robot configuration: which topics of a ROS 2 bag hold which channels.

A ROS 2 user records `ros2 bag record /joint_states /wrist_ft` (MCAP or SQLite). The field names the topics and
what the fields of their messages are for this robot:

```yaml
ros2:
  joint_states: /joint_states     # sensor_msgs/msg/JointState: one message is one sample (the sample clock)
  velocity: velocity              # the message's velocity: dq (the recorded q̇), NAME (kept as the extra column
                                  #   NAME.<joint>) or ignore (the default)
  effort: current                 # the message's effort: tau (joint torque, Nm), current (A) or pwm (duty) of the
                                  #   joint's motor, NAME (an extra column) or ignore (the default)
  joint_names: {arm_joint_1: arm_1_joint}   # optional: a message's joint name -> the configured joint
  wrenches:                       # geometry_msgs/msg/WrenchStamped, one topic per F/T sensor
    - {topic: /wrist_ft, sensor: wrist_ft, frame: wrist_ft_link}   # frame: optional, checked against frame_id
  wrench_alignment: linear        # linear (default) or nearest: how a wrench is taken at a joint state's stamp
  wrench_tolerance: 0.05          # s: linear interpolates across at most this gap between two wrench messages;
                                  #   nearest takes a message at most this far from the stamp (default 0.05)
  stamp: header                   # header (default): header.stamp; log: the time the recorder received it
  rate: 100                       # optional, Hz: instead of the joint-state clock, every topic is interpolated
  max_gap: 0.1                    #   onto one uniform grid at this rate, as a YARP folder is (joint_states may
                                  #   then list several topics); max_gap as yarp.max_gap
```

Positions are rad (m for a prismatic joint), velocities rad/s, efforts Nm (N) or the unit of what `effort` names:
ROS's units (REP 103); a wrench is N and Nm in the sensor's frame, the convention of docs/design.md §3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError
from .log_columns import _kind

JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH = "geometry_msgs/msg/WrenchStamped"
IGNORE = "ignore"
VELOCITY_AS = ("dq",)  # what a JointState's velocity may be besides an extra column or ignored
EFFORT_AS = ("tau", "current", "pwm")
ALIGNMENTS = ("linear", "nearest")
STAMPS = ("header", "log")
_KEYS = ("joint_states", "velocity", "effort", "joint_names", "wrenches", "wrench_alignment", "wrench_tolerance",
         "stamp", "rate", "max_gap")


@dataclass(frozen=True)
class WrenchTopic:
    topic: str
    sensor: str
    frame: str = ""  # the frame_id its messages must carry ("" = not checked)


@dataclass(frozen=True)
class Ros2Topics:
    joint_states: tuple[str, ...]  # one topic (the sample clock) unless `rate` is set
    velocity: str = IGNORE  # "dq", an extra column's prefix, or "ignore"
    effort: str = IGNORE  # "tau", "current", "pwm", an extra column's prefix, or "ignore"
    joint_names: tuple[tuple[str, str], ...] = ()  # (name in the messages, configured joint)
    wrenches: tuple[WrenchTopic, ...] = ()
    wrench_alignment: str = "linear"
    wrench_tolerance: float = 0.05  # s
    stamp: str = "header"
    rate: float | None = None  # Hz: the grid mode
    max_gap: float = 0.1  # s, the grid mode
    effort_motors: tuple[tuple[str, str], ...] = ()  # (joint, motor) for effort current or pwm

    def message_name(self, joint: str) -> str:
        """The name the messages give a configured joint."""
        return next((m for m, j in self.joint_names if j == joint), joint)


def parse_ros2(robot: str, value: Any, joints: tuple[str, ...], sensors: tuple[str, ...],
               motor_of: dict[str, dict[str, str] | None]) -> Ros2Topics | None:
    """Validate the `ros2:` field; every problem is a `ConfigError` naming the entry. `motor_of[input][joint]` is the
    motor a `current`/`pwm` effort of the joint is given to (None: no group of that input, or a coupled one)."""
    if value is None:
        return None

    def fld(key: str) -> str:
        return f"{robot}: field 'ros2.{key}'"

    if not isinstance(value, dict):
        raise ConfigError(f"{robot}: field 'ros2' must be a mapping with 'joint_states' (docs/formats.md)")
    unknown = sorted(set(value) - set(_KEYS))
    if unknown:
        raise ConfigError(f"{fld(unknown[0])} is not a known setting (known: {', '.join(_KEYS)})")
    topics = value.get("joint_states")
    topics = [topics] if isinstance(topics, str) else topics
    if not isinstance(topics, list) or not topics or not all(_is_topic(t) for t in topics):
        raise ConfigError(f"{fld('joint_states')} must be a topic name (e.g. /joint_states) or a list of them")
    if len(set(topics)) != len(topics):
        raise ConfigError(f"{fld('joint_states')} lists a topic twice")
    rate = None if value.get("rate") is None else _number(value["rate"], fld("rate"), 1.0, 100000.0)
    max_gap = _number(value.get("max_gap", 0.1), fld("max_gap"), 1e-4, 60.0)
    if rate is None and len(topics) > 1:
        raise ConfigError(f"{fld('joint_states')} lists {len(topics)} topics: one is the sample clock; several need "
                          "'rate' (every topic interpolated onto one grid)")
    if rate is not None and max_gap < 1.0 / rate:
        raise ConfigError(f"{fld('max_gap')} ({max_gap:g} s) must be at least one period of 'rate' ({1 / rate:g} s)")
    velocity = _field_use(value.get("velocity", IGNORE), fld("velocity"), VELOCITY_AS)
    effort = _field_use(value.get("effort", IGNORE), fld("effort"), EFFORT_AS)
    if effort in ("current", "pwm") and motor_of.get(effort) is None:
        raise ConfigError(f"{fld('effort')} is '{effort}', the input of a joint's own motor: the configuration needs an "
                          f"actuation group of input '{effort}' whose joints and motors correspond one to one (not coupled)")
    names = value.get("joint_names", {})
    if not isinstance(names, dict) or not all(isinstance(k, str) and k and isinstance(v, str) for k, v in names.items()):
        raise ConfigError(f"{fld('joint_names')} must map a message's joint name to a configured joint")
    for message_name, joint in names.items():
        if joint not in joints:
            raise ConfigError(f"{fld('joint_names')} maps '{message_name}' to '{joint}', which is not in the "
                              "configuration's 'joints'")
    if len(set(names.values())) != len(names):
        raise ConfigError(f"{fld('joint_names')} maps two names to one joint")
    wrenches = _wrenches(value.get("wrenches", []), fld, sensors, set(topics))
    alignment = value.get("wrench_alignment", "linear")
    if alignment not in ALIGNMENTS:
        raise ConfigError(f"{fld('wrench_alignment')} must be one of {', '.join(ALIGNMENTS)}, got {alignment!r}")
    tolerance = _number(value.get("wrench_tolerance", 0.05), fld("wrench_tolerance"), 1e-6, 10.0)
    stamp = value.get("stamp", "header")
    if stamp not in STAMPS:
        raise ConfigError(f"{fld('stamp')} must be header (the messages' header.stamp) or log (the time the recorder "
                          f"received them), got {stamp!r}")
    pairs = tuple((motor_of.get(effort) or {}).items()) if effort in ("current", "pwm") else ()
    return Ros2Topics(tuple(topics), velocity, effort, tuple(names.items()), wrenches, alignment, tolerance, stamp,
                      rate, max_gap, pairs)


def _wrenches(value: Any, fld: Any, sensors: tuple[str, ...], taken: set[str]) -> tuple[WrenchTopic, ...]:
    if not isinstance(value, list):
        raise ConfigError(f"{fld('wrenches')} must be a list of {{topic, sensor}}")
    out: list[WrenchTopic] = []
    for i, entry in enumerate(value):
        at = fld(f"wrenches[{i}]")
        if not isinstance(entry, dict) or set(entry) - {"topic", "sensor", "frame"} or not {"topic", "sensor"} <= set(entry):
            raise ConfigError(f"{at} must be a mapping with 'topic', 'sensor' and optionally 'frame', got {entry!r}")
        if not _is_topic(entry["topic"]):
            raise ConfigError(f"{at}.topic must be a topic name (e.g. /wrist_ft), got {entry['topic']!r}")
        if entry["topic"] in taken:
            raise ConfigError(f"{at}.topic {entry['topic']} is named twice in 'ros2'")
        taken.add(entry["topic"])
        if entry["sensor"] not in sensors:
            raise ConfigError(f"{at}.sensor names {entry['sensor']!r}, which is not in the configuration's 'ft_sensors'")
        if any(w.sensor == entry["sensor"] for w in out):
            raise ConfigError(f"{at}.sensor '{entry['sensor']}' has a topic already")
        frame = entry.get("frame", "")
        if not isinstance(frame, str):
            raise ConfigError(f"{at}.frame must be a frame name, got {frame!r}")
        out.append(WrenchTopic(entry["topic"], entry["sensor"], frame))
    return tuple(out)


def _field_use(value: Any, where: str, kinds: tuple[str, ...]) -> str:
    """`ignore`, one of `kinds`, or the prefix of an extra column (a name that is no column kind of §4)."""
    if not isinstance(value, str) or not value or any(c in value for c in ". ,\"\n"):
        raise ConfigError(f"{where} must be {', '.join((IGNORE, *kinds))} or a name for extra columns, got {value!r}")
    if value in (IGNORE, *kinds):
        return value
    if _kind(f"{value}.x") is not None or value in ("t", "contact"):
        raise ConfigError(f"{where} is '{value}', a column kind of its own: use {', '.join((IGNORE, *kinds))} or "
                          "another name for extra columns")
    return value


def _is_topic(value: Any) -> bool:
    return isinstance(value, str) and value.startswith("/") and len(value) > 1 and not any(c.isspace() for c in value)


def _number(value: Any, where: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not lo <= value <= hi:
        raise ConfigError(f"{where} must be a number from {lo:g} to {hi:g}, got {value!r}")
    return float(value)
