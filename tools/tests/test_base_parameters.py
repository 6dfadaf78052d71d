"""Base-parameter structure: an analytic pendulum, and the invariants any base-parameter set must satisfy."""

from __future__ import annotations

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.robot.regressors import build_stacked
from dynid.robot.regressors.base import (
    base_parameters,
    data_base_parameters,
    exciting_signals,
    structural_base_parameters,
)

PENDULUM_URDF = """\
<robot name="pendulum">
  <link name="base"/>
  <link name="arm">
    <inertial><origin xyz="0.3 0 -0.1"/><mass value="2.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.03"/></inertial>
  </link>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/>
  </joint>
</robot>
"""


def pendulum(tmp_path, actuation: str) -> RobotModel:
    (tmp_path / "pendulum.urdf").write_text(PENDULUM_URDF)
    header = "name: pendulum\nurdf: {path: pendulum.urdf}\nbase_link: base\njoints: [hinge]\n"
    (tmp_path / "pendulum.yaml").write_text(header + actuation + "\n")
    return RobotModel(load_config(tmp_path / "pendulum.yaml"))


def test_pendulum_with_torque_sensor_has_the_textbook_base(tmp_path) -> None:
    """A pendulum about y under gravity along −z: only Iyy (about the axis), m·cx and m·cz act: rank 3 + 4 friction."""
    model = pendulum(tmp_path, "actuation: [{name: j, input: torque, joints: [hinge]}]")
    bp = structural_base_parameters(model)
    assert bp.rank == 3 + 4
    names = {model.layout.names[i] for i in bp.independent}
    assert {"arm.Iyy", "arm.mcx", "arm.mcz"} <= names
    assert set(bp.unidentifiable) == {"arm.m", "arm.mcy", "arm.Ixx", "arm.Ixy", "arm.Ixz", "arm.Iyz", "arm.Izz"}


def test_pendulum_with_pwm_only_loses_the_scale(tmp_path) -> None:
    """Without F/T or torque sensing, the motor equation is homogeneous: gain and dynamics are known up to scale,
    but the rank still counts the gain column; identification needs the F/T rows to fix it (docs/design.md §3)."""
    model = pendulum(tmp_path, "motors: {m: {nominal_gain: 5.0}}\nactuation: [{name: j, input: pwm, joints: [hinge], motors: [m]}]")
    bp = structural_base_parameters(model)
    assert bp.rank == 3 + 4 + 1
    system = build_stacked(model, exciting_signals(model, 200))
    assert not system.b.any()  # homogeneous: least squares would return Φ = 0, the scale is not observable


def test_icub_structure(tmp_path) -> None:
    model = RobotModel(load_config("icub_right_arm"))
    bp = structural_base_parameters(model)
    # 118 parameters; the first body turns about its own axis, so its mass and three inertia entries act on nothing.
    assert len(model.layout) == 118
    assert set(bp.unidentifiable) == {"r_shoulder_1.m", "r_shoulder_1.Ixy", "r_shoulder_1.Iyy", "r_shoulder_1.Iyz"}
    assert bp.rank == 87
    # A clean numerical gap: the last kept singular value is far above the first dropped one.
    s = bp.singular_values / bp.singular_values[0]
    assert s[bp.rank - 1] > 1e-3 and s[bp.rank] < 1e-12
    # Every motor gain and every F/T offset is identifiable on its own.
    kept = {model.layout.names[i] for i in bp.independent}
    assert {"m0.phi_m", "m1.phi_m", "m2.phi_m", "m3.phi_m"} <= kept
    assert all(f"ft.r_arm_ft.offset.{c}" in kept for c in ("fx", "fy", "fz", "tx", "ty", "tz"))


def test_base_parameters_reproduce_every_prediction() -> None:
    """For any Φ, A Φ = A_b β with β = Φ_b + K Φ_d, on data the structure was not computed from."""
    model = RobotModel(load_config("icub_right_arm"))
    bp = structural_base_parameters(model, seed=0)
    other = build_stacked(model, exciting_signals(model, 300, seed=7))
    phi = np.random.default_rng(0).normal(size=len(model.layout))
    full = other.A @ phi
    reduced = other.A[:, bp.independent] @ bp.base(phi)
    assert np.abs(full - reduced).max() <= 1e-9 * max(1.0, np.abs(full).max())


def test_chunked_rank_equals_stacked_rank() -> None:
    model = RobotModel(load_config("icub_right_arm"))
    sig = exciting_signals(model, 5000, seed=3)  # more than one chunk
    chunked = data_base_parameters(model, sig, min_speed=None)  # every row, as the stacked system has them
    stacked = base_parameters(build_stacked(model, sig))
    assert chunked.rank == stacked.rank == 87
    assert np.allclose(chunked.singular_values, stacked.singular_values, rtol=1e-8, atol=1e-12)


def test_poor_excitation_lowers_the_rank() -> None:
    """Standing still excites nothing but gravity: the rank drops well below the structural one."""
    model = RobotModel(load_config("icub_right_arm"))
    sig = exciting_signals(model, 500, seed=1)
    still = type(sig)(sig.q, np.zeros_like(sig.dq), np.zeros_like(sig.ddq), sig.inputs, sig.tau, sig.ft)
    assert data_base_parameters(model, still).rank < 87 - 20


@pytest.mark.parametrize("seed", [0, 1])
def test_structure_does_not_depend_on_the_random_draw(seed: int) -> None:
    model = RobotModel(load_config("icub_right_arm"))
    assert structural_base_parameters(model, seed=seed).rank == 87
