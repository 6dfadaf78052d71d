"""The coefficient file: what `dynid export` hands to the real-time monitor (rt_monitor/README.md).

Layout (all integers little-endian):

    0    8 bytes   magic "DYNIDCOF"
    8    uint32    format version (FILE_VERSION)
    12   uint32    payload length L
    16   L bytes   payload: an LCM-encoded dynid.coefficients_t (rt_monitor/lcmtypes/coefficients_t.lcm; it starts
                   with the type's 8-byte fingerprint)
    16+L uint32    CRC-32 (IEEE 802.3, zlib's) of bytes 0 … 16+L−1

`build_coefficients` fills the payload from an identified model and the online calibration
(`dynid.detect.online`); `read_coefficients` checks a file as the C++ loader does; `describe` prints one readably.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..detect.momentum import causal_velocity_weights
from ..detect.momentum_t2 import ISOLATION_SIGMAS, MomentumDetector
from ..detect.online import FixedLagSavitzkyGolay
from ..errors import DataError
from ..identify.supply import SupplyTracking, tracked
from ..io.dataset import atomic_write
from ..robot.effects import EXPORTABLE, Effect
from ..robot.model import RobotModel
from ..robot.outputs import output_channels
from ..robot.regressors.stack import group_row_maps, group_rows
from ..version import __version__
from .capacity import capacity, file_version
from .lcm_coefficients import coefficients_t
from .plausible import Implausible, check_plausible

MAGIC = b"DYNIDCOF"
# rt_monitor/include/rt_monitor/capacity.hpp names the versions (6: the combined detector). Older files are refused,
# named: re-export them.
FILE_VERSION = file_version()
HEADER = struct.Struct("<8sII")
# The monitor's compile-time filter capacity (kMaxWindow, rt_monitor/include/rt_monitor/capacity.hpp): a longer
# window was exported without a word and the monitor then refused the file (exit 17).
MAX_WINDOW = capacity().window
KIND = {"ft": 0, "input": 1, "torque": 2}
RESIDUAL = {"acceleration": 0, "momentum": 1, "combined": 2}
JOINT_FIXED, JOINT_REVOLUTE, JOINT_PRISMATIC = 0, 1, 2
NO_LIMIT = 1e6  # rad or m: the range written for a joint without limits (plausibility.hpp's kMaxJointRange)
# Events, not samples: the filtered residuals are autocorrelated over the filter window, so single samples above
# T²_α come in bursts. On the default simulated runs, 5 samples gave an onset every 3 s on contact-free data;
# 10 gave none there and caught 21 of the contact run's 28 episodes (rt_monitor/README.md).
# The default debounce is a time, counted in samples at the file's rate: 10 and 100 samples at 1 kHz, 1 and 10 at
# 100 Hz (where 10 samples, 100 ms, outlast the UR10e's collisions: the monitor found none of 11)
DEFAULT_ONSET_S, DEFAULT_END_S, DEFAULT_HYSTERESIS = 0.010, 0.100, 0.5


def wrap(payload: bytes, version: int = FILE_VERSION) -> bytes:
    head = HEADER.pack(MAGIC, version, len(payload)) + payload
    return head + struct.pack("<I", zlib.crc32(head) & 0xFFFFFFFF)


def unwrap(data: bytes, where: str = "coefficient file") -> bytes:
    """The payload of a wrapped file; DataError on a bad magic, version, length or CRC."""
    if len(data) < HEADER.size + 4:
        raise DataError(f"{where}: truncated ({len(data)} bytes, shorter than the header)")
    magic, version, length = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise DataError(f"{where}: not a dynid coefficient file (bad magic)")
    if version != FILE_VERSION:  # older: the model exports again; newer: this dynid is the old one
        remedy = ("export the model again (dynid export)" if version < FILE_VERSION else
                  "a newer dynid wrote it: read it with that dynid, or export with this one")
        raise DataError(f"{where}: format version {version}, this dynid reads {FILE_VERSION}: {remedy}")
    if len(data) != HEADER.size + length + 4:
        raise DataError(f"{where}: truncated or padded ({len(data)} bytes, the header says {HEADER.size + length + 4})")
    (crc,) = struct.unpack_from("<I", data, HEADER.size + length)
    if zlib.crc32(data[: HEADER.size + length]) & 0xFFFFFFFF != crc:
        raise DataError(f"{where}: CRC mismatch (the file is corrupt)")
    return data[HEADER.size : HEADER.size + length]


def read_coefficients(path: str | Path) -> coefficients_t:
    path = Path(path)
    if not path.is_file():
        raise DataError(f"coefficient file not found: {path}")
    payload = unwrap(path.read_bytes(), str(path))
    try:
        c = coefficients_t.decode(payload)
    except (ValueError, struct.error) as e:
        raise DataError(f"{path}: payload is not a dynid.coefficients_t ({e})") from None
    try:
        check_plausible(c)
    except Implausible as e:
        raise Implausible(f"{path}: {e}") from None
    return c


def write_coefficients(c: coefficients_t, path: str | Path) -> int:
    """Write the file atomically; one the monitor would refuse as implausible is never written (Implausible)."""
    check_plausible(c)
    data = wrap(c.encode())
    atomic_write(Path(path), lambda f: f.write(data))
    return len(data)


# ------------------------------------------------------------------------------------------------------------


def _joint(model: RobotModel, jid: int) -> tuple[int, np.ndarray]:
    """(type, axis) of a Pinocchio joint of the split model, as the monitor knows joints."""
    jm = model.pin_model.joints[jid]
    name = jm.shortname()
    if name == "JointModelFreeFlyer" and model.pin_model.names[jid] in {s.joint for s in model.config.ft_sensors}:
        return JOINT_FIXED, np.zeros(3)
    unit = {"X": [1.0, 0, 0], "Y": [0, 1.0, 0], "Z": [0, 0, 1.0]}
    for prefix, kind in (("JointModelR", JOINT_REVOLUTE), ("JointModelP", JOINT_PRISMATIC)):
        if name in (prefix + "X", prefix + "Y", prefix + "Z"):
            return kind, np.array(unit[name[-1]])
        if name in (prefix + "UBX", prefix + "UBY", prefix + "UBZ") and kind == JOINT_REVOLUTE:
            return kind, np.array(unit[name[-1]])
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.asarray(jm.extract().axis, float)
        return (JOINT_REVOLUTE if "Revolute" in name else JOINT_PRISMATIC), axis / np.linalg.norm(axis)
    raise DataError(f"the monitor does not support joint '{model.pin_model.names[jid]}' ({name})")


@dataclass(frozen=True)
class EventSettings:
    """How the monitor turns T² samples into contact events."""

    debounce_on: int | None = None  # samples above T²_α for an onset (None: DEFAULT_ONSET_S at the file's rate)
    debounce_off: int | None = None  # samples below the hysteresis level for an end (None: DEFAULT_END_S)
    hysteresis: float = DEFAULT_HYSTERESIS  # the end level as a fraction of T²_α

    def at(self, period: float) -> EventSettings:
        """The counts at a sample period of `period` s: given ones as they are, the defaults' times in samples."""
        on = self.debounce_on if self.debounce_on is not None else max(1, round(DEFAULT_ONSET_S / period))
        off = self.debounce_off if self.debounce_off is not None else max(1, round(DEFAULT_END_S / period))
        return EventSettings(int(on), int(off), self.hysteresis)


