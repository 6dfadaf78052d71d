"""The compiled kernels (dynid._kernels, tools/kernels) against their Python references, sample by sample.

Every comparison is relative to a stated scale, at 1e-12: the kernels compute the same quantities in another order
(and the rigid-body regressor by another algorithm), so they agree to rounding, not bit for bit. Where the Python
reference itself is the loop the kernel compiles (the supply tracker, the non-uniform filter) the same tolerance
holds. Robots whose URDF is supplied (not bundled) are checked where the real-data folder holds it; their data are
not needed: the states are synthetic, inside the joint limits.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dynid import kernels
from dynid.config.robot_config import load_config
from dynid.detect import momentum
from dynid.identify import supply
from dynid.robot.model import RobotModel
from dynid.robot.outputs import divisors, residuals, residuals_many
from dynid.robot.regressors import kernel as row_kernel
from dynid.robot.regressors.stack import Signals, fill_rows_reference, row_channels
from dynid.simulation import SimulationSettings, simulate
from dynid.simulation import kernel as sim_kernel
from dynid.simulation.effects import parse_effect

pytestmark = pytest.mark.skipif(not kernels.available(), reason="dynid._kernels is not built (scripts/setup builds it)")

REALDATA = Path(os.environ.get("DYNID_REALDATA") or Path(__file__).resolve().parents[3] / "shared" / "realdata")
SUPPLIED = {  # the configurations whose URDF the user supplies: where the real-data folder holds one
    "icub_right_leg_standing": REALDATA / "icub_leg_insitu" / "iCubGenova02.urdf",
    "ur10e": REALDATA / "ur10e_mamedov" / "ur10e.urdf",
    "ur10e_known_gains": REALDATA / "ur10e_mamedov" / "ur10e.urdf",
    "tiago_wrist": REALDATA / "tiago_wrist_ft" / "urdf" / "tiago_48_hey5.urdf",
}
ROBOTS = ["icub_right_arm", "icub_right_leg_standing", "ur10e", "ur10e_known_gains", "panda", "tiago_wrist"]
RTOL = 1e-12


def robot(name: str) -> RobotModel:
    urdf = SUPPLIED.get(name)
    if urdf is not None and not urdf.is_file():
        pytest.skip(f"{name}'s URDF is supplied by the user and not at {urdf}")
    return RobotModel(load_config(name, urdf))


def synthetic(model: RobotModel, n: int, seed: int = 0, gravity: bool = False) -> Signals:
    """States inside the joint limits, random velocities and accelerations, inputs, torques and wrenches."""
    rng = np.random.default_rng(seed)
    cfg = model.config
    lo, hi = (np.array([model.joint_limits[j][k] for j in cfg.joints]) for k in (0, 1))
    q = rng.uniform(lo, hi, (n, len(lo)))
    dq, ddq = rng.normal(0, 1, q.shape), rng.normal(0, 5, q.shape)
    dq[::7, 0] = 0.0  # a joint at rest: the friction columns' zero
    inputs = {m: rng.uniform(-0.5, 0.5, n) for g in cfg.actuation if g.input != "torque" for m in g.motors}
    tau = {j: rng.normal(0, 3, n) for g in cfg.actuation if g.input == "torque" for j in g.joints}
    ft = {s.name: rng.normal(0, 5, (n, 6)) for s in cfg.ft_sensors}
    g = rng.normal(0, 1, (n, 3)) + np.asarray(cfg.gravity) if gravity else None
    return Signals(q, dq, ddq, inputs, tau, ft, None, g)


def close(kernel: np.ndarray, reference: np.ndarray, scale: np.ndarray | float) -> None:
    """|kernel − reference| ≤ RTOL · scale, element by element (scale broadcast: per sample, or one number)."""
    excess = np.abs(kernel - reference) - RTOL * np.maximum(scale, 1e-300)
    assert np.all(excess <= 0), f"worst excess {excess.max():.3g} over rtol·scale"


def per_sample_scale(*arrays: np.ndarray) -> np.ndarray:
    """The largest |value| of each sample over the given (N, …) arrays, shaped to broadcast against them."""
    return np.max([np.abs(a).reshape(a.shape[0], -1).max(axis=1) for a in arrays], axis=0)


@pytest.mark.parametrize("name", ROBOTS)
def test_rigid_body_regressor_matches_pinocchio(name: str) -> None:
    model = robot(name)
    chain = row_kernel.chain(model)
    assert chain is not None, "every bundled robot's joints are the kernel's (revolute, prismatic, held sensors)"
    sig = synthetic(model, 200, gravity=True)
    pm = model.pin_model
    Y = np.empty((200, pm.nv, 10 * len(model.bodies)))
    chain.regressor(np.ascontiguousarray(sig.q), np.ascontiguousarray(sig.dq), np.ascontiguousarray(sig.ddq),
                    np.ascontiguousarray(sig.gravity), Y)
    data = pm.createData()
    Q, V, A = model.pinocchio_configuration(sig.q), model.pinocchio_velocity(sig.dq), model.pinocchio_velocity(sig.ddq)
    saved = pm.gravity.copy()
    try:
        for k in range(200):
            pm.gravity = pin.Motion(sig.gravity[k], np.zeros(3))
            ref = pin.computeJointTorqueRegressor(pm, data, Q[k], V[k], A[k]).reshape(pm.nv, -1)
            close(Y[k], ref, np.abs(ref).max())
    finally:
        pm.gravity = saved


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("variant", ["plain", "weights", "payload", "tilting"])
def test_stacked_rows_match_the_reference(name: str, variant: str) -> None:
    """Rigid body, F/T, friction (joints and coupled motors), motor gains or known gains, joint torques, coupling
    (motor space or joint space), weights, a payload, gravity per sample."""
    model = robot(name)
    stack = row_kernel.stack(model)
    assert stack is not None
    sig = synthetic(model, 300, seed=1, gravity=variant == "tilting")
    if variant == "payload":
        sig = Signals(sig.q, sig.dq, sig.ddq, sig.inputs, sig.tau, sig.ft, model.payload_parameters(1.5, [0.01, 0, 0.02]))
    r, p, n = len(row_channels(model)), len(model.layout), 300
    A0, b0 = np.zeros((n, r, p)), np.zeros((n, r))
    fill_rows_reference(model, sig, A0, b0)
    weights = None
    if variant == "weights":
        weights = np.random.default_rng(2).uniform(0, 3, (n, r))
        weights[::5] = 0.0
        A0, b0 = A0 * weights[:, :, None], b0 * weights
    # channel-major with the b column last, as the statistics hold it: strided views
    X = np.full((r, n, p + 1), np.nan)
    row_kernel.fill(stack, model, sig, X[:, :, :p].transpose(1, 0, 2), X[:, :, p].T, weights)
    scale = per_sample_scale(A0, b0)
    close(X[:, :, :p].transpose(1, 0, 2), A0, scale[:, None, None])
    close(X[:, :, p].T, b0, scale[:, None])


@pytest.mark.parametrize("name", ["icub_right_arm", "panda", "ur10e"])
def test_residuals_without_storing_a(name: str) -> None:
    """b − A Φ in the kernel, A never stored, against the reference rows times Φ."""
    model = robot(name)
    sig = synthetic(model, 250, seed=3)
    phi = np.random.default_rng(4).normal(0, 1, len(model.layout))
    for m in model.layout.owners("motor_gain"):
        phi[model.layout.block("motor_gain", m).start] = 10.0
    e = residuals(model, phi, sig)
    r, p = len(row_channels(model)), len(model.layout)
    A0, b0 = np.zeros((250, r, p)), np.zeros((250, r))
    fill_rows_reference(model, sig, A0, b0)
    reference = b0 - A0 @ phi
    scale = per_sample_scale(np.abs(A0) * np.abs(phi), b0)
    close(e * divisors(model, phi), reference, scale[:, None])


@pytest.mark.parametrize("name", ["icub_right_arm", "ur10e"])
def test_residuals_of_several_phi_are_each_ones_own(name: str) -> None:
    """residuals_many builds each sample's rows once for every Φ (the T² calibration's in-sample and held-out
    residuals): each Φ's e is the one `residuals` gives for it alone, to the bit (the same products, in order)."""
    model = robot(name)
    sig = synthetic(model, 300, seed=5)
    rng = np.random.default_rng(6)
    phis = [rng.normal(0, 1, len(model.layout)) for _ in range(3)]
    for phi in phis:
        for m in model.layout.owners("motor_gain"):
            phi[model.layout.block("motor_gain", m).start] = rng.uniform(5.0, 15.0)
    for together, alone in zip(residuals_many(model, phis, sig), (residuals(model, phi, sig) for phi in phis)):
        np.testing.assert_array_equal(together, alone)
    zero_gain = phis[1].copy()
    zero_gain[model.layout.blocks_of("motor_gain")[0].start] = 0.0
    with pytest.raises(ValueError, match="zero or not finite"):
        residuals_many(model, [phis[0], zero_gain], sig)
    with pytest.raises(ValueError, match=r"\(K, N, rows\)"):
        row_kernel.stack(model).residuals_many(*row_kernel._arrays(model, sig), np.vstack(phis), np.empty((2, 300, 6)))


