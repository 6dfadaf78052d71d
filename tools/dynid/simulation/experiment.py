"""One simulated experiment: the closed loop of boards, motors and rigid bodies, and what the boards record.

The loop runs at the configured sample rate (1 kHz). Each sample the boards read the encoders, the impedance
controller computes the joint torques, and the motor boards turn them into PWMs (saturated at ±1, quantised to
their steps); the plant then takes a step with the PWM held (semi-implicit Euler, friction implicit; plant.py).
A sample records q before the step, q̇ after it and q̈ = Δq̇/h: the triple the step's dynamics satisfies, up to
the Coriolis torque being evaluated one step earlier. The recorded signals therefore meet the model's equations
to integration accuracy (consistency.py); only the measurement chain (sensors.py), static friction while a
joint sticks, contacts and the hidden effects make them disagree.

Randomness comes from independent streams: the true robot from `robot_seed` (the same arm for every kind), the
experiment (reference, contacts, noise, disturbance) from (`seed`, kind).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..config.robot_config import RobotConfig
from ..errors import DataError, InputError
from ..io.dataset import TRUTH_FORMAT, Dataset
from ..io.load import MIN_SAMPLES
from ..progress import track
from ..robot.model import RobotModel
from ..robot.parameters import WRENCH_FIELDS
from . import contacts as contact_model
from . import kernel as sim_kernel
from . import sensors
from .actuation import Actuators
from .controller import (BANDWIDTH_HZ, GivenTrajectory, ImpedanceController, Reference, followed_reference,
                         reaching_reference)
from .effects import Effect
from .plant import RigidBodyPlant
from .true_robot import TrueRobot, draw_true_robot

KINDS: dict[str, float] = {"identification": 300.0, "validation": 120.0, "contact": 120.0}  # default durations, s
_KIND_STREAM = {"identification": 1, "validation": 2, "contact": 3}

MIN_RATE_HZ, MAX_RATE_HZ = 250.0, 10_000.0
MAX_SAMPLES = 3_600_000  # about 1 kB per sample across the recorded and true signals

SUPPLY_STD = 0.03  # relative supply-voltage variation (std), the motor gains vary with it
SUPPLY_TIME_CONSTANT_S = 20.0
TORQUE_RIPPLE = 0.03  # relative amplitude of the commutation ripple


@dataclass(frozen=True)
class SimulationSettings:
    kind: str = "identification"
    duration: float | None = None  # s; None: the kind's default
    seed: int = 0
    robot_seed: int = 0
    noise: bool = True  # sensor noise and quantisation
    disturbance: bool = True  # supply variation and torque ripple (off with noise)
    effects: tuple[Effect, ...] = ()
    rate_hz: float = 1000.0
    substeps: int = 1
    # A base that tilts (a humanoid balancing): its amplitude in degrees about the root frame's x and y axes, with
    # periods TILT_PERIODS_S; the run then records an accelerometer fixed to the root (imu.ax, imu.ay, imu.az)
    tilt_deg: float = 0.0
    # A reference to follow instead of the reaching moves (`--trajectory`); the duration defaults to its length
    trajectory: GivenTrajectory | None = None
    # The true arm's friction scaled, per joint (all four coefficients; `scale_friction`): a worn joint (×2), or
    # friction that drifts between runs with temperature (`--friction-scale [JOINT=]K`); truth.json has the result
    friction_scale: tuple[tuple[str, float], ...] = ()

    @property
    def seconds(self) -> float:
        if self.duration is not None:
            return float(self.duration)
        return self.trajectory.duration if self.trajectory is not None else KINDS[self.kind]


def identification_reference(config: RobotConfig, duration: float, seed: int = 0, robot_seed: int = 0,
                             rate_hz: float = 1000.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, q̇, q̈) of the reaching moves `dynid simulate --kind identification --duration D --seed N` is told to
    follow (the same streams as `simulate`): today's identification trajectory, for `dynid excite`'s comparison."""
    model = RobotModel(config)
    streams = np.random.SeedSequence([seed, _KIND_STREAM["identification"], robot_seed]).spawn(5)
    truth = draw_true_robot(model, robot_seed)
    cad_plant = RigidBodyPlant(model, truth.cad_inertias)
    limits = np.array([model.joint_limits[j] for j in config.joints])
    n, dt = int(round(duration * rate_hz)), 1.0 / rate_hz
    ref = reaching_reference(cad_plant, model.bodies[-1].name, limits, limits.mean(axis=1), n, dt,
                             np.random.default_rng(streams[0]))
    return np.arange(n) * dt, ref.q, ref.dq, np.gradient(ref.dq, dt, axis=0)