@dataclass(frozen=True)
class MonitorDetector:
    """The monitor's T²: Λ and the thresholds, calibrated through its own filter (dynid.detect.online)."""

    variance: np.ndarray  # Λ (n_out,)
    threshold: float  # T²_α
    ft_thresholds: dict[str, float]  # sensor -> its channels' share of T² at α (the side of that sensor)
    alpha: float
    min_speed: float
    samples: int  # calibration samples
    events: EventSettings = EventSettings()
    tau_variance: np.ndarray | None = None  # (n_joints,) of τ_ext from the residuals; None: no isolation


@dataclass(frozen=True)
class MonitorObserver:
    """The monitor's momentum observer (dynid.detect.momentum), calibrated on the q̇ the monitor will have."""

    detector: MomentumDetector
    velocity_window: int  # samples of the causal q̇ estimator
    band: dict  # {(kind, owner): (fc_pos, fc_neg)}: the static-friction band, widened (friction_band)
    measured: bool = False  # q̇ the robot's own, from its bus (dq.J), else estimated from q


@dataclass(frozen=True)
class Provenance:
    """Where the coefficients come from, written into the file for the monitor's start-up line."""

    model_sha256: str = ""
    data_sha256: str = ""
    estimator: str = ""


def check_monitor_supports(model: RobotModel, effects: Sequence[Effect] = ()) -> None:
    """Refuse a robot the monitor's core cannot run, before any data is read or anything is written: every count
    within the compiled capacity (rt_monitor/include/rt_monitor/capacity.hpp), every joint of a kind it knows."""
    cfg, cap = model.config, capacity()
    counts = (("joints", len(cfg.joints), cap.joints), ("F/T sensors", len(cfg.ft_sensors), cap.sensors),
              ("bodies", len(model.bodies), cap.bodies), ("motors", len(_motors(model)), cap.motors),
              ("output channels", len(output_channels(model)), cap.outputs), ("effects", len(effects), cap.effects))
    for what, n, most in counts:
        if n > most:
            raise DataError(f"{cfg.name} has {n} {what}; the monitor holds at most {most} (rt_monitor/include/"
                            "rt_monitor/capacity.hpp: raise it and rebuild)")
    for k, b in enumerate(model.bodies):
        if b.joint_id != k + 1:
            raise DataError("the model's bodies are not in joint order")
        _joint(model, b.joint_id)  # a joint the monitor cannot move is refused here, named


