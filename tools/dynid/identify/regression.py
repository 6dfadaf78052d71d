"""Estimators of the stacked system A Φ = b (rows already weighted by 1/σ): PLS, base least squares, IV.

Two ways in, one algebra:

- scikit-learn style, on a stacked (X, y): `NipalsPLS` is Partial Least Squares by NIPALS, without an
  intercept (the stacked system has none), Φ̂ = W (PᵀW)⁻¹ C.
- on sufficient statistics accumulated a chunk at a time (`dynid.identify.statistics`), so that an hour of 1 kHz data
  never needs A in memory: `pls_path` is the kernel form of the same NIPALS (Dayal & MacGregor 1997: the
  weights, loadings and coefficients follow from XᵀX and Xᵀy alone), `base_least_squares` the baseline, and
  `instrumental_variables` the closed-loop remedy (IDIM-IV, Janot & Gautier).

scikit-learn's `PLSRegression` always centres X and y; here nothing is centred because the F/T offsets are
the model's only constant columns and must stay parameters. Where the two problems coincide (X and y already
centred), `NipalsPLS` equals scikit-learn's estimator (tools/tests/test_estimators.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

# ------------------------------------------------------------------------------------------------------------
# PLS


@dataclass(frozen=True)
class PLSComponents:
    """W (p, ν) weights, P (p, ν) loadings, C (ν,) y-loadings, in the (column-scaled) space they were fitted in."""

    W: np.ndarray
    P: np.ndarray
    C: np.ndarray

    def coefficients(self, n_components: int) -> np.ndarray:
        """Φ̂ = W (PᵀW)⁻¹ C with the first `n_components` latent variables."""
        W, P, C = self.W[:, :n_components], self.P[:, :n_components], self.C[:n_components]
        return W @ np.linalg.solve(P.T @ W, C)


def nipals_pls1(X: np.ndarray, y: np.ndarray, n_components: int) -> PLSComponents:
    """NIPALS for one response, deflating X and y after each latent variable (no centring)."""
    X, y = np.array(X, dtype=float), np.array(y, dtype=float)
    p = X.shape[1]
    W, P, C = np.zeros((p, n_components)), np.zeros((p, n_components)), np.zeros(n_components)
    for a in range(n_components):
        w = X.T @ y
        norm = np.linalg.norm(w)
        if norm == 0.0:  # y is fully explained: no further latent variable exists
            return PLSComponents(W[:, :a], P[:, :a], C[:a])
        w /= norm
        t = X @ w
        tt = t @ t
        P[:, a], C[a], W[:, a] = X.T @ t / tt, y @ t / tt, w
        X -= np.outer(t, P[:, a])
        y -= C[a] * t
    return PLSComponents(W, P, C)


def kernel_pls1(XtX: np.ndarray, Xty: np.ndarray, n_components: int) -> PLSComponents:
    """The same components as `nipals_pls1`, from XᵀX and Xᵀy (Dayal & MacGregor's improved kernel PLS).

    With R = W (PᵀW)⁻¹ built column by column (r_a = w_a − Σ (p_jᵀ w_a) r_j), the scores are t_a = X r_a, so
    tᵀt = r_aᵀ XᵀX r_a and p_a = XᵀX r_a / tᵀt; only Xᵀy is deflated.
    """
    p = XtX.shape[0]
    xy = np.array(Xty, dtype=float)
    W, P, R = np.zeros((p, n_components)), np.zeros((p, n_components)), np.zeros((p, n_components))
    C = np.zeros(n_components)
    for a in range(n_components):
        norm = np.linalg.norm(xy)
        if norm <= 1e-14 * np.linalg.norm(Xty):
            return PLSComponents(W[:, :a], P[:, :a], C[:a])
        w = xy / norm
        for _ in range(2):  # NIPALS weights are orthonormal; re-orthogonalise what rounding lost (many ν)
            w -= W[:, :a] @ (W[:, :a].T @ w)
        w /= np.linalg.norm(w)
        r = w - R[:, :a] @ (P[:, :a].T @ w)
        tt = r @ XtX @ r
        if not tt > 0.0:  # rounding left Xᵀy a direction X does not see (a rank-deficient fold): nothing more to fit
            return PLSComponents(W[:, :a], P[:, :a], C[:a])
        P[:, a], C[a], W[:, a], R[:, a] = XtX @ r / tt, r @ xy / tt, w, r
        xy = xy - P[:, a] * (C[a] * tt)
    return PLSComponents(W, P, C)


def column_scale(XtX: np.ndarray) -> np.ndarray:
    """Column norms (from the Gram diagonal); zero columns keep scale 1 so they stay zero."""
    d = np.sqrt(np.clip(np.diag(XtX), 0.0, None))
    return np.where(d > 0, d, 1.0)


def pls_path(XtX: np.ndarray, Xty: np.ndarray, max_components: int) -> np.ndarray:
    """Coefficients (ν, p) for ν = 1 … max_components, kernel PLS on unit-norm columns, original units."""
    s = column_scale(XtX)
    comps = kernel_pls1(XtX / np.outer(s, s), Xty / s, max_components)
    return np.array([comps.coefficients(k) / s for k in range(1, comps.C.size + 1)])


# ------------------------------------------------------------------------------------------------------------
# Least squares and instrumental variables on the base parameters


# A direction a Gram-like matrix (AᵀA, or the IV's ZᵀA) does not see: its eigen- or singular value, columns
# scaled to unit norm, below this times the largest. It is the base parameters' rank cut (singular values of the
# column-normalised A below 1e-6 of the largest, dynid.identification.BASE_RTOL) squared, as a Gram squares them.
NULL_RTOL = 1e-12


def solve_normal(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Solve G x = g for a symmetric positive definite G, scaled to unit diagonal first (Gram of mixed units)."""
    s = column_scale(G)
    return scipy.linalg.solve(G / np.outer(s, s), g / s, assume_a="pos") / s


def unseen_directions(G: np.ndarray, rtol: float = NULL_RTOL) -> np.ndarray:
    """An orthonormal basis (columns) of the directions a Gram matrix G does not see, in G's unit-diagonal scaling
    (x = v / s for a direction v, s the column norms): none when G is positive definite to `rtol`."""
    s = column_scale(G)
    lam, V = np.linalg.eigh(G / np.outer(s, s))
    return V[:, lam <= rtol * max(float(lam[-1]), 0.0)]


def jackknife_se(estimates: np.ndarray) -> np.ndarray:
    """The jackknife's standard error of an estimate from its leave-one-out values (along axis 0):
    √((B − 1)/B · Σ (θ_(i) − θ̄)²)."""
    b = estimates.shape[0]
    return np.sqrt((b - 1) / b * np.sum((estimates - estimates.mean(axis=0)) ** 2, axis=0))


def restricted_solve(M: np.ndarray, g: np.ndarray, x0: np.ndarray, rtol: float = NULL_RTOL) -> np.ndarray:
    """x solving M x = g (square, Gram-like M) on the directions M sees, and keeping x0 on those it does not.

    With M's columns scaled to unit norm, x = x0 + the minimum-norm least-squares solution of M d = g − M x0,
    singular values below `rtol` times the largest counted as zero. Where M has full numerical rank this is
    M⁻¹ g whatever x0; where it is singular along v, x's component along v is x0's: the data say nothing there.
    """
    s = column_scale(M.T @ M)
    U, sv, Vt = np.linalg.svd(M / s[None, :])
    keep = sv > rtol * sv[0] if sv.size and sv[0] > 0 else np.zeros(sv.size, dtype=bool)
    d = Vt[keep].T @ ((U[:, keep].T @ (g - M @ x0)) / sv[keep])
    return x0 + d / s


def base_least_squares(gram: np.ndarray, base: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
    """β̂ minimising |A_b β − b|² from the augmented Gram [A b]ᵀ[A b] (p+1, p+1); `base`: columns of A_b.

    Rows that do not determine every base parameter (a jackknife fold of a short run: a joint that moved one way
    in the left-out block only) leave the directions they do not see at `prior` (β; zero by default)."""
    p = gram.shape[0] - 1
    G, g = gram[np.ix_(base, base)], gram[base, p]
    if unseen_directions(G).shape[1] == 0:
        return solve_normal(G, g)
    return restricted_solve(G, g, np.zeros(len(base)) if prior is None else prior)


@dataclass(frozen=True)
class InputColumns:
    """For each row channel whose equation holds one motor's input with an unknown gain: the Φ index of that
    gain. The instrument of that column is the model's own predicted input, −û = (row without it)·Φ̂ / φ̂_m."""

    gain_index: dict[int, int]  # row channel -> Φ index of the gain multiplying that row's input


def instrument_map(p: int, gain: int, phi: np.ndarray) -> np.ndarray:
    """G with z = a_s G: the instrument row a_s with its gain entry replaced by −(a_s without it)·Φ̂ / φ̂_g."""
    keep = np.eye(p)
    keep[gain, gain] = 0.0
    return keep @ (np.eye(p) - np.outer(phi, np.eye(p)[gain]) / phi[gain])


def instrumented(X: np.ndarray, gain: int, phi: np.ndarray) -> np.ndarray:
    """instrument_map(p, gain, phi)ᵀ @ X in O(p²): G is the identity but for its column `gain`, which holds
    −φ̂_i/φ̂_g (0 at i = g), so Gᵀ X is X with row `gain` replaced by that column against X."""
    w = -phi / phi[gain]
    w[gain] = 0.0
    out = X.copy()
    out[gain] = w @ X
    return out


def instrumental_variables(
    cross: np.ndarray,
    cross_b: np.ndarray,
    base: np.ndarray,
    beta0: np.ndarray,
    inputs: InputColumns,
    iterations: int = 20,
    tol: float = 1e-10,
    prior: np.ndarray | None = None,
) -> tuple[np.ndarray, int, float]:
    """Iterated IV on the base parameters: β = (Zᵀ A_b)⁻¹ Zᵀ b, Z from the instrument regressors.

    `cross[c]` = Σ Z₀ᵀ A over the rows of channel c (Z₀: the regressor along the instrument trajectory, A: the
    measured one), `cross_b[c]` = Σ Z₀ᵀ b. The instruments' input columns hold the model's predicted inputs,
    which depend on Φ̂, so the estimate is iterated to a fixed point from `beta0`. Where Zᵀ A_b is singular (rows
    that do not see every base direction) those directions stay at `prior` (default `beta0`), as in
    `restricted_solve`. Returns (β̂, iterations, the last step: max relative change of β̂, below `tol` once
    converged); an iteration that cannot go on (a gain at zero, a step that is not finite) ends with the last
    iterate and an infinite step.

    The step is relaxed: β ← β + ω (F(β) − β), ω halved whenever the step grew and grown back towards 1 while it
    shrinks. Where the plain iteration contracts (every run long enough for its rank) ω stays 1 and this is the plain
    iteration; on a run too short for its rank the plain map can fall into a cycle (steps 1, 2, 11, 32, 15, …
    repeating) on one CPU's rounding and reach the fixed point on another's, and the relaxed one reaches it on both.
    """
    r, p, _ = cross.shape
    beta = beta0.copy()
    x0 = beta0 if prior is None else prior
    step, last, omega = np.inf, np.inf, 1.0
    for it in range(1, iterations + 1):
        phi = np.zeros(p)
        phi[base] = beta
        ZA, Zb = np.zeros((p, p)), np.zeros(p)
        for c in range(r):
            g = inputs.gain_index.get(c)
            if g is None:
                ZA += cross[c]
                Zb += cross_b[c]
                continue
            if not (np.isfinite(phi[g]) and phi[g] != 0.0):  # no predicted input to instrument this channel with
                return beta, it - 1, np.inf
            ZA += instrumented(cross[c], g, phi)  # instrument_map(p, g, phi).T @ cross[c]
            Zb += instrumented(cross_b[c], g, phi)
        M = ZA[np.ix_(base, base)]
        s = column_scale(M.T @ M)
        sv = scipy.linalg.svdvals(M / s[None, :])
        if sv[-1] > NULL_RTOL * sv[0]:
            new = np.linalg.solve(M / s[None, :], Zb[base]) / s
        else:
            new = restricted_solve(M, Zb[base], x0)
        if not np.all(np.isfinite(new)):
            return beta, it - 1, np.inf
        step = float(np.max(np.abs(new - beta) / np.maximum(np.abs(new), 1e-12)))
        omega = max(omega / 2, RELAX_MIN) if step > last else min(2 * omega, 1.0)
        last = step
        beta = new if omega == 1.0 else beta + omega * (new - beta)
        if step < tol:
            return beta, it, step
    return beta, iterations, step


RELAX_MIN = 1 / 64  # the IV iteration's smallest relaxation
