"""Identification: one regression for inertia, F/T offsets, friction and motor gains, and its model file.

Takes a `RobotModel` and `Dataset`s; accumulates the stacked system per time block (statistics), solves it by
OLS, PLS (NIPALS) and instrumental variables (regression) in the fit (fit), tracks each motor's supply
(supply), writes and reads the model file (model_file), and evaluates a model on a run: residuals and the
paper's Table II (validation). Layer: imports config, io and robot.
"""

from .fit import FitResult, FitSettings, fit
from .model_file import IdentifiedModel, load_model

__all__ = ["FitResult", "FitSettings", "IdentifiedModel", "fit", "load_model"]
