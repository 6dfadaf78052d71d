"""Robot configuration: everything robot-specific, so that another arm needs a file, never code.

A configuration is a YAML file (format in `robots/README.md`), or the name of one bundled in `dynid/config/robots`
(`icub_right_arm` is the default). `load_config` validates every field and refuses a wrong or incomplete file
with a `ConfigError` whose message names the field, e.g. ``icub_right_arm: actuation[0].coupling: ...``.
"""

from __future__ import annotations

import difflib
import hashlib
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from ..errors import ConfigError
from ..outputs import note_input
from .bus import BusDescription, parse_bus
from .fields import Fields, as_float, shown
from .icub_bus import icub_bus
from .log_columns import LogColumn, parse_columns
from .run_files import RunFile, parse_files
from .urdf_source import URDF_PATH_ENV, resolve_urdf, urdf_if_found  # noqa: F401 - URDF_PATH_ENV: part of this API
from .ros2_topics import Ros2Topics, parse_ros2
from .yarp_ports import YarpLayout, parse_yarp

DEFAULT_ROBOT = "icub_right_arm"
BUNDLED_DIR = Path(__file__).parent / "robots"

InputKind = Literal["pwm", "current", "torque"]
INPUT_KINDS: tuple[str, ...] = ("pwm", "current", "torque")
FT_CHANNEL_NAMES: tuple[str, ...] = ("fx", "fy", "fz", "tx", "ty", "tz")
MAX_GRAVITY = 30.0  # m/s², three times Earth's: a longer vector is in another unit (981: cm/s²)


@dataclass(frozen=True)
class FTSensorConfig:
    """A 6-axis F/T sensor at a fixed joint of the URDF; its frame is the joint's child link frame."""

    name: str
    joint: str
    force_noise: float  # std of one force channel, N
    torque_noise: float  # std of one torque channel, Nm
    channel_noise: tuple[float, ...] = ()  # std per channel fx fy fz tx ty tz (N, Nm), force/torque unless given

    def noise_of(self, k: int) -> float:
        """The noise std of channel k (0..5: fx fy fz tx ty tz)."""
        if self.channel_noise:
            return self.channel_noise[k]
        return self.force_noise if k < 3 else self.torque_noise


@dataclass(frozen=True)
class MotorConfig:
    name: str
    nominal_gain: float  # Nm per unit input (duty or A), a prior for weighting and for the plant
    known_gain: float | None = None  # set when the gain is known (e.g. a datasheet torque constant)


@dataclass(frozen=True)
class ActuationGroup:
    """Joints driven together: motor velocities are `coupling @ joint velocities`.

    `input` says what drives them: `pwm` or `current` (gains unknown unless every motor has `known_gain`),
    or `torque` (a joint torque sensor per joint, no motors).
    """

    name: str
    input: InputKind
    joints: tuple[str, ...]
    motors: tuple[str, ...]
    coupling: np.ndarray  # (n_motors, n_joints); identity when directly driven

    @cached_property  # asked for every chunk of rows (the excitation designer builds thousands)
    def coupled(self) -> bool:
        """Motor friction is a separate parameter only when motors and joints are not one-to-one."""
        n = len(self.joints)
        return self.coupling.shape != (n, n) or not np.allclose(self.coupling, np.eye(n))


@dataclass(frozen=True)
class NoiseConfig:
    """Channel noise levels (standard deviations) used to weight rows of mixed units."""

    pwm: float  # duty fraction
    current: float  # A
    torque: float  # Nm, joint torque sensors
    encoder_step: float  # rad (or m), encoder quantum
    # Per channel, where the configuration gives one value per motor (pwm, current) or joint (torque): the
    # noise of a UR's currents differs tenfold from its base to its wrist.
    per_channel: dict[str, float] = field(default_factory=dict)  # "current.<motor>", "tau.<joint>", ...

    def of(self, kind: str, name: str) -> float:
        """The noise std of one input channel: kind 'pwm', 'current' or 'torque', a motor or joint name."""
        key = f"{'tau' if kind == 'torque' else kind}.{name}"
        return self.per_channel.get(key, float(getattr(self, kind)))


