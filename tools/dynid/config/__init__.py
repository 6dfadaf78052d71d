"""The robot configuration: everything robot-specific, so that another robot needs a file, never code.

Takes a YAML file or the name of a bundled one (`robots/`, format in its README); hands on a checked,
immutable `RobotConfig` (URDF, base, joints, F/T sensors, motors and coupling, CAN mapping, noise levels).
Layer: the lowest but errors and progress; it imports nothing else of dynid.
"""

from .robot_config import DEFAULT_ROBOT, RobotConfig, bundled_configs, load_config

__all__ = ["DEFAULT_ROBOT", "RobotConfig", "bundled_configs", "load_config"]
