"""The real-time core on every bundled robot: its coefficient file loads, and the core predicts what dynid predicts.

Each robot's CAD model is exported (`dynid export --cad --robot R --rate HZ`: no data needed) and the core's
prediction (`rt_eval --predict`) is compared, sample by sample, with `dynid.robot.outputs.residuals` on states that
cover both signs of every joint velocity, joints at rest and every robot's own inputs: the iCub arm's PWMs through
its coupled shoulder, the iCub leg standing on its sole with two F/T sensors, the UR10e's motor currents, the
Panda's joint torques and TIAGo's wrist sensor with a prismatic torso. Robots whose URDF the user supplies skip
without ../shared/realdata, saying so.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid as forked_dynid
from test_rt_core import RT_EVAL, read_matrix, rel_err, write_matrix

from dynid.config.robot_config import load_config
from dynid.detect.t2 import Detector
from dynid.export.capacity import capacity
from dynid.export.coefficients import read_coefficients
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels, residuals
from dynid.robot.regressors.stack import Signals

ROOT = Path(__file__).resolve().parents[2]
REALDATA = Path(os.environ.get("DYNID_REALDATA") or ROOT.parent / "shared" / "realdata")
URDF_PATH = os.pathsep.join(str(REALDATA / d) for d in ("icub_leg_insitu", "ur10e_mamedov", "tiago_wrist_ft/urdf"))
# robot -> (the rate its boards sample at, Hz; whether its URDF comes with ../shared/realdata)
ROBOTS = {
    "icub_right_arm": (1000, False),
    "icub_right_leg_standing": (100, True),
    "ur10e": (500, True),
    "ur10e_known_gains": (500, True),
    "panda": (1000, False),
    "tiago_wrist": (100, True),
}


def dynid(*args: str) -> subprocess.CompletedProcess:
    return forked_dynid(*args, env={"DYNID_URDF_PATH": URDF_PATH})


def cad_export(robot: str, out: Path) -> Path:
    rate, supplied = ROBOTS[robot]
    if supplied and not REALDATA.is_dir():
        pytest.skip(f"{robot}'s URDF comes with the real data, absent at {REALDATA}")
    done = dynid("export", "--cad", "--robot", robot, "--rate", str(rate), "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out


def test_python_reads_the_capacity_the_monitor_is_built_with() -> None:
    """dynid.export.capacity parses rt_monitor/include/rt_monitor/capacity.hpp; the compiled monitor says the same."""
    done = subprocess.run([str(RT_EVAL), "--capacity"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    compiled = {k: int(v) for k, v in (line.split() for line in done.stdout.splitlines())}
    assert compiled == capacity().__dict__


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_every_robot_exports_and_the_core_predicts_what_dynid_predicts(robot: str, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    coef = cad_export(robot, tmp_path / "cad.dcoef")
    done = subprocess.run([str(RT_EVAL), "--coef", str(coef), "--check"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    c = read_coefficients(coef)
    monkeypatch.setenv("DYNID_URDF_PATH", URDF_PATH)
    model = RobotModel(load_config(robot))
    cfg = model.config
    assert c.n_sensors == len(cfg.ft_sensors) and list(c.sensor_names) == [s.name for s in cfg.ft_sensors]
    phi = np.nan_to_num(model.cad_parameters(), nan=0.0)  # what export --cad writes: CAD, nominal gains
    for m in model.layout.owners("motor_gain"):
        phi[model.layout.block("motor_gain", m).start] = cfg.motor(m).nominal_gain

    rng = np.random.default_rng(7)
    n, nj = 400, len(cfg.joints)
    lo = np.array([max(model.joint_limits[j][0], -3.0) for j in cfg.joints])
    hi = np.array([min(model.joint_limits[j][1], 3.0) for j in cfg.joints])
    q = rng.uniform(lo, hi, (n, nj))
    dq = rng.choice([-1.0, 0.0, 1.0], (n, nj)) * rng.uniform(0.02, 1.5, (n, nj))
    dq[n // 2 : n // 2 + 40] *= 0.004  # below min_speed: input rows gated
    ddq = rng.normal(0, 3.0, (n, nj))
    outs = output_channels(model)
    inputs = {o.motor: rng.uniform(-1.0, 1.0, n) for o in outs if o.kind == "input"}
    tau = {o.name.split(".", 1)[1]: rng.normal(0, 10.0, n) for o in outs if o.kind == "torque"}
    ft = {s.name: rng.normal(0, 5.0, (n, 6)) for s in cfg.ft_sensors}
    sig = Signals(q, dq, ddq, inputs, tau, ft)
    e = residuals(model, phi, sig)
    columns = {**{f"ft.{s}.{k}": v[:, i] for s, v in ft.items() for i, k in enumerate(("fx", "fy", "fz", "tx", "ty", "tz"))},
               **{o.name: inputs[o.motor] for o in outs if o.kind == "input"}, **{f"tau.{j}": v for j, v in tau.items()}}
    y = np.column_stack([columns[name] for name in c.channel_names])
    assert list(c.channel_names) == [o.name for o in outs]
    det = Detector("calibrated", np.asarray(c.residual_variance), c.threshold, c.alpha, c.min_speed, c.n_outputs)
    active, t2 = det.active(model, dq), det.t2(model, e, dq)

    write_matrix(tmp_path / "in.mx", np.hstack([q, dq, ddq, y]))
    done = subprocess.run([str(RT_EVAL), "--coef", str(coef), "--predict", str(tmp_path / "in.mx"),
                           str(tmp_path / "out.mx")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    out = read_matrix(tmp_path / "out.mx")
    no = c.n_outputs
    scale = np.maximum(np.abs(y - e), np.abs(y)).max(axis=0)
    assert rel_err(out[:, :no], y - e, scale) <= 1e-9
    assert rel_err(out[:, no : 2 * no], e, scale) <= 1e-9
    assert np.array_equal(out[:, 2 * no : 3 * no].astype(bool), active)
    assert rel_err(out[:, 3 * no], t2, np.maximum(t2, 1e-12)) <= 1e-9
    for k in range(c.n_sensors):  # each sensor's share of T², over its six channels
        share = np.sum(e[:, 6 * k : 6 * k + 6] ** 2 / np.asarray(c.residual_variance)[6 * k : 6 * k + 6], axis=1)
        assert rel_err(out[:, 3 * no + 1 + k], share, np.maximum(share, 1e-12)) <= 1e-9