def _motors(model: RobotModel) -> list[str]:
    return [m for g in model.config.actuation if g.input != "torque" for m in g.motors]


def check_window(est: FixedLagSavitzkyGolay) -> None:
    """Refuse a filter window the monitor cannot hold (`MAX_WINDOW`), before anything is calibrated or written."""
    if est.window > MAX_WINDOW:
        raise DataError(f"the monitor's filter holds at most {MAX_WINDOW} samples, this one {est.window} "
                        f"({1e3 * est.window * est.sample_period:.3g} ms at {1 / est.sample_period:.6g} Hz): give "
                        f"--window {MAX_WINDOW} or fewer")


def build_coefficients(model: RobotModel, phi: np.ndarray, detector: MonitorDetector, est: FixedLagSavitzkyGolay,
                       provenance: Provenance = Provenance(), effects: Sequence[Effect] = (),
                       tracking: SupplyTracking | None = None, observer: MonitorObserver | None = None,
                       residual: str = "acceleration", combined_scale: float = 0.0,
                       fit_range: np.ndarray | None = None) -> coefficients_t:
    """The payload of the coefficient file for Φ (with Stribeck and spring effects), the detector and the filter,
    the momentum observer, and the combined detector's κ (`combined_scale`, 0: none; dynid.detect.combined);
    `residual` names what the monitor runs (the observer needs `observer`, the combined detector both);
    `fit_range` (joints, 2) rad: the postures the fit saw (dynid.identify.transfer.fit_ranges), None: not recorded."""
    if residual not in RESIDUAL or (residual != "acceleration" and observer is None):
        raise DataError(f"the monitor's residual is acceleration, or momentum or combined with an observer, not "
                        f"'{residual}'")
    if not (np.isfinite(combined_scale) and combined_scale >= 0) or (residual == "combined" and combined_scale == 0):
        raise DataError(f"the combined detector needs a positive combined_scale, not {combined_scale}")
    if combined_scale > 0 and observer is None:
        raise DataError("a combined_scale needs the observer")
    cfg, layout, pm = model.config, model.layout, model.pin_model
    exportable_effects(effects)
    check_monitor_supports(model, effects)
    check_window(est)
    c = coefficients_t()
    c.robot_name, c.config_digest, c.dynid_version = cfg.name, cfg.digest, __version__
    c.model_sha256, c.data_sha256, c.estimator = provenance.model_sha256, provenance.data_sha256, provenance.estimator

    joints = list(cfg.joints)
    c.n_joints, c.joint_names = len(joints), joints
    c.joint_limits = [[max(lo, -NO_LIMIT), min(hi, NO_LIMIT)] for lo, hi in (model.joint_limits[j] for j in joints)]
    if fit_range is not None and (np.shape(fit_range) != (len(joints), 2) or not np.all(np.isfinite(fit_range))):
        raise DataError(f"the fit's joint ranges must be ({len(joints)}, 2) finite values")
    c.fit_range = ([[-NO_LIMIT, NO_LIMIT]] * len(joints) if fit_range is None else
                   np.clip(np.asarray(fit_range, float), -NO_LIMIT, NO_LIMIT).tolist())
    c.n_bodies = len(model.bodies)
    c.body_names = [b.name for b in model.bodies]
    c.parent, c.joint_type, c.joint_index, c.axis, c.rotation, c.translation, c.inertial = [], [], [], [], [], [], []
    inertial = phi[layout.span("inertial")]
    for k, b in enumerate(model.bodies):
        kind, axis = _joint(model, b.joint_id)
        c.parent.append(int(pm.parents[b.joint_id]) - 1)
        c.joint_type.append(kind)
        c.joint_index.append(model.joint_ids.index(b.joint_id) if kind != JOINT_FIXED else -1)
        c.axis.append(axis.tolist())
        M = pm.jointPlacements[b.joint_id]
        c.rotation.append(np.asarray(M.rotation).ravel().tolist())
        c.translation.append(np.asarray(M.translation).tolist())
        c.inertial.append(inertial[10 * k : 10 * k + 10].tolist())
    c.gravity = np.asarray(pm.gravity.linear).tolist()
    sensors = list(cfg.ft_sensors)
    c.n_sensors, c.sensor_names = len(sensors), [s.name for s in sensors]
    c.sensor_body = [[b.name for b in model.bodies].index(model.sensor_bodies[s.name].name) for s in sensors]

    col = {j: i for i, j in enumerate(joints)}
    motors = _motors(model)
    c.n_motors, c.motor_names = len(motors), motors
    c.motor_velocity = [[0.0] * len(joints) for _ in motors]
    c.motor_friction_on, c.motor_friction = [0] * len(motors), [[0.0] * 4 for _ in motors]
    c.joint_friction = [[0.0] * 4 for _ in joints]
    gates: dict[str, tuple[int, int]] = {}  # row channel of a group -> (joint bits, motor bits)
    rows: dict[str, tuple[np.ndarray, int]] = {}  # output channel -> (row map over all joints, motor index)
    for g in cfg.actuation:
        for j in g.joints:
            c.joint_friction[col[j]] = phi[layout.block("joint_friction", j).slice].tolist()
        L, C = group_row_maps(g)
        touches, touches_motor = np.abs(L) > 1e-9 * np.abs(L).max(), np.abs(C) > 1e-9 * np.abs(C).max()
        if g.input != "torque":
            for mi, m in enumerate(g.motors):
                k = motors.index(m)
                for li, j in enumerate(g.joints):
                    c.motor_velocity[k][col[j]] = float(g.coupling[mi, li])
                if g.coupled:
                    c.motor_friction_on[k] = 1
                    c.motor_friction[k] = phi[layout.block("motor_friction", m).slice].tolist()
        names = [f"tau.{j}" for j in g.joints] if g.input == "torque" else [f"{g.input}.{m}" for m in g.motors]
        for r, name in enumerate(names):
            full = np.zeros(len(joints))
            full[[col[j] for j in g.joints]] = L[r]
            jbits = sum(1 << col[j] for li, j in enumerate(g.joints) if touches[r, li])
            mbits = 0
            if g.input != "torque" and g.coupled:
                mbits = sum(1 << motors.index(m) for mi, m in enumerate(g.motors) if touches_motor[r, mi])
            motor = motors.index(g.motors[r]) if g.input != "torque" else -1
            if g.input != "torque" and not np.allclose(C[:, r], np.eye(len(g.motors))[:, r]):
                raise DataError(f"actuation group '{g.name}': a motor row mixes several motors' inputs")
            rows[name], gates[name] = (full, motor), (jbits, mbits)

    outs = output_channels(model)
    c.n_outputs = len(outs)
    c.channel_names = [o.name for o in outs]
    c.channel_kind = [KIND[o.kind] for o in outs]
    c.ft_offset = [phi[layout.block("ft_offset", s.name).slice].tolist() for s in sensors]
    c.row_map, c.channel_motor, c.divisor, c.gate_joints, c.gate_motors = [], [], [], [], []
    for o in outs:
        full, motor = rows.get(o.name, (np.zeros(len(joints)), -1))
        c.row_map.append(full.tolist())
        c.channel_motor.append(motor)
        c.divisor.append(float(phi[o.gain_index]) if o.gain_index is not None else float(o.known_gain))
        jb, mb = gates.get(o.name, (0, 0))
        c.gate_joints.append(jb)
        c.gate_motors.append(mb)
    d, ev = detector, detector.events
    c.residual_variance = np.asarray(d.variance, float).tolist()
    c.min_speed, c.alpha, c.threshold = float(d.min_speed), float(d.alpha), float(d.threshold)
    c.ft_threshold = [float(d.ft_thresholds[s.name]) for s in sensors]
    c.accel_tau_variance = (np.zeros(len(joints)) if d.tau_variance is None else np.asarray(d.tau_variance, float)).tolist()
    c.calibration_samples = int(d.samples)
    ev = ev.at(est.sample_period)
    c.debounce_on, c.debounce_off, c.hysteresis = int(ev.debounce_on), int(ev.debounce_off), float(ev.hysteresis)
    c.sample_period, c.window, c.order, c.lag = est.sample_period, est.window, est.order, est.lag
    c.filter = est.weights().tolist()
    c.n_effects, c.effect_kind, c.effect_joint, c.effect_param = 0, [], [], []
    for e in effects:
        p = e.parameters
        c.effect_kind.append(EXPORTABLE[e.kind])
        c.effect_joint.append(col[e.target[1]])
        c.effect_param.append([p["static_torque"], p["velocity"], 0.0] if e.kind == "stribeck"
                              else [p["stiffness"], p["rest"], 0.0])
    c.n_effects = len(c.effect_kind)
    # Supply tracking (dynid.identify.supply): off is a zero time constant; gates only on the motor inputs.
    c.supply_time_constant = tracking.time_constant_s if tracking is not None else 0.0
    c.supply_prior = tracking.prior_input ** 2 if tracking is not None else 0.0
    c.supply_gate = [tracking.gate_of(o.sigma) if tracking is not None and tracked(o) else 0.0 for o in outs]
    c.tau_map, c.isolation_sigmas = external_torque_map(model).tolist(), float(ISOLATION_SIGMAS)
    _observer_section(c, model, est, observer, residual)
    c.combined_scale = float(combined_scale)
    # Known answers (format version 7): none until dynid.export.known_answers.attach takes them on calibration data.
    c.n_known, c.known_width, c.known_input = 0, c.n_joints * (1 + c.observer_velocity) + c.n_outputs, []
    c.known_columns, c.known_answer = (3 + 2 * c.n_sensors) if c.residual == 2 else 1 + c.n_sensors, []
    return c


