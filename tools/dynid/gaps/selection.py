"""Forward selection of candidate effects by cross-validated residual reduction on held-out time blocks.

The design is the standard model's weighted rows (every row in units of its own noise, rows at rest dropped),
reduced to its identifiable subspace Z. Statistics are Gram matrices per (time block, row channel), so a
candidate costs one cross product with Z, and every fold's fit and held-out error are small solves.

A candidate is accepted when (1) it lowers the held-out weighted SSE of the channels it acts on by at least
`min_gain` (relative), on every fold's average, and (2) its in-sample F-test is significant at `alpha` with
the samples counted after decimation. (1) is the practical bar: simulation and robot residuals are coloured
(derivative filters, vibration), so an F-test alone names something on any long enough run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats as sps

from .candidates import Candidate


SPAN_TOL = 1e-9  # a candidate direction whose residual after the design is below this share of its size: spanned


def _pinv(G: np.ndarray) -> np.ndarray:
    s, V = np.linalg.eigh(G)
    keep = s > 1e-10 * max(s.max(), 1e-300)
    return (V[:, keep] / s[keep]) @ V[:, keep].T


def _solve(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Minimum-norm least squares from normal equations (the augmented design may be rank deficient)."""
    return _pinv(G) @ g


def _bordered_solve(Ginv: np.ndarray, G: np.ndarray, g: np.ndarray, d: int) -> np.ndarray:
    """Least squares of the normal equations G (d + K square) whose leading d×d block has the (cached) pseudo-
    inverse Ginv: a Schur complement on the K candidate columns, K small, instead of a new (d + K) solve.
    Candidate directions the design already spans (Schur complement ~ 0 against their own scale) get 0."""
    B, C = G[:d, d:], G[d:, d:]
    GiB = Ginv @ B
    S = C - B.T @ GiB
    s, V = np.linalg.eigh(S)
    keep = s > SPAN_TOL * max(float(np.abs(np.diag(C)).max()), 1e-300)
    th = V[:, keep] @ ((V[:, keep].T @ (g[d:] - GiB.T @ g[:d])) / s[keep])
    return np.concatenate([Ginv @ g[:d] - GiB @ th, th])