@dataclass(frozen=True)
class MotionLimits:
    """How fast a designed trajectory may move each joint (`limits` in the configuration; `dynid excite`).

    Positions come from the URDF, kept `position_margin` of each joint's range inside both ends; velocities are the
    smaller of the URDF's `<limit velocity>` and these (many URDFs, the iCub's among them, carry placeholders such as
    50000 rad/s); accelerations are these alone (a URDF has none).
    """

    position_margin: float = 0.1  # fraction of each joint's range kept free at both ends
    velocity: dict[str, float] = field(default_factory=dict)  # joint -> rad/s (m/s)
    acceleration: dict[str, float] = field(default_factory=dict)  # joint -> rad/s² (m/s²)


DEFAULT_VELOCITY_LIMIT = 1.5  # rad/s: the fastest joint's peak speed in the simulated reaching moves (1.48)
DEFAULT_ACCELERATION_LIMIT = 4.0  # rad/s²: about the peak of the simulated reaching moves (4.1)


@dataclass(frozen=True)
class RobotConfig:
    name: str
    source: str  # where it was loaded from
    digest: str  # sha256 of the file's bytes: models and datasets record it
    urdf: Path
    base_link: str
    gravity: np.ndarray  # (3,) in the model root's frame: the URDF root, or base_link when re-rooted there
    joints: tuple[str, ...]
    ft_sensors: tuple[FTSensorConfig, ...]
    actuation: tuple[ActuationGroup, ...]
    motors: tuple[MotorConfig, ...]
    noise: NoiseConfig
    can: dict[str, Any] = field(default_factory=dict)
    # The CAN bus as data (config/bus.py): the `bus` section, or the iCub protocol's `can` section expanded; None
    # when the configuration describes no bus (its runs then never cross one: CSV, logs, bags).
    bus: BusDescription | None = None
    # Offline derivative estimator for q̇, q̈ when the data lack them: `method` and its options, passed to
    # dynid.io.derivatives.estimate_derivatives (the window depends on the robot's sampling rate and encoders).
    derivatives: dict[str, Any] = field(default_factory=dict)
    # A headerless log as the controller writes it: one entry per column, with its unit (config/log_columns.py).
    columns: tuple[LogColumn, ...] = ()
    # A run written as a folder of files, one per signal group: each file's columns (config/run_files.py).
    files: tuple[RunFile, ...] = ()
    # The URDF frame a payload's centre of mass is given in (`--payload MASS@x,y,z`); "" = the last moving link.
    payload_frame: str = ""
    # A yarpdatadumper folder: which port holds which joints and sensors (config/yarp_ports.py).
    yarp: YarpLayout | None = None
    # A ROS 2 bag: which topics hold which joints and sensors (config/ros2_topics.py).
    ros2: Ros2Topics | None = None
    # Gravity per sample for a base that tilts: the URDF frame of an accelerometer fixed to the base and its three
    # data columns (m/s², the specific force it measures: −g at rest); "" = the constant `gravity`.
    gravity_imu: str = ""
    gravity_imu_columns: tuple[str, ...] = ()
    # What a designed excitation trajectory may do (dynid excite): position margin, velocity, acceleration.
    limits: MotionLimits = field(default_factory=MotionLimits)
    # `dynid fit --consistent`'s default for this robot ("off", "on" or "pseudo-inertia"): the `fit: {consistent}`
    # field, decided per robot by held-out blocks and runs (docs/consistency.md#default); "off" where it gives none.
    fit_consistent: str = "off"
    # Known change points of the F/T sensors' offsets (s, the data's own seconds): `dynid gaps` takes a step at each
    # as known (dynid.gaps.steps); `--steps` replaces them.
    ft_steps: tuple[float, ...] = ()
    # rt_monitor's contact_limit_s (the `monitor: {contact_limit_s}` field): a contact held longer is its `contact too
    # long` fault, more likely the model no longer fitting than a touch; a robot that holds contacts by design (a leg
    # standing on its feet) sets its own
    contact_limit_s: float = 10.0

    @property
    def motor_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.motors)

    def motor(self, name: str) -> MotorConfig:
        return next(m for m in self.motors if m.name == name)

    def motors_with_input(self, kind: InputKind) -> tuple[str, ...]:
        return tuple(m for g in self.actuation if g.input == kind for m in g.motors)

    def joints_with_input(self, kind: InputKind) -> tuple[str, ...]:
        return tuple(j for g in self.actuation if g.input == kind for j in g.joints)


