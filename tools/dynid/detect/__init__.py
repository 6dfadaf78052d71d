"""Contact detection: Hotelling T² on a model's residuals.

Takes residuals of an identified model; calibrates the detector's Λ and threshold on contact-free data (t2),
with the monitor's own causal estimator for the coefficient file (online); scores T² against ground truth:
TPR, FPR, ROC, episodes and delays (evaluation), and tells which contacts the sensors can see at all
(visibility). Layer: imports config, io, robot and identify.
"""

from .t2 import ALPHA, VARIANTS, Detector, f_threshold

__all__ = ["ALPHA", "VARIANTS", "Detector", "f_threshold"]
