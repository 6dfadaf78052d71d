"""Cross-library check: dynid's Pinocchio-based F/T regressor against iDynTree's expected F/T measurement
(ExtWrenchesAndJointTorquesEstimator), and its torque regressor against iDynTree's inverse dynamics."""

from __future__ import annotations

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.robot.regressors import Signals, build_stacked, rigid_body_regressors

from .reference.idyntree_ft import gravity_in_link, idyntree_expected_ft_and_torques

N_STATES = 200


@pytest.fixture(scope="module")
def icub_states():
    model = RobotModel(load_config("icub_right_arm"))
    rng = np.random.default_rng(11)
    lo = np.array([model.joint_limits[j][0] for j in model.config.joints])
    hi = np.array([model.joint_limits[j][1] for j in model.config.joints])
    q = rng.uniform(lo, hi, (N_STATES, 7))
    dq = rng.normal(0, 1.5, q.shape)
    ddq = rng.normal(0, 4.0, q.shape)
    urdf = str(model.config.urdf)
    # iDynTree's base is the configured base link; gravity is the configured one, expressed there.
    g_base = gravity_in_link(urdf, model.config.base_link, g=tuple(model.config.gravity))
    ft_ref, tau_ref = idyntree_expected_ft_and_torques(
        urdf, list(model.config.joints), model.config.base_link, "r_arm_ft", q, dq, ddq, gravity=g_base
    )
    return model, q, dq, ddq, ft_ref, tau_ref


def test_ft_regressor_matches_idyntree(icub_states) -> None:
    model, q, dq, ddq, ft_ref, _ = icub_states
    ft = rigid_body_regressors(model, q, dq, ddq).ft["r_arm_ft"] @ model.cad_inertial_parameters
    assert np.abs(ft - ft_ref).max() <= 1e-9
    assert np.abs(ft_ref[:, :3]).max() > 10.0  # forces of the order of the arm's weight and more


def test_stacked_ft_rows_match_idyntree_with_offset(icub_states) -> None:
    """A·Φ = b on the F/T rows, with b the iDynTree measurement plus an offset."""
    model, q, dq, ddq, ft_ref, _ = icub_states
    offset = np.array([1.5, -2.0, 3.0, 0.1, -0.05, 0.2])
    layout = model.layout
    phi = np.zeros(len(layout))
    phi[layout.span("inertial")] = model.cad_inertial_parameters
    phi[layout.block("ft_offset", "r_arm_ft").slice] = offset
    zeros = np.zeros(N_STATES)
    sig = Signals(q, dq, ddq, {m: zeros for m in model.config.motor_names}, {}, {"r_arm_ft": ft_ref + offset})
    system = build_stacked(model, sig)
    residual = (system.A @ phi - system.b).reshape(N_STATES, -1)[:, :6]
    assert np.abs(residual).max() <= 1e-9


def test_torque_regressor_matches_idyntree(icub_states) -> None:
    model, q, dq, ddq, _, tau_ref = icub_states
    tau = rigid_body_regressors(model, q, dq, ddq).tau @ model.cad_inertial_parameters
    assert np.abs(tau - tau_ref).max() <= 1e-9
