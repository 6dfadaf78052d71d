"""Friction regressor: asymmetric Coulomb and viscous, four coefficients per joint or motor.

τ_f = fc_pos·[q̇>0] − fc_neg·[q̇<0] + fv_pos·max(q̇,0) + fv_neg·min(q̇,0)

so all four coefficients are positive for a physical friction, and back-EMF folds into the viscous pair.
At zero velocity the Coulomb terms vanish (static friction is not modelled), and "zero" is within VELOCITY_FLOOR:
the derivative filter's estimate at rest is a weighted sum of equal samples, exactly 0 or ±1e-15 depending on the
order the sum is taken in (the CPU's BLAS kernel, the monitor's vector width), and a Coulomb term must not take its
sign from that rounding. The monitor's core (rt_monitor/src/core.cpp) and the compiled regressor
(tools/kernels/src/stack.cpp) use the same floor.
"""

from __future__ import annotations

import numpy as np


VELOCITY_FLOOR = 1e-9  # rad/s or m/s: a velocity this close to zero is zero for the sign of friction


def friction_regressor(velocity: np.ndarray) -> np.ndarray:
    """Columns [fc_pos, fc_neg, fv_pos, fv_neg] for each velocity: (...,) -> (..., 4)."""
    v = np.asarray(velocity, dtype=float)
    return np.stack([(v > VELOCITY_FLOOR).astype(float), -(v < -VELOCITY_FLOOR).astype(float), np.maximum(v, 0.0),
                     np.minimum(v, 0.0)], axis=-1)


def friction_torque(velocity: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """τ_f for velocities (..., n) and coefficients (n, 4): (..., n)."""
    return np.einsum("...nk,nk->...n", friction_regressor(velocity), np.asarray(coefficients, dtype=float))

def stribeck_shape(v: np.ndarray, velocity: float) -> np.ndarray:
    """sign(v)·exp(−(v/v_s)²): the Stribeck curve per unit static torque, the one definition the fit's candidate
    columns (dynid.robot.effect_library), the augmented model's prediction and the monitor's (core.cpp) all follow."""
    return np.where(np.abs(v) > VELOCITY_FLOOR, np.sign(v), 0.0) * np.exp(-((v / velocity) ** 2))
