"""The robot as a model: what the physics says, with no data fitted yet.

Takes a `RobotConfig`; hands on a `RobotModel` (Pinocchio, the F/T sensor's split bodies, the parameter layout of
parameters), the regressors that make the rows of A Φ = b (regressors), the output channels y and their
prediction ŷ (outputs), and the effects an augmented model may carry (effects, effect_library).
Layer: imports config and io.
"""

from .model import RobotModel

__all__ = ["RobotModel"]
