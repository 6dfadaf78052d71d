"""Regressor correctness against independent references: Pinocchio's rnea on the unsplit URDF model, and
motor/coupling equations built by hand from known gains, friction and coupling."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.robot.regressors import Signals, build_stacked, friction_regressor, friction_torque, rigid_body_regressors
from dynid.robot.regressors.stack import row_channels

N_STATES = 200


@pytest.fixture(scope="module")
def icub() -> RobotModel:
    return RobotModel(load_config("icub_right_arm"))


def random_states(model: RobotModel, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    lo = np.array([model.joint_limits[j][0] for j in model.config.joints])
    hi = np.array([model.joint_limits[j][1] for j in model.config.joints])
    q = rng.uniform(lo, hi, (n, len(lo)))
    dq = rng.normal(0, 1.5, q.shape)
    dq[: n // 10] = 0.0  # include standstill
    return q, dq, rng.normal(0, 4.0, q.shape)


def unsplit_reference(model: RobotModel) -> pin.Model:
    """Pinocchio's own model of the same chain, sensor fixed joint merged as usual: an independent path."""
    full = pin.buildModelFromUrdf(str(model.config.urdf))
    lock = [i for i in range(1, full.njoints) if full.names[i] not in model.config.joints]
    ref = pin.buildReducedModel(full, lock, pin.neutral(full))
    ref.gravity = pin.Motion(model.config.gravity, np.zeros(3))
    return ref


def test_torque_regressor_matches_rnea(icub: RobotModel) -> None:
    q, dq, ddq = random_states(icub, N_STATES, seed=1)
    reg = rigid_body_regressors(icub, q, dq, ddq)
    ref = unsplit_reference(icub)
    data = ref.createData()
    tau_ref = np.array([pin.rnea(ref, data, q[k], dq[k], ddq[k]) for k in range(N_STATES)])
    tau = reg.tau @ icub.cad_inertial_parameters
    assert np.abs(tau - tau_ref).max() <= 1e-9
    assert np.abs(tau_ref).max() > 1.0  # the check is not vacuous


def test_split_preserves_the_merged_body(icub: RobotModel) -> None:
    """Proximal + distal sub-bodies, brought to one frame, are exactly the URDF's merged r_shoulder_yaw body."""
    ref = unsplit_reference(icub)
    prox = icub.pin_model.inertias[icub.pin_model.getJointId("r_shoulder_yaw")]
    sensor_jid = icub.pin_model.getJointId("r_arm_ft_sensor")
    distal = icub.pin_model.jointPlacements[sensor_jid].act(icub.pin_model.inertias[sensor_jid])
    merged = ref.inertias[ref.getJointId("r_shoulder_yaw")]
    assert np.allclose((prox + distal).toDynamicParameters(), merged.toDynamicParameters(), atol=1e-12)
    assert icub.sensor_bodies["r_arm_ft"].name == "r_upper_arm"


def test_stacked_torque_rows_equal_rnea(icub: RobotModel) -> None:
    """A·Φ on the motor-equation rows, with friction and gains zero, is rnea's torque: the elbow's directly,
    the shoulder's as motor torques T⁻ᵀ τ (the coupled group is written per motor)."""
    q, dq, ddq = random_states(icub, N_STATES, seed=2)
    zeros = np.zeros(N_STATES)
    sig = Signals(q, dq, ddq, {m: zeros for m in icub.config.motor_names}, {}, {"r_arm_ft": np.zeros((N_STATES, 6))})
    system = build_stacked(icub, sig)
    phi = np.zeros(len(icub.layout))
    phi[icub.layout.span("inertial")] = icub.cad_inertial_parameters
    rows = (system.A @ phi).reshape(N_STATES, -1)
    ref = unsplit_reference(icub)
    data = ref.createData()
    tau_ref = np.array([pin.rnea(ref, data, q[k], dq[k], ddq[k]) for k in range(N_STATES)])
    names = [c.name for c in system.channels]
    r = 65 / 40
    T = np.array([[1, 0, 0], [-r, r, 0], [-r, r, r]])
    motor_torque = np.linalg.solve(T.T, tau_ref[:, :3].T).T
    for i, m in enumerate(("m0", "m1", "m2")):
        assert np.abs(rows[:, names.index(f"motor.{m}")] - motor_torque[:, i]).max() <= 1e-9
    assert np.abs(rows[:, names.index("joint.r_elbow")] - tau_ref[:, 3]).max() <= 1e-9


