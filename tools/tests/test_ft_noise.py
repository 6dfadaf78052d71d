"""F/T noise per channel: given in the configuration, or estimated by `fit --noise estimate`, used in the weights."""

from __future__ import annotations

from pathlib import Path

import pytest

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError
from dynid.robot.model import RobotModel
from dynid.robot.regressors.stack import row_channels

BUNDLED = Path(load_config("icub_right_arm").source).read_text()


def _with_sensor_noise(tmp_path: Path, noise: str):
    text = BUNDLED.replace("noise: {force: 0.15, torque: 0.008}", noise)
    assert text != BUNDLED
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    return load_config(path)


def test_a_channel_given_its_own_noise_weights_its_rows(tmp_path: Path) -> None:
    config = _with_sensor_noise(tmp_path, "noise: {force: 0.15, torque: 0.008, fz: 0.6, tx: 0.02}")
    sigma = {c.name: c.sigma for c in row_channels(RobotModel(config))}
    assert [sigma[f"ft.r_arm_ft.{c}"] for c in ("fx", "fy", "fz", "tx", "ty", "tz")] == [0.15, 0.15, 0.6, 0.02, 0.008, 0.008]


def test_an_estimate_overrides_the_configuration(tmp_path: Path) -> None:
    from dataclasses import replace

    config = load_config("icub_right_arm")
    config = replace(config, noise=replace(config.noise, per_channel={"ft.r_arm_ft.fy": 0.9}))
    sigma = {c.name: c.sigma for c in row_channels(RobotModel(config))}
    assert sigma["ft.r_arm_ft.fy"] == 0.9 and sigma["ft.r_arm_ft.fx"] == 0.15


def test_a_bad_channel_noise_names_itself(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"ft_sensors\[0\]\.noise\.fz"):
        _with_sensor_noise(tmp_path, "noise: {force: 0.15, fz: -1}")
    with pytest.raises(ConfigError, match="fw"):
        _with_sensor_noise(tmp_path, "noise: {fw: 0.1}")
