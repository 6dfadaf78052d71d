"""Excitation trajectories designed for the fit (`dynid excite`): finite Fourier series per joint, at rest at both
ends, within the joints' limits, minimising the condition number of the fit's regressor (Swevers et al. 1997).

fourier.py (the series and its parametrisation) → objective.py (the condition number) → design.py (the optimiser).
Layer: beside identify and simulation; imports config and robot. Today's identification trajectory, for the
comparison, comes from the simulation through the cli.
"""

from .design import Design, JointLimits, design, joint_limits, margins, whole_periods
from .fourier import FourierTrajectory
from .objective import ConditionObjective

__all__ = ["ConditionObjective", "Design", "FourierTrajectory", "JointLimits", "design", "joint_limits", "margins",
           "whole_periods"]