def test_torque_sensor_rows_equal_rnea_plus_friction(tmp_path) -> None:
    """Table I, joint torque sensors: A·Φ = b with b the rnea torque plus friction, on every joint."""
    text = open(load_config().source).read().split("\nft_sensors:")[0]  # keep name, urdf, base, gravity, joints
    joints = load_config().joints
    text += f"\nactuation:\n  - {{name: arm, input: torque, joints: [{', '.join(joints)}]}}\n"
    path = tmp_path / "icub_torque.yaml"
    path.write_text(text)
    model = RobotModel(load_config(path))
    q, dq, ddq = random_states(model, N_STATES, seed=6)
    ref = unsplit_reference(model)
    data = ref.createData()
    coeff = np.random.default_rng(6).uniform(0.01, 0.3, (7, 4))
    tau = np.array([pin.rnea(ref, data, q[k], dq[k], ddq[k]) for k in range(N_STATES)]) + friction_torque(dq, coeff)
    system = build_stacked(model, Signals(q, dq, ddq, {}, {j: tau[:, i] for i, j in enumerate(joints)}, {}))
    phi = np.zeros(len(model.layout))
    phi[model.layout.span("inertial")] = model.cad_inertial_parameters
    phi[model.layout.span("joint_friction")] = coeff.ravel()
    assert system.A.shape[1] == 7 * 10 + 7 * 4  # no sensor split, no offsets, no motors
    assert np.abs(system.A @ phi - system.b).max() <= 1e-9


def test_friction_regressor_convention() -> None:
    v = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
    coeff = np.array([[0.3, 0.2, 0.05, 0.07]])  # fc+, fc-, fv+, fv-
    expected = np.array([-0.2 - 0.14, -0.2 - 0.035, 0.0, 0.3 + 0.025, 0.3 + 0.1])
    assert np.allclose(friction_torque(v[:, None], coeff)[:, 0], expected, atol=1e-15)
    assert friction_regressor(v).shape == (5, 4)


def test_coulomb_sign_ignores_a_rounding_at_rest() -> None:
    """A resting joint's filtered velocity is ±1e-15 or 0 by the order of the filter's sum: no Coulomb term inside the
    velocity floor, the full one just outside it; Stribeck's sign alike."""
    from dynid.robot.regressors.friction import VELOCITY_FLOOR, stribeck_shape

    v = np.array([-7e-15, -VELOCITY_FLOOR, 0.0, 1e-16, VELOCITY_FLOOR, 2 * VELOCITY_FLOOR, -2 * VELOCITY_FLOOR])
    F = friction_regressor(v)
    assert np.array_equal(F[:, 0], [0, 0, 0, 0, 0, 1, 0]) and np.array_equal(F[:, 1], [0, 0, 0, 0, 0, 0, -1])
    assert np.array_equal(F[:, 2:], np.column_stack([np.maximum(v, 0), np.minimum(v, 0)]))
    assert np.array_equal(np.sign(stribeck_shape(v, 0.1)), [0, 0, 0, 0, 0, 1, -1])