# ----------------------------------------------------------------------------------------------------------
# Loading and validation


def resolve_config_path(robot: str | Path) -> Path:
    """A path to a YAML file, or the name of a bundled configuration."""
    path = Path(robot)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise ConfigError(f"robot configuration file not found: {path}")
        return path
    bundled = BUNDLED_DIR / f"{robot}.yaml"
    if not bundled.is_file():
        names = ", ".join(sorted(p.stem for p in BUNDLED_DIR.glob("*.yaml")))
        raise ConfigError(f"unknown robot configuration '{robot}': not a file, and not one of the bundled ({names})")
    return bundled


def robot_argument(config: RobotConfig) -> str:
    """What `--robot` takes to load `config` again: its name where it is the bundled one, else its file."""
    bundled = BUNDLED_DIR / f"{config.name}.yaml"
    source = Path(config.source)
    return config.name if bundled.is_file() and source.resolve() == bundled.resolve() else str(source.resolve())


def bundled_configs() -> list[str]:
    return sorted(p.stem for p in BUNDLED_DIR.glob("*.yaml"))


def _noise(f: Fields, motors: tuple[str, ...], joints: tuple[str, ...]) -> NoiseConfig:
    """`noise`: each input kind one number, or a mapping with a value per motor (pwm, current) or joint (torque)."""
    n = f.sub("noise", {}).only("pwm", "current", "torque", "encoder_step")
    defaults = {"pwm": 0.002, "current": 0.01, "torque": 0.05}
    scalar: dict[str, float] = {}
    per_channel: dict[str, float] = {}
    for kind, default in defaults.items():
        value = n.raw(kind, default)
        if not isinstance(value, dict):
            scalar[kind] = n.number(kind, default, positive=True)
            continue
        names = joints if kind == "torque" else motors
        per = n.sub(kind).only(*names)
        missing = [x for x in names if not per.has(x)]
        if missing:
            raise per.fail(missing[0], f"is missing: a per-channel '{kind}' noise needs every "
                           f"{'joint' if kind == 'torque' else 'motor'} ({', '.join(names)})")
        for x in names:
            per_channel[f"{'tau' if kind == 'torque' else kind}.{x}"] = per.number(x, positive=True)
        scalar[kind] = float(np.median([per_channel[f"{'tau' if kind == 'torque' else kind}.{x}"] for x in names]))
    return NoiseConfig(
        pwm=scalar["pwm"], current=scalar["current"], torque=scalar["torque"],
        encoder_step=n.number("encoder_step", 2 * math.pi / 65536, positive=True),
        per_channel=per_channel,
    )