def test_a_wrong_shape_is_refused_not_read_out_of_bounds() -> None:
    model = robot("icub_right_arm")
    stack = row_kernel.stack(model)
    sig = synthetic(model, 10)
    with pytest.raises(ValueError, match="A must be"):
        row_kernel.fill(stack, model, sig, np.empty((10, 3, 4)), np.empty((10, 10)))
    with pytest.raises(ValueError, match="weights"):
        row_kernel.fill(stack, model, sig, np.empty((10, 10, 118)), np.empty((10, 10)), np.ones((9, 10)))


@pytest.mark.parametrize("tilting", [False, True])
def test_momentum_products(tilting: bool) -> None:
    """p = M q̇ and Cᵀq̇ − g by the O(n) kernel against Pinocchio's rnea, computeCoriolisMatrix and gravity."""
    model = robot("icub_right_arm")
    phi = np.nan_to_num(model.cad_parameters(), nan=0.0)
    sig = synthetic(model, 300, seed=5, gravity=tilting)
    got = momentum.momentum_terms(model, phi, sig.q, sig.dq, sig.gravity)
    ref = momentum.momentum_terms_reference(model, phi, sig.q, sig.dq, sig.gravity)
    close(got.p, ref.p, per_sample_scale(ref.p)[:, None])
    close(got.beta_rb, ref.beta_rb, per_sample_scale(ref.beta_rb)[:, None])