def test_motor_and_coupling_rows_hold_for_a_constructed_plant(icub: RobotModel) -> None:
    """PWMs made from known gains, friction and the shoulder coupling satisfy A·Φ = b to 1e-9.

    The PWMs are computed here by solving the motor equations with T⁻ᵀ explicitly, not through stack.py.
    """
    cfg, layout = icub.config, icub.layout
    rng = np.random.default_rng(3)
    q, dq, ddq = random_states(icub, N_STATES, seed=3)
    ref = unsplit_reference(icub)
    data = ref.createData()
    tau_rb = np.array([pin.rnea(ref, data, q[k], dq[k], ddq[k]) for k in range(N_STATES)])

    gains = {m: rng.uniform(10, 30) for m in cfg.motor_names}
    joint_fric = {j: rng.uniform([0.1, 0.1, 0.01, 0.01], [0.5, 0.5, 0.2, 0.2]) for j in cfg.joints[:4]}
    motor_fric = {m: rng.uniform([0.05, 0.05, 0.005, 0.005], [0.3, 0.3, 0.05, 0.05]) for m in ("m0", "m1", "m2")}
    r = 65 / 40
    T = np.array([[1, 0, 0], [-r, r, 0], [-r, r, r]])

    pwm: dict[str, np.ndarray] = {}
    # Shoulder: Tᵀ τ_m = τ_joint + joint friction, with τ_m = gain·pwm − motor friction(T q̇).
    tau_joint = tau_rb[:, :3] + np.stack([friction_torque(dq[:, i : i + 1], joint_fric[j][None])[:, 0]
                                          for i, j in enumerate(cfg.joints[:3])], axis=1)
    dq_motor = dq[:, :3] @ T.T
    tau_motor = np.linalg.solve(T.T, tau_joint.T).T
    for mi, m in enumerate(("m0", "m1", "m2")):
        tau_motor_m = tau_motor[:, mi] + friction_torque(dq_motor[:, mi : mi + 1], motor_fric[m][None])[:, 0]
        pwm[m] = tau_motor_m / gains[m]
    # Elbow, directly driven.
    pwm["m3"] = (tau_rb[:, 3] + friction_torque(dq[:, 3:4], joint_fric["r_elbow"][None])[:, 0]) / gains["m3"]

    offset = rng.normal(0, 5, 6)
    ft = rigid_body_regressors(icub, q, dq, ddq).ft["r_arm_ft"] @ icub.cad_inertial_parameters + offset

    phi = np.zeros(len(layout))
    phi[layout.span("inertial")] = icub.cad_inertial_parameters
    phi[layout.block("ft_offset", "r_arm_ft").slice] = offset
    for j, c in joint_fric.items():
        phi[layout.block("joint_friction", j).slice] = c
    for m, c in motor_fric.items():
        phi[layout.block("motor_friction", m).slice] = c
    for m, g in gains.items():
        phi[layout.block("motor_gain", m).slice] = g

    system = build_stacked(icub, Signals(q, dq, ddq, pwm, {}, {"r_arm_ft": ft}))
    residual = system.A @ phi - system.b
    assert np.abs(residual).max() <= 1e-9
    # Not vacuous: a 1 % gain error breaks the shoulder rows.
    phi[layout.index("m1.phi_m")] *= 1.01
    assert np.abs(system.A @ phi - system.b).max() > 1e-3


def test_known_gain_current_rows_are_non_homogeneous(icub: RobotModel, tmp_path) -> None:
    """Table I, 'currents with known gains': the motor term moves to b, and no gain column remains."""
    # Without the iCub bus (`can:`, the last section): its motor boards carry PWM, which these motors no longer take
    text = open(icub.config.source).read().split("\ncan:")[0] + "\n"
    text = text.replace("input: pwm", "input: current")
    text = text.replace("m3: {nominal_gain: 15.0}", "m3: {nominal_gain: 15.0, known_gain: 12.5}")
    path = tmp_path / "icub_current.yaml"
    path.write_text(text)
    model = RobotModel(load_config(path))
    assert "m3.phi_m" not in model.layout.names and "m0.phi_m" in model.layout.names
    q, dq, ddq = random_states(model, 20, seed=4)
    current = np.linspace(-1, 1, 20)
    sig = Signals(q, dq, ddq, {m: current for m in model.config.motor_names}, {}, {"r_arm_ft": np.zeros((20, 6))})
    system = build_stacked(model, sig)
    elbow_rows = system.b.reshape(20, -1)[:, [c.name for c in system.channels].index("joint.r_elbow")]
    assert np.allclose(elbow_rows, 12.5 * current)