def load_config(robot: str | Path = DEFAULT_ROBOT, urdf: str | Path | None = None,
                need_urdf: bool = True) -> RobotConfig:
    """Load and validate a robot configuration (a path or a bundled name); `urdf` replaces its URDF (--urdf).
    `need_urdf` False: a URDF that cannot be found is left unresolved (`urdf` an empty path), for what reads the
    configuration alone (the bus: `export --dbc`, `--monitor-config`)."""
    path = resolve_config_path(robot)
    text = path.read_bytes()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise ConfigError(f"{path}: not valid YAML{where}") from None
    # PyYAML's constructors let ValueError out (a date such as 2001-13-45, an integer of more than 4300 digits),
    # and its composer recurses once per level of nesting.
    except (ValueError, RecursionError) as e:
        raise ConfigError(f"{path}: not valid YAML: {e.__class__.__name__}: {str(e)[:80]}") from None
    if isinstance(data, dict) and {"robot", "parameters"} <= data.keys():  # JSON is YAML: a model file, given as --robot
        raise ConfigError(f"{path} is a model file of `dynid fit`, not a robot configuration: give it as --model where "
                          f"the command takes one; its robot is '{data['robot'].get('name', '?')}'"
                          if isinstance(data["robot"], dict) else f"{path} is a model file, not a robot configuration")
    root = Fields(path.stem, "", data)
    name = root.string("name")
    f = Fields(name, "", data).only(
        "name", "urdf", "base_link", "gravity", "joints", "ft_sensors", "motors", "actuation", "noise", "can", "bus",
        "derivatives", "columns", "files", "payload_frame", "yarp", "ros2", "limits", "fit", "ft_steps", "monitor",
    )

    joints = f.strings("joints")
    if not joints:
        raise f.fail("joints", "must list at least one moving joint")

    sensors = []
    for s in f.items("ft_sensors", []):
        s.only("name", "joint", "noise")
        noise = s.sub("noise", {}).only("force", "torque", *FT_CHANNEL_NAMES)
        force, torque = noise.number("force", 0.1, positive=True), noise.number("torque", 0.005, positive=True)
        # A channel may have its own value (a real sensor's axes differ: the iCub leg's fz is noisier than fx)
        channels = tuple(noise.number(c, force if k < 3 else torque, positive=True) for k, c in enumerate(FT_CHANNEL_NAMES))
        sensors.append(
            FTSensorConfig(
                name=s.string("name"),
                joint=s.string("joint"),
                force_noise=force,
                torque_noise=torque,
                channel_noise=channels if any(noise.has(c) for c in FT_CHANNEL_NAMES) else (),
            )
        )
    if len({s.name for s in sensors}) != len(sensors):
        raise f.fail("ft_sensors", "lists a sensor name twice")

    motors = []
    motor_fields = f.sub("motors", {})
    for mname, _ in motor_fields.data.items():
        m = motor_fields.sub(str(mname)).only("nominal_gain", "known_gain")
        known = m.number("known_gain", positive=True) if m.has("known_gain") else None
        motors.append(
            MotorConfig(
                name=str(mname),
                nominal_gain=m.number("nominal_gain", positive=True),
                known_gain=known,
            )
        )
    motor_names = [m.name for m in motors]

    groups: list[ActuationGroup] = []
    seen_joints: set[str] = set()
    seen_motors: set[str] = set()
    for g in f.items("actuation", []):
        g.only("name", "input", "joints", "motors", "coupling")
        kind = g.string("input")
        if kind not in INPUT_KINDS:
            raise g.fail("input", f"must be one of {', '.join(INPUT_KINDS)}, got '{kind}'")
        gj = g.strings("joints")
        if not gj:  # a group that drives nothing is a mistake, and a 0x0 coupling matrix
            raise g.fail("joints", "must list at least one joint")
        for j in gj:
            if j not in joints:
                raise g.fail("joints", f"names '{j}', which is not in 'joints'")
            if j in seen_joints:
                raise g.fail("joints", f"names '{j}', which another actuation group already drives")
        seen_joints.update(gj)
        if kind == "torque":
            if g.has("motors"):
                raise g.fail("motors", "must be absent for input 'torque' (joint torque sensors have no motors)")
            gm: tuple[str, ...] = ()
            coupling = np.eye(len(gj))
        else:
            gm = g.strings("motors")
            for m in gm:
                if m not in motor_names:
                    raise g.fail("motors", f"names '{m}', which is not under 'motors'")
                if m in seen_motors:
                    raise g.fail("motors", f"names '{m}', which another actuation group already uses")
            seen_motors.update(gm)
            if g.has("coupling"):
                coupling = g.matrix("coupling", (len(gm), len(gj)))
            elif len(gm) == len(gj):
                coupling = np.eye(len(gj))
            else:
                raise g.fail("coupling", f"is missing, and {len(gm)} motors cannot drive {len(gj)} joints one-to-one")
            if np.linalg.matrix_rank(coupling) < len(gj):
                raise g.fail("coupling", "must have full column rank (every joint driven)")
        groups.append(ActuationGroup(g.string("name"), kind, gj, gm, coupling))  # type: ignore[arg-type]
    unused = [m for m in motor_names if m not in seen_motors]
    if unused:
        raise f.fail("motors", f"defines {unused[0]}, which no actuation group uses")

    gravity = f.raw("gravity", [0.0, 0.0, -9.81])
    imu_frame, imu_columns = "", ()
    if isinstance(gravity, dict):  # per sample, from an accelerometer fixed to the base (a base that tilts)
        spec = f.sub("gravity").only("imu", "columns", "magnitude")
        imu_frame = spec.string("imu")
        imu_columns = spec.strings("columns", ["imu.ax", "imu.ay", "imu.az"])
        if len(imu_columns) != 3 or len(set(imu_columns)) != 3:
            raise spec.fail("columns", f"must name three different columns (x, y, z), got {list(imu_columns)}")
        gravity = [0.0, 0.0, -spec.number("magnitude", 9.81, positive=True)]  # the nominal: export, CAD checks
    try:
        g_arr = np.array(gravity, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise f.fail("gravity", f"must be three numbers, got {gravity!r}") from None
    if g_arr.shape != (3,) or not np.all(np.isfinite(g_arr)):
        raise f.fail("gravity", f"must be three finite numbers, got {gravity!r}")
    if np.linalg.norm(g_arr) > MAX_GRAVITY:
        raise f.fail("gravity", f"is {np.linalg.norm(g_arr):g} m/s² long: gravity is in m/s² (9.81 on Earth)")

    can = f.raw("can", {})
    if not isinstance(can, dict):
        raise f.fail("can", "must be a mapping")
    if f.has("can") and f.has("bus"):
        raise f.fail("bus", "and 'can' both describe the bus: give one ('can' is the iCub protocol's form of 'bus')")
    sensor_names = tuple(s.name for s in sensors)
    inputs = {m: g.input for g in groups for m in g.motors}
    can_map = _validate_can(f, joints, inputs, sensor_names)
    torques = tuple(j for g in groups if g.input == "torque" for j in g.joints)
    if f.has("bus"):
        bus = parse_bus(f.sub("bus"), joints, inputs, sensor_names, torques=torques)
    elif can_map:
        bus = parse_bus(Fields(name, "can", icub_bus(can_map, sensor_names)), joints, inputs, sensor_names, "can",
                        torques=torques)
    else:
        bus = None

    note_input(path, "the robot configuration")
    resolved = resolve_urdf(f, path.parent, urdf) if need_urdf else urdf_if_found(f, path.parent, urdf)
    if resolved != Path():  # an unresolved URDF (need_urdf False) is no file
        note_input(resolved, f"{name}'s URDF")
    return RobotConfig(
        name=name,
        source=str(path),
        digest=hashlib.sha256(text).hexdigest(),
        urdf=resolved,
        base_link=f.string("base_link"),
        gravity=g_arr,
        gravity_imu=imu_frame,
        gravity_imu_columns=tuple(imu_columns),
        joints=joints,
        ft_sensors=tuple(sensors),
        actuation=tuple(groups),
        motors=tuple(motors),
        noise=_noise(f, tuple(motor_names), joints),
        can=can_map,
        bus=bus,
        derivatives=_derivatives(f),
        columns=parse_columns(name, f.raw("columns", None)),
        files=parse_files(name, f.raw("files", None)),
        payload_frame=f.string("payload_frame") if f.has("payload_frame") else "",
        yarp=parse_yarp(name, f.raw("yarp", None), joints, tuple(s.name for s in sensors)),
        ros2=parse_ros2(name, f.raw("ros2", None), joints, tuple(s.name for s in sensors), _motor_of(groups)),
        limits=_limits(f, joints),
        fit_consistent=_fit_consistent(f),
        ft_steps=_ft_steps(f, bool(sensors)),
        contact_limit_s=_contact_limit(f),
    )


CONSISTENT_MODES = ("off", "on", "pseudo-inertia")  # `dynid fit --consistent`'s choices


def _fit_consistent(f: Fields) -> str:
    """`fit: {consistent: on|off|pseudo-inertia}`: the robot's default for `dynid fit --consistent`. YAML 1.1 reads a
    bare on/off as a boolean, so true/false are taken as on/off too."""
    section = f.sub("fit", {}).only("consistent")
    value = section.raw("consistent", "off")
    if isinstance(value, bool):
        value = "on" if value else "off"
    if value not in CONSISTENT_MODES:
        raise section.fail("consistent", f"must be one of {', '.join(CONSISTENT_MODES)}, got {value!r}")
    return str(value)


CONTACT_LIMIT_S = (0.1, 86400.0, 10.0)  # rt_monitor's contact_limit_s: its range (monitor_config.hpp), its default


def _contact_limit(f: Fields) -> float:
    """`monitor: {contact_limit_s: S}`: a contact held longer is the monitor's `contact too long` fault."""
    section = f.sub("monitor", {}).only("contact_limit_s")
    low, high, default = CONTACT_LIMIT_S
    value = section.number("contact_limit_s", default, positive=True)
    if not low <= value <= high:
        raise section.fail("contact_limit_s", f"must be {low:g} to {high:g} s (the monitor's range), got {value:g}")
    return value


def _ft_steps(f: Fields, has_sensor: bool) -> tuple[float, ...]:
    """`ft_steps`: a list of finite seconds, strictly increasing, on a robot with an F/T sensor."""
    value = f.raw("ft_steps", [])
    if not isinstance(value, list) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(as_float(v)) for v in value):
        raise f.fail("ft_steps", f"must be a list of change points in seconds, got {shown(value)}")
    if any(b <= a for a, b in zip(value, value[1:])):
        raise f.fail("ft_steps", f"must increase, got {shown(value)}")
    if value and not has_sensor:
        raise f.fail("ft_steps", "names change points of F/T offsets, but the robot has no F/T sensor")
    return tuple(float(v) for v in value)


