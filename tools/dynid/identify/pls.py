"""`NipalsPLS`: dynid's NIPALS PLS as a scikit-learn estimator (fit/predict, get_params), the form in which a test proves
it equals scikit-learn's `PLSRegression` where the two problems coincide (docs/design.md §3, Estimators).

Apart from `regression`, so that commands which never fit (detect, validate, export) do not import scikit-learn
(1.3 s of a `dynid detect`'s start, measured: docs/benchmarks.md#compiled-kernels).
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, check_X_y, validate_data

from .regression import nipals_pls1


class NipalsPLS(RegressorMixin, BaseEstimator):
    """Partial Least Squares regression by NIPALS, one response, no intercept.

    Parameters
    ----------
    n_components : int
        Number of latent variables ν.
    scale : bool
        Scale X's columns to unit norm before the fit (the parameters of Φ have mixed units; without it PLS
        favours whichever columns are numerically large). Coefficients are returned in the original units.
    center : bool
        Centre X and y first, as scikit-learn's PLSRegression always does (then an intercept is fitted).
        False for the stacked system, which has no intercept.
    """

    def __init__(self, n_components: int = 2, scale: bool = True, center: bool = False) -> None:
        self.n_components = n_components
        self.scale = scale
        self.center = center

    def fit(self, X: np.ndarray, y: np.ndarray) -> NipalsPLS:
        X, y = check_X_y(X, y, y_numeric=True)
        self.n_features_in_ = X.shape[1]
        x_mean = X.mean(axis=0) if self.center else np.zeros(X.shape[1])
        y_mean = float(y.mean()) if self.center else 0.0
        Xc, yc = X - x_mean, y - y_mean
        s = np.where(np.linalg.norm(Xc, axis=0) > 0, np.linalg.norm(Xc, axis=0), 1.0) if self.scale else np.ones(X.shape[1])
        self.components_ = nipals_pls1(Xc / s, yc, self.n_components)
        self.coef_ = self.components_.coefficients(self.components_.C.size) / s
        self.intercept_ = y_mean - x_mean @ self.coef_
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self)
        X = validate_data(self, X, reset=False)
        return X @ self.coef_ + self.intercept_