def external_torque_map(model: RobotModel) -> np.ndarray:
    """(n_joints, n_outputs) τ_ext = map · r, r the rows' residuals as torques on them: −L⁻¹ per actuation group
    (dynid.detect.momentum); zero on the F/T rows."""
    no = len(output_channels(model))
    tau_map = np.zeros((len(model.config.joints), no))
    for g, gj, rows in group_rows(model):
        L, _ = group_row_maps(g)
        tau_map[np.ix_(gj, np.arange(no)[rows])] = -np.linalg.inv(L)
    return tau_map


def _observer_section(c: coefficients_t, model: RobotModel, est: FixedLagSavitzkyGolay,
                      observer: MonitorObserver | None, residual: str) -> None:
    """Format version 4: the momentum observer, its band, T² and the external-torque map (zeros without one)."""
    cfg = model.config
    nj, no, motors = c.n_joints, c.n_outputs, c.motor_names
    c.residual = RESIDUAL[residual]
    if observer is None:
        c.observer_bandwidth, c.velocity_window, c.velocity_filter, c.observer_velocity = 0.0, 0, [], 0
        c.joint_band, c.motor_band = [[0.0, 0.0] for _ in range(nj)], [[0.0, 0.0] for _ in motors]
        c.observer_variance = [0.0] * no
        c.observer_threshold = c.observer_rest_threshold = 0.0
        c.observer_ft_threshold = [0.0] * c.n_sensors
        c.tau_variance = [0.0] * nj
        return
    d = observer.detector
    if observer.velocity_window > MAX_WINDOW:
        raise DataError(f"the monitor's q̇ estimator holds at most {MAX_WINDOW} samples, this one {observer.velocity_window}")
    c.observer_bandwidth = float(d.bandwidth_hz)
    c.velocity_window = int(observer.velocity_window)
    c.velocity_filter = causal_velocity_weights(observer.velocity_window, est.sample_period).tolist()
    c.observer_velocity = 1 if observer.measured else 0
    c.joint_band = [list(observer.band.get(("joint_friction", j), (0.0, 0.0))) for j in cfg.joints]
    c.motor_band = [list(observer.band.get(("motor_friction", m), (0.0, 0.0))) for m in motors]
    c.observer_variance = np.asarray(d.variance, float).tolist()
    c.observer_threshold, c.observer_rest_threshold = float(d.threshold), float(d.rest_threshold)
    c.observer_ft_threshold = [float(d.ft_thresholds[s]) for s in c.sensor_names]
    c.tau_variance = np.asarray(d.tau_variance, float).tolist()


