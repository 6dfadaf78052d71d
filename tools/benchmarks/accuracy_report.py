"""The accuracy figures of the README's "Checked against" table, measured (the tests assert bounds on them).

    .venv/bin/python tools/benchmarks/accuracy_report.py

Needs the iDynTree reference in tests/reference and, for the real runs, shared/realdata beside the checkout.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tests.realdata import convert  # noqa: E402
from tests.reference.idyntree_ft import gravity_in_link, idyntree_expected_ft_and_torques  # noqa: E402

from dynid.config.robot_config import load_config
from dynid.io.load import load_data
from dynid.robot.model import RobotModel
from dynid.robot.regressors import build_stacked, rigid_body_regressors, signals_from_dataset


def regressor_errors(n: int = 200, seed: int = 11) -> None:
    model = RobotModel(load_config("icub_right_arm"))
    cfg = model.config
    rng = np.random.default_rng(seed)
    lo = np.array([model.joint_limits[j][0] for j in cfg.joints])
    hi = np.array([model.joint_limits[j][1] for j in cfg.joints])
    q, dq, ddq = rng.uniform(lo, hi, (n, 7)), rng.normal(0, 1.5, (n, 7)), rng.normal(0, 4.0, (n, 7))
    reg = rigid_body_regressors(model, q, dq, ddq)
    phi = model.cad_inertial_parameters

    full = pin.buildModelFromUrdf(str(cfg.urdf))
    ref = pin.buildReducedModel(full, [i for i in range(1, full.njoints) if full.names[i] not in cfg.joints],
                                pin.neutral(full))
    data = ref.createData()
    tau_rnea = np.array([pin.rnea(ref, data, q[k], dq[k], ddq[k]) for k in range(n)])
    urdf = str(cfg.urdf)
    g = gravity_in_link(urdf, cfg.base_link, g=tuple(cfg.gravity))
    ft_idt, tau_idt = idyntree_expected_ft_and_torques(urdf, list(cfg.joints), cfg.base_link, "r_arm_ft", q, dq, ddq, g)
    print(f"{n} random iCub states, max |error|:")
    print(f"  Y_tau.phi vs Pinocchio rnea (unsplit model) {np.abs(reg.tau @ phi - tau_rnea).max():.2g} Nm")
    print(f"  Y_tau.phi vs iDynTree inverse dynamics      {np.abs(reg.tau @ phi - tau_idt).max():.2g} Nm")
    print(f"  Y_FT.phi  vs iDynTree expected F/T          {np.abs(reg.ft['r_arm_ft'] @ phi - ft_idt).max():.2g}")


def real_runs(tmp: Path) -> None:
    if not convert.REALDATA.is_dir():
        print(f"real runs: skipped, no data at {convert.REALDATA}")
        return
    for which, conv, cfg, urdf in (("panda", convert.convert_panda, "panda", None),
                                   ("tiago", convert.convert_tiago, "tiago_wrist", convert.TIAGO_URDF)):
        conv().write(tmp / f"{which}.csv")
        config = load_config(cfg, urdf)
        model = RobotModel(config)
        ds = load_data(tmp / f"{which}.csv", config, joint_limits=model.joint_limits)
        if which == "panda":
            n = ds.n_samples
            a = build_stacked(model, signals_from_dataset(model, ds.slice(0, 2 * n // 3)))
            b = build_stacked(model, signals_from_dataset(model, ds.slice(2 * n // 3, n)))
            phi = np.linalg.lstsq(a.A, a.b, rcond=None)[0]
            rel = np.linalg.norm(b.b - b.A @ phi) / np.linalg.norm(b.b)
            print(f"Panda: least squares on the first 2/3 predicts the last 1/3 with {100 * rel:.1f} % torque error")
            continue
        system = build_stacked(model, signals_from_dataset(model, ds.slice(921, 6791)))
        hand = model.layout.block("inertial", model.sensor_bodies["wrist_ft"].name).start
        off = model.layout.block("ft_offset", "wrist_ft").slice
        cols = [hand, hand + 1, hand + 2, hand + 3, *range(off.start, off.stop)]
        x = np.linalg.lstsq(system.A[:, cols], system.b, rcond=None)[0]
        res = np.sqrt(((system.b - system.A[:, cols] @ x).reshape(-1, 6)[:, :3] ** 2).mean(0))
        print(f"TIAGo: mass below the wrist sensor {x[0]:.3f} kg, Fz offset {x[6]:.1f} N, "
              f"force residual {res.min():.2f}-{res.max():.2f} N RMS")


if __name__ == "__main__":
    regressor_errors()
    with tempfile.TemporaryDirectory() as tmp:
        real_runs(Path(tmp))