@pytest.mark.parametrize("steps", ["uneven", "uniform"])  # the Python reference: a loop, or scipy's lfilter
def test_first_order_filter(monkeypatch: pytest.MonkeyPatch, steps: str) -> None:
    rng = np.random.default_rng(6)
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 2000)) if steps == "uneven" else 2.0 + np.arange(2000) * 1e-3
    x = rng.normal(0, 1, (2000, 4))
    got, got_one = momentum.first_order(t, x, 15.0), momentum.first_order(t, x[:, 1], 15.0)
    monkeypatch.setenv("DYNID_KERNELS", "0")
    ref = momentum.first_order(t, x, 15.0)
    close(got, ref, np.abs(ref).max())
    assert got_one.shape == (2000,)
    close(got_one, ref[:, 1], np.abs(ref).max())


def test_supply_tracker(monkeypatch: pytest.MonkeyPatch) -> None:
    model = robot("icub_right_arm")
    sig = synthetic(model, 3000, seed=7)
    t = np.arange(3000) * 1e-3
    e = np.random.default_rng(8).normal(0, 0.01, (3000, len(row_channels(model))))
    settings = supply.SupplyTracking()
    got = supply.smoothed_ratios(model, settings, 0.01, e, sig, t)
    monkeypatch.setenv("DYNID_KERNELS", "0")
    ref = supply.smoothed_ratios(model, settings, 0.01, e, sig, t)
    close(got, ref, 1.0)


EFFECTS = ["pwm_deadzone:motor=m1,width=0.02", "cogging:motor=m3", "stribeck:joint=r_elbow,excess=0.5",
           "spring:joint=r_elbow,stiffness=0.5", "drag:joint=r_shoulder_roll", "load_friction:motor=m0",
           "armature:motor=m2,inertia=0.0005"]


@pytest.mark.parametrize("kind,effects", [("identification", []), ("contact", []), ("identification", EFFECTS)])
def test_closed_loop_and_sensors_match_the_reference(kind: str, effects: list[str], monkeypatch: pytest.MonkeyPatch
                                                     ) -> None:
    """Without the boards' quantisation (noise off) the closed loop is continuous, so the kernel's run follows the
    Python loop to rounding over 1.5 s: positions to 1e-9 rad, F/T to 1e-9 of their range; with noise on, a single
    encoder step read differently (a rounding on the edge) sends the two runs apart, as it would on another CPU."""
    config = load_config("icub_right_arm")
    bodies = tuple(b.name for b in RobotModel(config).bodies)
    settings = SimulationSettings(kind=kind, duration=1.5, noise=False,
                                  effects=tuple(parse_effect(e, config, bodies) for e in effects))
    got = simulate(config, settings)
    monkeypatch.setenv("DYNID_KERNELS", "0")
    ref = simulate(config, settings)
    a, b = got.truth_signals, ref.truth_signals
    close(a.q, b.q, 1e3)  # 1e-9 rad
    close(a.dq, b.dq, 1e3)
    fa, fb = got.dataset.ft["r_arm_ft"], ref.dataset.ft["r_arm_ft"]
    close(fa, fb, 1e3 * np.abs(fb).max())


