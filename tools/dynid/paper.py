"""The published figures of Traversaro et al., Humanoids 2013, on the real iCub arm, shown beside dynid's own.

These describe the paper's robot and set-up only; output for another robot does not print them.
"""

from __future__ import annotations

PAPER_ROBOT = "icub_right_arm"  # the bundled configuration of the paper's arm: only its output shows PAPER

# Contact detection at α = 0.99 (TPR, FPR), and Table II: F/T prediction error norms, mean and std.
PAPER: dict[str, float | tuple[float, float]] = {
    "tpr": 0.67,
    "fpr": 0.06,
    "force_error": (1.33, 0.64),
    "force_error_cad": (1.86, 0.59),
    "torque_error": (0.15, 0.13),
    "torque_error_cad": (0.15, 0.07),
}