def exportable_effects(effects: Sequence[Effect]) -> None:
    """The monitor implements Stribeck friction and the spring torque; any other effect is refused, named."""
    for e in effects:
        if e.kind not in EXPORTABLE:
            raise DataError(f"the monitor does not implement effect '{e.kind}' (on {e.where}); it exports only "
                            f"{' and '.join(EXPORTABLE)}: refit without it (dynid gaps) or drop it from the model file")
        if e.kind == "stribeck" and not e.parameters["velocity"] > 0:
            raise DataError(f"stribeck on {e.where}: the Stribeck velocity must be positive")


def _name(names: Sequence[str], i: int) -> str:
    """names[i], or the index marked as out of range: a dump shows a file the monitor refuses (its indices past
    its counts) instead of ending in an IndexError (issue 22's sweep)."""
    return names[i] if 0 <= i < len(names) else f"#{i} (out of range)"


def describe(c: coefficients_t) -> str:
    """A readable dump of every section."""
    f = lambda v: " ".join(f"{x:.6g}" for x in v)  # noqa: E731
    kinds = {0: "fixed (F/T split)", 1: "revolute", 2: "prismatic"}
    lines = [f"robot {c.robot_name} (config sha256 {c.config_digest[:16]}…), exported by dynid {c.dynid_version}",
             f"  model sha256 {c.model_sha256 or '-'}; data sha256 {c.data_sha256 or '-'}; estimator {c.estimator}",
             f"chain: {c.n_bodies} bodies, {c.n_joints} joints; gravity [{f(c.gravity)}] m/s²; "
             + (", ".join(f"F/T sensor {n} at body {_name(c.body_names, b)}" for n, b in zip(c.sensor_names, c.sensor_body))
                or "no F/T sensor")]
    for i in range(c.n_bodies):
        j = _name(c.joint_names, c.joint_index[i]) if c.joint_index[i] >= 0 else "-"
        parent = _name(c.body_names, c.parent[i]) if c.parent[i] >= 0 else "base"
        lines.append(f"  {c.body_names[i]:14s} parent {parent:14s} joint {j:18s} {kinds.get(c.joint_type[i], '?'):18s}"
                     f" axis [{f(c.axis[i])}] p [{f(c.translation[i])}]")
        lines.append(f"    φ = [{f(c.inertial[i])}]")
    lines.append(f"motors: {', '.join(c.motor_names) or 'none'}")
    for k in range(c.n_motors):
        fr = f"friction [{f(c.motor_friction[k])}]" if c.motor_friction_on[k] else "no motor friction"
        lines.append(f"  {c.motor_names[k]}: q̇_m = [{f(c.motor_velocity[k])}]·q̇; {fr}")
    # a prismatic joint's q is in m, its q̇ in m/s and its torque in N
    prismatic = {c.joint_index[i] for i in range(c.n_bodies) if c.joint_type[i] == 2 and c.joint_index[i] >= 0}
    lines.append("joint friction, and the postures the fit saw (its data's range, widened by 1° or 1 mm; the monitor "
                 "counts samples beyond):")
    for j in range(c.n_joints):
        lo, hi = c.fit_range[j]
        seen = ("fit range not recorded" if max(abs(lo), abs(hi)) >= NO_LIMIT else
                f"fit {1e3 * lo:.1f}…{1e3 * hi:.1f} mm" if j in prismatic else
                f"fit {np.rad2deg(lo):.1f}…{np.rad2deg(hi):.1f}°")
        lines.append(f"  {c.joint_names[j]:18s} friction fc+ fc- fv+ fv- [{f(c.joint_friction[j])}]  {seen}")
    lines.append(f"outputs ({c.n_outputs})" + "".join(f"; {n} offset [{f(o)}]" for n, o in zip(c.sensor_names, c.ft_offset)))
    for i in range(c.n_outputs):
        lines.append(f"  {c.channel_names[i]:18s} Λ {c.residual_variance[i]:.4g}  divisor {c.divisor[i]:.6g}"
                     f"  gates joints 0x{c.gate_joints[i]:x} motors 0x{c.gate_motors[i]:x}")
    sides = ", ".join(f"{n} {t:.6g}" for n, t in zip(c.sensor_names, c.ft_threshold)) or "none"
    speed = "rad/s" + (" (m/s for a prismatic joint)" if prismatic else "")
    lines.append(f"T²: α {c.alpha}, threshold {c.threshold:.6g}, F/T-side thresholds {sides}, "
                 f"min speed {c.min_speed} {speed}, from {c.calibration_samples} samples; debounce on {c.debounce_on} "
                 f"off {c.debounce_off}, hysteresis {c.hysteresis}")
    lines.append(f"derivatives: fixed-lag Savitzky-Golay, window {c.window}, order {c.order}, lag {c.lag} "
                 f"({1e3 * c.lag * c.sample_period:.3g} ms), period {c.sample_period:.6g} s")
    if c.supply_time_constant > 0:
        gates = ", ".join(f"{n} {g:.4g}" for n, g in zip(c.channel_names, c.supply_gate) if g > 0)
        lines.append(f"supply tracking: time constant {c.supply_time_constant:g} s, prior weight {c.supply_prior:.4g}; "
                     f"gates {gates}")
    else:
        lines.append("supply tracking: off (constant motor gains)")
    if c.velocity_window > 0:
        chosen = {1: "the monitor runs it", 2: "the monitor runs it in the combined detector"}.get(
            c.residual, "carried; the monitor runs the acceleration residuals")
        velocity = ("the robot's measured q̇ (dq.J on its bus)" if c.observer_velocity
                    else f"causal q̇ over {c.velocity_window} samples")
        lines.append(f"momentum observer ({chosen}): bandwidth {c.observer_bandwidth:g} Hz, {velocity}; "
                     f"T²_α {c.observer_threshold:.6g} (all rows at rest "
                     f"{c.observer_rest_threshold:.6g}), F/T-side thresholds "
                     + (", ".join(f"{n} {t:.6g}" for n, t in zip(c.sensor_names, c.observer_ft_threshold)) or "none"))
        for i in range(c.n_outputs):
            lines.append(f"  {c.channel_names[i]:18s} Λ {c.observer_variance[i]:.4g}")
        for j in range(c.n_joints):
            unit = "N" if j in prismatic else "Nm"
            lines.append(f"  {c.joint_names[j]:18s} static-friction band [{f(c.joint_band[j])}] {unit}, τ_ext variance "
                         f"{c.tau_variance[j]:.4g} {unit}²")
        for k in range(c.n_motors):
            if c.motor_friction_on[k]:
                lines.append(f"  {c.motor_names[k]:18s} static-friction band [{f(c.motor_band[k])}] Nm")
    else:
        lines.append("momentum observer: none (the monitor runs the acceleration residuals)")
    if c.combined_scale > 0:
        state = "the monitor runs it" if c.residual == 2 else "carried (rt_monitor --residual combined)"
        lines.append(f"combined detector ({state}): s = (T²_o/T²_o,α + T²/T²_α)/{c.combined_scale:.6g}, a contact "
                     "where s > 1")
    names = {1: "stribeck", 2: "spring"}
    for k in range(c.n_effects):
        j, p = _name(c.joint_names, c.effect_joint[k]), c.effect_param[k]
        what = (f"extra static torque {p[0]:.6g} Nm, Stribeck velocity {p[1]:.6g} rad/s" if c.effect_kind[k] == 1
                else f"stiffness {p[0]:.6g} Nm/rad, rest {p[1]:.6g} rad")
        lines.append(f"effect {names.get(c.effect_kind[k], '?')} on joint {j}: {what}")
    return "\n".join(lines)