@dataclass
class Simulation:
    dataset: Dataset  # what the boards recorded
    truth_signals: Dataset  # the true state, inputs and wrenches, sample by sample
    truth: dict = field(default_factory=dict)  # parameters, effects, contacts, realism counters (JSON-able)


def _supply(n: int, n_motors: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """Relative supply voltage per motor: 1 + an Ornstein–Uhlenbeck variation (a shared bus, per-board drops)."""
    a = np.exp(-dt / SUPPLY_TIME_CONSTANT_S)
    shocks = rng.normal(0.0, SUPPLY_STD * np.sqrt(1 - a * a), (n, 1 + n_motors))
    x = np.empty_like(shocks)
    x[0] = rng.normal(0.0, SUPPLY_STD, 1 + n_motors)
    for k in range(1, n):  # a first-order recursion; lfilter would do it too, this keeps numpy only
        x[k] = a * x[k - 1] + shocks[k]
    return 1.0 + 0.8 * x[:, :1] + 0.6 * x[:, 1:]


TILT_PERIODS_S = (17.0, 23.0)  # about x and y: slow against the arm's reaching motions
IMU_NOISE = 0.02  # m/s², std per axis


def tilted_gravity(gravity: np.ndarray, degrees: float, t: np.ndarray) -> np.ndarray:
    """(N, 3) gravity in a root frame that tilts by up to `degrees` about x and y: R(t)ᵀ g."""
    amp = np.deg2rad(degrees)
    angles = np.column_stack([amp * np.sin(2 * np.pi * t / TILT_PERIODS_S[0]),
                              amp * np.sin(2 * np.pi * t / TILT_PERIODS_S[1] + 0.7), np.zeros_like(t)])
    return np.array([pin.exp3(w).T @ gravity for w in angles])


def _given(traj: GivenTrajectory, joints: tuple[str, ...], limits: np.ndarray, seconds: float, n: int,
           dt: float) -> Reference:
    """The given trajectory on the run's grid, refused when it is too short or leaves the URDF's joint limits."""
    if seconds > traj.duration + 1e-9:
        raise InputError(f"--duration {seconds:g} s is longer than the trajectory {traj.source} ({traj.duration:g} s)")
    outside = (traj.q < limits[:, 0]) | (traj.q > limits[:, 1])
    if outside.any():
        k, j = (int(x[0]) for x in np.nonzero(outside))
        raise InputError(f"the trajectory {traj.source} leaves {joints[j]}'s limits [{limits[j, 0]:.4g}, "
                         f"{limits[j, 1]:.4g}] rad at t = {traj.t[k]:g} s (q = {traj.q[k, j]:.4g})")
    return followed_reference(traj, n, dt)


def scale_friction(truth: TrueRobot, config: RobotConfig, joint: str, factor: float) -> None:
    """Scale everything the fit sees as `joint`'s friction: the joint's own and, where one motor drives it alone,
    that motor's friction and back-EMF (docs/design.md §3 folds them into the joint's); a coupled group's motor
    friction has parameters of its own and is left as it is."""
    truth.joint_friction[joint] = truth.joint_friction[joint] * factor
    for g in config.actuation:
        if joint in g.joints and g.input != "torque" and not g.coupled:
            m = g.motors[g.joints.index(joint)]
            truth.motor_friction[m] = truth.motor_friction[m] * factor
            truth.back_emf[m] = truth.back_emf[m] * factor


def simulate(config: RobotConfig, settings: SimulationSettings) -> Simulation:
    """The experiment `settings` describe on the simulated arm `config`: its data, truth and realism figures."""
    try:
        return _simulate(config, settings)
    except RuntimeError as e:  # the plant (compiled or not) could not be integrated: an input, not a bug
        if not str(e).startswith("the plant"):
            raise
        given = ", ".join(x.kind + (f" on {x.target}" if x.target else "") for x in settings.effects)
        why = f"with the hidden effects {given}: their parameters make the arm unstable" if given else \
            "(the trajectory or the rate?)"
        raise DataError(f"{e}: the simulated arm cannot be integrated {why}") from None


def _simulate(config: RobotConfig, settings: SimulationSettings) -> Simulation:
    if settings.kind not in KINDS:
        raise InputError(f"unknown experiment kind '{settings.kind}' (known: {', '.join(KINDS)})")
    if not MIN_RATE_HZ <= settings.rate_hz <= MAX_RATE_HZ:
        raise InputError(
            f"sample rate {settings.rate_hz:g} Hz is outside {MIN_RATE_HZ:g}..{MAX_RATE_HZ:g} Hz: the boards' "
            "controller runs at the sample rate"
        )
    dt = 1.0 / settings.rate_hz
    samples = settings.seconds * settings.rate_hz
    if samples > MAX_SAMPLES:  # before int(): `--duration 1e300` printed a 300-digit sample count
        raise InputError(
            f"duration {settings.seconds:g} s at {settings.rate_hz:g} Hz is {samples:.3g} samples; at most "
            f"{MAX_SAMPLES} (an hour at 1 kHz) fit in memory: simulate several experiments instead"
        )
    n = int(round(samples))
    if n < MIN_SAMPLES:  # a shorter run was written, and then refused by every command that reads it
        raise InputError(
            f"duration {settings.seconds:g} s at {settings.rate_hz:g} Hz is {n} samples; a run needs at least "
            f"{MIN_SAMPLES}"
        )
    model = RobotModel(config)
    streams = np.random.SeedSequence([settings.seed, _KIND_STREAM[settings.kind], settings.robot_seed]).spawn(5)
    rng_ref, rng_contact, rng_noise, rng_disturbance, rng_effects = (np.random.default_rng(s) for s in streams)
    effects = list(settings.effects)
    delay_s = sum(float(e.params["ms"]) * 1e-3 for e in effects if e.kind == "pwm_delay")
    if delay_s >= settings.seconds:  # the recorded PWM would be its first sample throughout
        raise InputError(f"effect 'pwm_delay': {1e3 * delay_s:g} ms is not shorter than the run ({settings.seconds:g} s)")
    truth = draw_true_robot(model, settings.robot_seed)
    for joint, factor in settings.friction_scale:
        scale_friction(truth, config, joint, factor)
    joints, motors = config.joints, config.motor_names
    nj, nm = len(joints), len(motors)

    # The true bodies and gravity, with the hidden body effects.
    inertias = [i.copy() for i in truth.inertias]
    bodies = [b.name for b in model.bodies]
    effect_truth: list[dict] = []
    for e in effects:
        entry = e.as_dict()
        if e.kind == "payload":
            k = bodies.index(e.target)
            inertias[k] = inertias[k] + pin.Inertia(e.params["mass"], np.array([e.params[c] for c in "xyz"]), np.zeros((3, 3)))
            entry["equivalent_parameters"] = dict(
                zip(model.layout.block("inertial", e.target).names, inertias[k].toDynamicParameters().tolist())
            )
        effect_truth.append(entry)
    gravity = np.asarray(config.gravity, float)
    for e in effects:
        if e.kind == "base_tilt":
            axis = np.eye(3)["xyz".index(str(e.params["axis"]))]
            gravity = pin.exp3(axis * np.deg2rad(float(e.params["degrees"]))) @ gravity
    plant = RigidBodyPlant(model, inertias, gravity)
    # A tilting base: gravity in the root's frame turns slowly (R(t)ᵀ g); the base's own acceleration is left out,
    # so the rigid-body model with gravity per sample is exact (the identification's model of a tilting base)
    g_of_t = tilted_gravity(gravity, settings.tilt_deg, np.arange(n) * dt) if settings.tilt_deg else None
    cad_plant = RigidBodyPlant(model, truth.cad_inertias)

    limits = np.array([model.joint_limits[j] for j in joints])
    q_rest = limits.mean(axis=1)
    ref: Reference = reaching_reference(cad_plant, bodies[-1], limits, q_rest, n, dt, rng_ref)
    if settings.trajectory is not None:  # drawn all the same: the controller's gains take the stream after it
        ref = _given(settings.trajectory, config.joints, limits, settings.seconds, n, dt)
        q_rest = ref.q[0]  # the arm starts where the trajectory does, at rest
    controller = ImpedanceController(config, cad_plant, limits, dt, rng_ref, bodies[-1], contact_model.FORCE_RANGE_N[1])
    disturbed = settings.disturbance and settings.noise
    # Phases of ripple and cogging belong to the motors: drawn from the robot seed, like the arm itself.
    motor_phases = np.random.default_rng([settings.robot_seed, 0xC0])
    actuators = Actuators(config, truth, effects, limits, TORQUE_RIPPLE if disturbed else 0.0, motor_phases)
    supply = _supply(n, nm, dt, rng_disturbance) if disturbed else np.ones((n, nm))
    t = np.arange(n) * dt

    sites = list(plant.sites.values())
    episodes: list[contact_model.Episode] = []
    patches = contact_model.skin_patches(config, plant)
    if settings.kind == "contact":
        coms = {b: inertias[k].lever for k, b in enumerate(bodies)}
        episodes = contact_model.draw_episodes(settings.seconds, patches, plant, coms, rng_contact)
    site_index, contact_wrench, episode_index = contact_model.timeline(episodes, t, sites)

    encoder = sensors.encoder_steps(config)
    pwm_counts = sensors.pwm_full_scale(config) if settings.noise else np.zeros(nm)
    pwm_motors = np.array([m in config.motors_with_input("pwm") for m in motors], dtype=bool)
    board_inputs = sensors.InputQuantiser(pwm_motors, pwm_counts)
    torque_joints = config.joints_with_input("torque")

    Q, V, A = np.empty((n, nj)), np.empty((n, nj)), np.empty((n, nj))
    U, TAU_DIRECT = np.empty((n, nm)), np.empty((n, nj))
    unsaturated = np.empty((n, nm))
    STUCK = np.empty((n, len(actuators.coordinates)), dtype=bool)
    mode = np.zeros(len(actuators.coordinates), dtype=np.int8)
    fext = pin.StdVec_Force()
    for _ in range(plant.model.njoints):
        fext.append(pin.Force.Zero())
    q, v = q_rest.copy(), np.zeros(nj)
    controller.reset(q)
    h = dt / settings.substeps
    loop = sim_kernel.closed_loop(plant, cad_plant, controller, actuators, board_inputs, encoder, settings.noise)
    if loop is not None:  # the loop below, compiled (dynid.simulation.kernel)
        joint, force = sim_kernel.contact_forces(sites, site_index, contact_wrench)
        unconverged, diverged = loop.run(
            q_rest.astype(float), np.ascontiguousarray(ref.q, dtype=float), np.ascontiguousarray(ref.dq, dtype=float),
            np.ascontiguousarray(supply, dtype=float), joint, force,
            None if g_of_t is None else np.ascontiguousarray(g_of_t), settings.substeps, Q, V, A, U, TAU_DIRECT,
            unsaturated, STUCK)
        plant.unconverged_steps += unconverged
        if diverged >= 0:
            raise RuntimeError(f"the plant diverged at t = {t[diverged]:.3f} s")
    for k in track(range(n), n, f"simulating {settings.kind}") if loop is None else ():
        q_measured = sensors.quantise(q, encoder) if settings.noise else q
        tau_cmd = controller.torque(q_measured, ref.q[k], ref.dq[k])
        u = controller.motor_inputs(tau_cmd)
        unsaturated[k] = u
        u = board_inputs(u)
        c = site_index[k]
        forces = None
        if c >= 0:
            fext[sites[c].joint_id] = contact_model.contact_force(sites[c], contact_wrench[k])
            forces = fext
        if g_of_t is not None:
            plant.model.gravity = pin.Motion(g_of_t[k], np.zeros(3))
        for s in range(settings.substeps):
            tau0, law = actuators.drive(q, v, u, supply[k], tau_cmd)
            v_next, a = plant.step(q, v, tau0, law, h, forces, actuators.armature, mode)
            if s == 0:
                Q[k], V[k], A[k], STUCK[k] = q, v_next, a, mode == 0
            v = v_next
            q = q + h * v
        U[k], TAU_DIRECT[k] = u, tau_cmd
        if c >= 0:
            fext[sites[c].joint_id] = pin.Force.Zero()
        if not np.all(np.isfinite(q)):
            raise RuntimeError(f"the plant diverged at t = {t[k]:.3f} s")

    # The sensors, from the true trajectory.
    measured = sim_kernel.sensor_wrenches(plant, Q, V, A, site_index, contact_wrench, sites, g_of_t)
    if measured is None:  # the Python reference
        measured = plant.sensor_wrenches(Q, V, A, site_index, contact_wrench, sites, g_of_t)
    wrenches, at_sensor, tau_contact = measured
    ft_measured, ft_offsets, ft_saturated = {}, {}, {}
    for s in config.ft_sensors:
        offset = sensors.ft_offset_track(effects, s.name, t, truth.ft_offsets[s.name], rng_effects)
        steps = sensors.ft_step_sizes(effects, s.name, np.random.default_rng([settings.robot_seed, 0x57E9]))
        offset = offset + sensors.ft_step_track(steps, t)
        for e, size in steps:  # the truth of each step: its size per axis (its times are its parameters)
            effect_truth[effects.index(e)].update({f"d{a}": float(v) for a, v in zip(("fx", "fy", "fz", "tx", "ty", "tz"), size)})
        gain = sensors.ft_gain_matrix(effects, s.name, np.random.default_rng([settings.robot_seed, 0xF7]))
        std = np.array([s.noise_of(k) for k in range(6)])
        ft_measured[s.name], ft_saturated[s.name] = sensors.measure_ft(
            wrenches[s.name], offset, gain, std, sensors.ft_full_scale(config, s.name), settings.noise, rng_noise
        )
        ft_offsets[s.name] = offset
        for e, entry in zip(effects, effect_truth):
            if e.kind == "ft_gain" and e.target == s.name:
                entry["matrix"] = (gain - np.eye(6)).tolist()  # E of measured = (I + E) w, rows and columns fx … tz
    recorded_u = U.copy()
    delay = sum(int(round(float(e.params["ms"]) * 1e-3 * settings.rate_hz)) for e in effects if e.kind == "pwm_delay")
    if delay:
        recorded_u[delay:], recorded_u[:delay] = U[:-delay], U[0]
    q_recorded = sensors.quantise(Q, encoder) if settings.noise else Q.copy()
    inputs = {m: recorded_u[:, i] for i, m in enumerate(motors)}
    tau_measured = {}
    for j in torque_joints:
        i = joints.index(j)
        tau_measured[j] = TAU_DIRECT[:, i] + (rng_noise.normal(0, config.noise.torque, n) if settings.noise else 0.0)
    current = {m: inputs[m] for m in config.motors_with_input("current")}
    if settings.noise:
        current = {m: c + rng_noise.normal(0, config.noise.current, n) for m, c in current.items()}

    contact = side = patch = None
    if settings.kind == "contact":
        contact = (episode_index >= 0).astype(np.uint8)
        side_code = {"distal": 1.0, "proximal": -1.0}
        side = np.array([side_code[episodes[i].side] if i >= 0 else 0.0 for i in episode_index])
        patch = np.array([episodes[i].patch + 1.0 if i >= 0 else 0.0 for i in episode_index])
    meta = {
        "robot": config.name, "config_digest": config.digest, "source": f"dynid simulate --kind {settings.kind}",
        "seed": settings.seed, "robot_seed": settings.robot_seed, "noise": settings.noise,
    }  # never the hidden effects: finding them is the gap workflow's job
    extra: dict[str, np.ndarray] = {}
    if contact is not None:
        extra = {"skin.side": side, "skin.patch": patch}
    if g_of_t is not None:  # the accelerometer at the root: the specific force −g, with its noise
        a = -g_of_t + (rng_effects.normal(0.0, IMU_NOISE, g_of_t.shape) if settings.noise else 0.0)
        extra.update({f"imu.a{c}": a[:, i] for i, c in enumerate("xyz")})
    dataset = Dataset(
        t=t, joints=joints, q=q_recorded,
        pwm={m: inputs[m] for m in config.motors_with_input("pwm")}, current=current, tau=tau_measured,
        ft=ft_measured, contact=contact, extra=extra, meta=meta,
    ).validate()

    truth_extra: dict[str, np.ndarray] = {}
    for s in config.ft_sensors:
        for kf, f in enumerate(WRENCH_FIELDS):
            truth_extra[f"ft.{s.name}.offset.{f}"] = ft_offsets[s.name][:, kf]
            truth_extra[f"contact.{s.name}.{f}"] = at_sensor[s.name][:, kf]
    for i, j in enumerate(joints):
        truth_extra[f"contact.tau.{j}"] = tau_contact[:, i]
        truth_extra[f"reference.q.{j}"] = ref.q[:, i]
    for i, name in enumerate(actuators.coordinates):
        truth_extra[f"stuck.{name}"] = STUCK[:, i].astype(float)
    for i, m in enumerate(motors):
        truth_extra[f"supply.{m}"] = supply[:, i]
        truth_extra[f"command.{m}"] = unsaturated[:, i]
    truth_signals = Dataset(
        t=t, joints=joints, q=Q, dq=V, ddq=A, pwm={m: U[:, i] for i, m in enumerate(motors)},
        ft=wrenches, contact=contact, extra=truth_extra, meta={**meta, "truth": True},
    )

    drive_u = U[:, pwm_motors]
    in_limits = np.all((Q >= limits[:, 0]) & (Q <= limits[:, 1]), axis=1)
    record = {
        "format": TRUTH_FORMAT, "format_version": 1,
        "robot": config.name, "config_digest": config.digest, "kind": settings.kind,
        "duration_s": settings.seconds, "rate_hz": settings.rate_hz, "samples": n,
        "seed": settings.seed, "robot_seed": settings.robot_seed, "noise": settings.noise,
        "friction_scale": dict(settings.friction_scale),
        "disturbance": disturbed,
        "parameters": truth.parameters(model),
        "cad_parameters": {n: (None if np.isnan(x) else x) for n, x in zip(model.layout.names, model.cad_parameters().tolist())},
        "plant": {
            **truth.describe(model),
            "gravity": gravity.tolist(),
            "tilt": None if g_of_t is None else {"degrees": settings.tilt_deg, "periods_s": list(TILT_PERIODS_S),
                                                 "imu_noise": IMU_NOISE, "imu_frame": "the URDF root"},
            "integrator": f"semi-implicit Euler with implicit friction, {settings.substeps} step(s) per sample",
            "unconverged_friction_steps": plant.unconverged_steps,
            "torque_ripple": TORQUE_RIPPLE if disturbed else 0.0,
            "supply_std": SUPPLY_STD if disturbed else 0.0,
            "reference": "reaching moves" if settings.trajectory is None else f"given: {settings.trajectory.source}",
            "controller": {"bandwidth_hz": BANDWIDTH_HZ, "stiffness": controller.K.tolist(), "damping": controller.D.tolist()},
            "pwm_delay_samples": delay,
        },
        "effects": effect_truth,
        "patches": [{"name": p.name, "links": list(p.links), "side": p.side} for p in patches],
        "contacts": [e.as_dict(patches) for e in episodes],
        "realism": {
            "pwm_within_limits": float(np.mean(np.all(np.abs(drive_u) < 1.0, axis=1))) if drive_u.size else 1.0,
            "command_saturated": float(np.mean(np.abs(unsaturated[:, pwm_motors]) > 1.0)) if drive_u.size else 0.0,
            "joint_limits_respected": float(np.mean(in_limits)),
            "stuck_fraction": dict(zip(actuators.coordinates, STUCK.mean(axis=0).tolist())),
            "ft_saturated_samples": {s: int(np.any(v, axis=1).sum()) for s, v in ft_saturated.items()},
            "peak_velocity": dict(zip(joints, np.max(np.abs(V), axis=0).tolist())),
            "reaching_targets": len(ref.targets),
        },
    }
    return Simulation(dataset, truth_signals, record)