def _motor_of(groups: list[ActuationGroup]) -> dict[str, dict[str, str] | None]:
    """Per motor input (current, pwm): joint -> the motor that drives it alone, or None where a group of that input
    is coupled (a motor's input is then no joint's effort)."""
    out: dict[str, dict[str, str] | None] = {}
    for kind in ("current", "pwm"):
        of: dict[str, str] | None = {}
        for g in groups:
            if g.input != kind:
                continue
            if len(g.motors) != len(g.joints) or not np.array_equal(g.coupling, np.eye(len(g.joints))):
                of = None
                break
            of.update(zip(g.joints, g.motors))
        out[kind] = of if of else None
    return out


def _limits(f: Fields, joints: tuple[str, ...]) -> MotionLimits:
    """`limits`: {position_margin, velocity, acceleration}; each rate one number or a value per joint."""
    spec = f.sub("limits", {}).only("position_margin", "velocity", "acceleration")
    margin = spec.number("position_margin", 0.1)
    if not 0.0 <= margin < 0.5:
        raise spec.fail("position_margin", f"must be a fraction of the range from 0 to under 0.5, got {margin!r}")
    rates: dict[str, dict[str, float]] = {}
    for kind, default in (("velocity", DEFAULT_VELOCITY_LIMIT), ("acceleration", DEFAULT_ACCELERATION_LIMIT)):
        value = spec.raw(kind, default)
        if not isinstance(value, dict):
            rates[kind] = dict.fromkeys(joints, spec.number(kind, default, positive=True))
            continue
        per = spec.sub(kind).only(*joints)
        rates[kind] = {j: per.number(j, default, positive=True) for j in joints}
    return MotionLimits(margin, rates["velocity"], rates["acceleration"])


