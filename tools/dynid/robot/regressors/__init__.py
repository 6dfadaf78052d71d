"""Regressors: the rows of A Φ = b (docs/design.md §3), built from (q, q̇, q̈, inputs) for a batch of samples.

- `rigid_body`: Y_τ and Y_FT from Pinocchio;
- `friction`: asymmetric Coulomb and viscous columns;
- `stack`: the motor equations (coupling, gains, motor friction), the F/T offset columns, and the stacked system;
- `base`: the numerical rank and the identifiable (base) parameter combinations.
"""

from .friction import friction_regressor, friction_torque
from .rigid_body import RigidBodyRegressors, rigid_body_regressors
from .stack import RowChannel, Signals, StackedSystem, build_stacked, iter_stacked, row_channels, signals_from_dataset

__all__ = [
    "RigidBodyRegressors",
    "RowChannel",
    "Signals",
    "StackedSystem",
    "build_stacked",
    "friction_regressor",
    "friction_torque",
    "iter_stacked",
    "rigid_body_regressors",
    "row_channels",
    "signals_from_dataset",
]
