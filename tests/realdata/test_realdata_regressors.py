"""The regressors on real robot data: the Panda's joint-torque rows and the TIAGo's wrist F/T rows build from the
imported CSVs and explain the measurements (a plain least-squares fit here; `dynid fit` is the real estimator)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.io.load import load_data
from dynid.robot.model import RobotModel
from dynid.robot.regressors import build_stacked, signals_from_dataset
from dynid.robot.regressors.base import data_base_parameters, structural_base_parameters

from . import convert

HERE = Path(__file__).parent
pytestmark = pytest.mark.skipif(not convert.REALDATA.is_dir(), reason=f"no real data at {convert.REALDATA}")


def imported(tmp_path: Path, which: str):
    conversion = convert.convert_panda() if which == "panda" else convert.convert_tiago()
    csv = tmp_path / f"{which}.csv"
    conversion.write(csv)
    config = load_config("panda") if which == "panda" else load_config("tiago_wrist", convert.TIAGO_URDF)
    model = RobotModel(config)
    return model, load_data(csv, config, joint_limits=model.joint_limits)


def test_panda_joint_torque_regressor(tmp_path: Path) -> None:
    model, ds = imported(tmp_path, "panda")
    n = ds.n_samples
    sig = signals_from_dataset(model, ds)
    system = build_stacked(model, sig)
    assert system.A.shape == (n * 7, 7 * 10 + 7 * 4)  # 7 bodies, 7 joints' friction; no F/T, no motors
    # The excitation reaches the full structural rank of the torque-sensing set-up.
    assert data_base_parameters(model, sig).rank == structural_base_parameters(model).rank == 71

    # Least squares on the first 2/3 predicts the torques of the last 1/3 (measured: 2.9 %).
    train, test = ds.slice(0, 2 * n // 3), ds.slice(2 * n // 3, n)
    a = build_stacked(model, signals_from_dataset(model, train))
    b = build_stacked(model, signals_from_dataset(model, test))
    phi = np.linalg.lstsq(a.A, a.b, rcond=None)[0]
    rel = np.linalg.norm(b.b - b.A @ phi) / np.linalg.norm(b.b)
    assert rel < 0.04


def test_tiago_wrist_ft_regressor(tmp_path: Path) -> None:
    """Mass, first moments and the six offsets of the hand from the real, untared wrist sensor."""
    model, ds = imported(tmp_path, "tiago")
    ds = ds.slice(921, 6791)  # the excitation window of protocol.yaml
    system = build_stacked(model, signals_from_dataset(model, ds))
    layout = model.layout
    hand = layout.block("inertial", model.sensor_bodies["wrist_ft"].name).start
    offsets = layout.block("ft_offset", "wrist_ft").slice
    cols = [hand, hand + 1, hand + 2, hand + 3, *range(offsets.start, offsets.stop)]
    x = np.linalg.lstsq(system.A[:, cols], system.b, rcond=None)[0]
    residual = (system.b - system.A[:, cols] @ x).reshape(-1, 6)
    mass = x[0]
    # The authors' quasi-static fit: 0.79 kg below the sensor, residual 0.29-0.55 N (measured here: 0.795 kg).
    assert 0.75 < mass < 0.84
    assert np.sqrt((residual[:, :3] ** 2).mean()) < 0.6
    assert x[4 + 2] == pytest.approx(-69, abs=2)  # the untared Fz offset
    # The rows only see the distal body and the offsets: 16 identifiable columns.
    assert data_base_parameters(model, signals_from_dataset(model, ds)).rank == 16