_DERIVATIVE_OPTIONS: dict[str, type] = {
    "method": str, "window_s": float, "polyorder": int, "d": float, "max_window": int, "causal": bool,
}
DERIVATIVE_METHODS = ("savgol", "adaptive")  # dynid.io.derivatives.METHODS (the config layer does not import io)


def _derivatives(f: Fields) -> dict[str, Any]:
    """Options of dynid.io.derivatives.estimate_derivatives, each checked for its type."""
    d = f.sub("derivatives", {}).only(*_DERIVATIVE_OPTIONS)
    out: dict[str, Any] = {}
    for key, value in d.data.items():
        kind = _DERIVATIVE_OPTIONS[key]
        if kind is float:
            out[key] = d.number(key, positive=True)
            continue
        if kind is int and (isinstance(value, bool) or not isinstance(value, int) or value <= 0):
            raise d.fail(key, f"must be a positive integer, got {value!r}")
        if not isinstance(value, kind):
            raise d.fail(key, f"must be a {kind.__name__}, got {value!r}")
        if key == "method" and value not in DERIVATIVE_METHODS:
            near = difflib.get_close_matches(value, DERIVATIVE_METHODS, n=1)
            raise d.fail(key, f"must be one of {', '.join(DERIVATIVE_METHODS)}, got {value!r}"
                         + (f" (did you mean '{near[0]}'?)" if near else ""))
        out[key] = value
    return out