@dataclass
class Design:
    """Per (block, channel) statistics of the weighted system D x = y, D = [Z, accepted effect columns]."""

    D: np.ndarray  # (N, r, d) weighted columns
    y: np.ndarray  # (N, r) weighted right-hand side
    bounds: np.ndarray  # (B + 1,) sample index where each contiguous time block starts, and N
    G: np.ndarray = field(init=False)  # (B, r, d, d)
    g: np.ndarray = field(init=False)  # (B, r, d)
    yy: np.ndarray = field(init=False)  # (B, r)
    rows: np.ndarray = field(init=False)  # (B, r) rows that count (nonzero weight)
    inv_folds: np.ndarray = field(init=False)  # (B, d, d) pseudo-inverse of each fold's training normal matrix
    inv_all: np.ndarray = field(init=False)  # (d, d) the same over all blocks

    @property
    def n_blocks(self) -> int:
        return len(self.bounds) - 1

    def _block(self, b: int) -> slice:
        return slice(int(self.bounds[b]), int(self.bounds[b + 1]))

    def __post_init__(self) -> None:
        B, r, d = self.n_blocks, self.D.shape[1], self.D.shape[2]
        self.G, self.g, self.yy, self.rows = np.zeros((B, r, d, d)), np.zeros((B, r, d)), np.zeros((B, r)), np.zeros((B, r))
        for b in range(B):
            sel = self._block(b)
            Db, yb = self.D[sel], self.y[sel]
            self.G[b] = np.einsum("nri,nrj->rij", Db, Db)
            self.g[b] = np.einsum("nri,nr->ri", Db, yb)
            self.yy[b] = (yb**2).sum(axis=0)
            self.rows[b] = (np.abs(Db).sum(axis=2) > 0).sum(axis=0)
        Gb = self.G.sum(axis=1)
        self.inv_all = _pinv(Gb.sum(axis=0))
        self.inv_folds = np.stack([_pinv(Gb.sum(axis=0) - Gb[b]) for b in range(B)])

    def cross(self, E: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(D'E, E'E, E'y) per (block, channel) for extra columns E (N, r, K)."""
        B, r, d, K = self.n_blocks, self.D.shape[1], self.D.shape[2], E.shape[2]
        DE, EE, Ey = np.zeros((B, r, d, K)), np.zeros((B, r, K, K)), np.zeros((B, r, K))
        active = np.flatnonzero(np.abs(E).sum(axis=(0, 2)) > 0)
        for b in range(B):
            sel = self._block(b)
            for c in active:  # views, no copies: a candidate touches few channels
                Ec = E[sel, c]
                DE[b, c] = self.D[sel, c].T @ Ec
                EE[b, c] = Ec.T @ Ec
                Ey[b, c] = Ec.T @ self.y[sel, c]
        return DE, EE, Ey

    def augmented(self, E: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(G, g) per (block, channel) of [D, E]."""
        if E is None:
            return self.G, self.g
        DE, EE, Ey = self.cross(E)
        top = np.concatenate([self.G, DE], axis=3)
        bottom = np.concatenate([np.swapaxes(DE, 2, 3), EE], axis=3)
        return np.concatenate([top, bottom], axis=2), np.concatenate([self.g, Ey], axis=2)

    def cv_sse(self, E: np.ndarray | None) -> np.ndarray:
        """(B, r) held-out SSE of each block and channel, fitting on the other blocks."""
        G, g = self.augmented(E)
        Gb, gb = G.sum(axis=1), g.sum(axis=1)  # (B, d, d), (B, d): all channels of a block
        Gt, gt = Gb.sum(axis=0), gb.sum(axis=0)
        out = np.zeros((self.n_blocks, G.shape[1]))
        d = self.D.shape[2]
        for b in range(self.n_blocks):
            x = self.inv_folds[b] @ (gt - gb[b]) if E is None else _bordered_solve(self.inv_folds[b], Gt - Gb[b], gt - gb[b], d)
            out[b] = np.einsum("i,rij,j->r", x, G[b], x) - 2 * g[b] @ x + self.yy[b]
        return out

    def fit(self, E: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(x over all blocks, in-sample SSE per channel)."""
        G, g = self.augmented(E)
        Gs, gs = G.sum(axis=(0, 1)), g.sum(axis=(0, 1))
        x = self.inv_all @ gs if E is None else _bordered_solve(self.inv_all, Gs, gs, self.D.shape[2])
        Gc, gc, yy = G.sum(axis=0), g.sum(axis=0), self.yy.sum(axis=0)
        return x, np.einsum("i,rij,j->r", x, Gc, x) - 2 * gc @ x + yy


@dataclass
class Trial:
    candidate: Candidate
    channels: np.ndarray  # row channels it acts on
    cv_before: float  # held-out SSE on those channels
    cv_after: float
    p_value: float

    @property
    def gain(self) -> float:
        return 1.0 - self.cv_after / self.cv_before if self.cv_before > 0 else 0.0


def evaluate(design: Design, cand: Candidate, weights: np.ndarray, base_cv: np.ndarray, base_sse: float, dof: int) -> Trial:
    """The candidate's columns, weighted like the rows (1/σ, 0 at rest), against the current design."""
    E = weighted_columns(cand.values, weights)
    channels = np.flatnonzero(np.abs(E).sum(axis=(0, 2)) > 0)
    cv = design.cv_sse(E)
    _, sse = design.fit(E)
    k = E.shape[2]
    n = int(design.rows.sum())
    drop = max(base_sse - float(sse.sum()), 0.0)
    F = (drop / k) / (float(sse.sum()) / max(n - dof - k, 1))
    p = float(sps.f.sf(F, k, max(n - dof - k, 1)))
    return Trial(cand, channels, float(base_cv[:, channels].sum()), float(cv[:, channels].sum()), p)


def weighted_columns(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    return values * weights[:, :, None]