def test_rows_have_channel_noise(icub: RobotModel) -> None:
    channels = row_channels(icub)
    sigma = {c.name: c.sigma for c in channels}
    assert sigma["ft.r_arm_ft.fx"] == 0.15 and sigma["ft.r_arm_ft.tz"] == 0.008
    # Elbow: σ_pwm · gain; shoulder yaw: σ_pwm · |Tᵀ row| · gains.
    # Elbow: σ_pwm · gain. The coupled shoulder is written per motor, so its rows' errors are independent.
    assert sigma["joint.r_elbow"] == pytest.approx(0.002 * 15.0)
    assert [c.name for c in channels][6:9] == ["motor.m0", "motor.m1", "motor.m2"]
    assert sigma["motor.m2"] == pytest.approx(0.002 * 20.0)


def test_shoulder_rows_are_motor_torque_equations(icub: RobotModel) -> None:
    """In motor space, a motor row's gain column is −u of that motor alone, and its friction that motor's alone."""
    q, dq, ddq = random_states(icub, 50, seed=5)
    u = {m: np.random.default_rng(i).uniform(-0.5, 0.5, 50) for i, m in enumerate(icub.config.motor_names)}
    system = build_stacked(icub, Signals(q, dq, ddq, u, {}, {"r_arm_ft": np.zeros((50, 6))}))
    A = system.A.reshape(50, len(system.channels), -1)
    names = [c.name for c in system.channels]
    layout = icub.layout
    for m in ("m0", "m1", "m2"):
        row = A[:, names.index(f"motor.{m}")]
        for other in ("m0", "m1", "m2"):
            gain = row[:, layout.index(f"{other}.phi_m")]
            fric = row[:, layout.block("motor_friction", other).slice]
            if other == m:
                assert np.allclose(gain, -u[m], atol=1e-12)
            else:
                assert np.abs(gain).max() < 1e-12 and np.abs(fric).max() < 1e-12


def test_rows_at_rest_follow_the_coupling() -> None:
    """A motor-space row holds the joint frictions its T⁻ᵀ row touches and its own motor's friction."""
    from dynid.robot.regressors.stack import row_channels, rows_at_rest

    model = RobotModel(load_config("icub_right_arm"))
    names = [c.name for c in row_channels(model)]
    # T⁻ᵀ = [[1, 1, 0], [0, 1/r, -1/r], [0, 0, 1/r]]: m0 holds pitch and roll, m1 roll and yaw, m2 yaw.
    moving = np.array([0.3, 0.7, 0.5, 0.4, 0.2, 0.2, 0.2])  # every joint and motor well above 0.01 rad/s
    dq = np.tile(moving, (4, 1))
    dq[0, :2] = [0.0, 0.4]  # pitch rests (so does m0 = pitch): m0's row
    dq[1, 2] = 0.005  # yaw slower than the default 0.01 rad/s: m1 and m2
    dq[2, :3] = [0.5, 0.5, 1.0]  # m1 = r (roll - pitch) = 0: m1 alone
    dq[3, 3] = -0.001  # the elbow: its own row
    rest = rows_at_rest(model, dq)
    at_rest = [[n for n, r in zip(names, row) if r] for row in rest]
    assert at_rest == [["motor.m0"], ["motor.m1", "motor.m2"], ["motor.m1"], ["joint.r_elbow"]]
    assert not rows_at_rest(model, moving[None]).any()