def _validate_can(f: Fields, joints: tuple[str, ...], motors: dict[str, str], sensors: tuple[str, ...]) -> dict:
    """The CAN mapping: buses, and which board (bus, address) carries which joint, motor or sensor."""
    if not f.has("can"):
        return {}
    can = f.sub("can").only("buses", "strain", "motor_control", "skin")
    buses = can.strings("buses")
    used_addresses: set[tuple[str, int, int]] = set()

    def address(b: Fields, cls: int) -> int:
        bus = b.string("bus")
        if bus not in buses:
            raise b.fail("bus", f"names '{bus}', which is not in can.buses")
        a = b.raw("address")
        if isinstance(a, bool) or not isinstance(a, int) or not 0 < a < 16:
            raise b.fail("address", f"must be an integer board address in 1..15, got {a!r}")
        if (bus, cls, a) in used_addresses:
            raise b.fail("address", f"is used twice on bus {bus}")
        used_addresses.add((bus, cls, a))
        return a

    strain = []
    for b in can.items("strain", []):
        b.only("sensor", "bus", "address", "full_scale", "saturation_flags")
        address(b, 3)
        if not isinstance(b.raw("saturation_flags", False), bool):
            raise b.fail("saturation_flags", "must be true (7-byte frames, flags in byte 6) or false (6 bytes)")
        sensor = b.string("sensor")
        if sensor not in sensors:
            raise b.fail("sensor", f"names '{sensor}', which is not in ft_sensors")
        fs = b.raw("full_scale")
        if not (isinstance(fs, list) and len(fs) == 6 and all(  # finite: an inf full scale made every F/T value nan
                not isinstance(x, bool) and isinstance(x, (int, float)) and 0 < as_float(x) < math.inf for x in fs)):
            raise b.fail("full_scale", f"must be six positive numbers (N, N, N, Nm, Nm, Nm), got {fs!r}")
        strain.append(b.data)
    if not strain:  # config/icub_bus.py: the first strain board's torque half clocks every sample
        raise can.fail("strain", "must list at least one strain board: the first one's frames clock the sample")
    mc = []
    for b in can.items("motor_control", []):
        b.only("bus", "address", "pwm_full_scale", "axes")
        address(b, 1)
        axes = b.items("axes")
        if not 1 <= len(axes) <= 2:
            raise b.fail("axes", f"must list 1 or 2 axes (a board serves two), got {len(axes)}")
        for ax in axes:
            ax.only("joint", "motor", "ticks_per_degree", "zero_deg")
            j = ax.string("joint")
            if j not in joints:
                raise ax.fail("joint", f"names '{j}', which is not in 'joints'")
            m = ax.raw("motor", None)
            if m is not None and m not in motors:
                raise ax.fail("motor", f"names '{m}', which is not under 'motors'")
            if m is not None and motors[m] != "pwm":  # PID_VAL carries a duty cycle, nothing else
                raise ax.fail("motor", f"names '{m}', whose input is {motors[m]}: the iCub board's PID_VAL frame carries "
                              "PWM; describe this bus with 'bus:' instead (docs/formats.md)")
            ax.number("ticks_per_degree", positive=True)
            ax.number("zero_deg", 0.0)
        b.number("pwm_full_scale", positive=True)
        mc.append(b.data)
    skin = []
    for b in can.items("skin", []):
        b.only("bus", "address", "patch", "links", "side")
        address(b, 4)
        side = b.string("side")
        if side not in ("distal", "proximal"):
            raise b.fail("side", f"must be 'distal' or 'proximal' of the F/T sensor, got '{side}'")
        b.string("patch")
        if b.has("links") and not b.strings("links"):
            raise b.fail("links", "must list at least one link the patch covers")
        skin.append(b.data)
    return {"buses": list(buses), "strain": strain, "motor_control": mc, "skin": skin}