def test_sensor_wrenches_on_one_trajectory(monkeypatch: pytest.MonkeyPatch) -> None:
    """The F/T measurement of the same trajectory, contacts on both sides of the sensor, gravity per sample."""
    from dynid.simulation.plant import RigidBodyPlant
    from dynid.simulation.true_robot import draw_true_robot

    model = robot("icub_right_arm")
    plant = RigidBodyPlant(model, draw_true_robot(model, 0).inertias)
    sites = list(plant.sites.values())
    rng = np.random.default_rng(9)
    n = 400
    q, v, a = rng.normal(0, 0.5, (3, n, plant.nv))
    site_index = rng.integers(-1, len(sites), n)
    wrench = rng.normal(0, 5, (n, 6))
    gravity = rng.normal(0, 1, (n, 3)) + np.array([0, 0, -9.81])
    got = sim_kernel.sensor_wrenches(plant, q, v, a, site_index, wrench, sites, gravity)
    ref = plant.sensor_wrenches(q, v, a, site_index, wrench, sites, gravity)
    for g, r in zip(got[:2], ref[:2]):
        for s in r:
            close(g[s], r[s], per_sample_scale(r[s], wrench)[:, None])
    close(got[2], ref[2], per_sample_scale(ref[2], wrench)[:, None])


def test_csv_text_is_reprs_byte_for_byte() -> None:
    """dynid._kernels.csv_rows writes what the reference writes (repr of each float, str of each integer), byte for
    byte: random bit patterns over every exponent, decimals of every scale, and repr's edges (its switch to the
    exponent form at 1e-4 / 1e16, signed zero, subnormals, the largest double, nan and the infinities)."""
    from dynid.io.csv_format import _rows_text

    rng = np.random.default_rng(3)
    bits = rng.integers(0, 2**64, size=200_000, dtype=np.uint64).view(np.float64)
    scales = rng.standard_normal(100_000) * 10.0 ** rng.integers(-12, 22, 100_000)
    edges = np.array([0.0, -0.0, 1e-4, 9.999999999999999e-05, 1e-5, 1e15, 1e16, 9999999999999998.0, 1e22, 0.1, 0.3,
                      100.0, -2.5e-310, 5e-324, 1.7976931348623157e308, 2.0**53, np.nan, np.inf, -np.inf])
    for values in (bits, scales, edges, np.round(scales, 4)):
        block = values.reshape(-1, 4) if values.size % 4 == 0 else values.reshape(-1, 1)
        columns = list(block.T)
        assert kernels.native().csv_rows(block, [False] * block.shape[1]) == _rows_text(columns)
    counts = rng.integers(-(2**53), 2**53, (1000, 2))
    mixed = [counts[:, 0], rng.standard_normal(1000), counts[:, 1].astype(np.uint64) % 7]
    assert kernels.native().csv_rows(np.column_stack(mixed).astype(float), [True, False, True]) == _rows_text(mixed)


def test_csv_files_are_the_same_either_way(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """write_csv gives the same file through the kernel and the reference (the contact column as integers), which
    reads back to the same values; booleans and integers past 2^53 are left to the reference."""
    from dynid.io.csv_format import _compiled_rows, write_csv
    from dynid.io.dataset import Dataset

    rng = np.random.default_rng(4)
    n = 3000
    data = Dataset(t=np.arange(n) * 1e-3, joints=["a", "b"], q=rng.normal(0, 1, (n, 2)), pwm={"m0": rng.normal(0, 1, n)},
                   contact=(rng.uniform(size=n) < 0.1).astype(np.uint8), extra={"x": rng.normal(0, 1e-6, n)})
    assert _compiled_rows(data.columns()) is not None
    write_csv(data, tmp_path / "compiled.csv")
    monkeypatch.setenv("DYNID_KERNELS", "0")
    assert _compiled_rows(data.columns()) is None
    write_csv(data, tmp_path / "reference.csv")
    assert (tmp_path / "compiled.csv").read_bytes() == (tmp_path / "reference.csv").read_bytes()
    back = np.loadtxt(tmp_path / "compiled.csv", delimiter=",", skiprows=1)  # t, q.a, q.b, pwm.m0, contact, x
    assert np.array_equal(back, np.column_stack([data.t, data.q, data.pwm["m0"], data.contact, data.extra["x"]]))
    monkeypatch.setenv("DYNID_KERNELS", "1")
    for odd in (np.ones(3, dtype=bool), np.array([0, 2**53 + 1, 0]), np.array([0, -(2**53) - 1, 0])):
        assert _compiled_rows([("t", np.zeros(3)), ("odd", odd)]) is None
