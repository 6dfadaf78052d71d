"""Forward selection of candidate effects by cross-validated residual reduction on held-out time blocks.

The design is the standard model's weighted rows (every row in units of its own noise, rows at rest dropped),
reduced to its identifiable subspace Z. Statistics are Gram matrices per (time block, row channel), so a
candidate costs one cross product with Z (a round's candidates crossed together, `batched`: one read of Z for many),
and every fold's fit and held-out error are small solves.

A candidate is accepted when (1) it lowers the held-out weighted SSE of the channels it acts on by at least
`min_gain` (relative), on every fold's average, and (2) its coefficients are significant by a Wald test whose
covariance is robust to autocorrelated, heteroscedastic residuals (`robust_p_value`: batch means of the scores
over ~1 s batches). Residuals of a real or simulated arm are coloured (derivative filters, supply variation,
stiction: lag-1 autocorrelation 0.5–0.9 at the decimated rate), so a test that counts every row as independent
(an F-test) over-counts the evidence by one to two orders of magnitude and names something on a control run.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
from scipy.special import fdtrc

from ..margins import borderline
from ..robot.effect_library import Candidate

MIN_DOF = 10  # batches beyond the number of columns tested, at least (the F reference's denominator dof)
SPAN_TOL = 1e-9  # a candidate direction whose residual after the design is below this share of its size: spanned


def _pinv(G: np.ndarray) -> np.ndarray:
    """Pseudo-inverse of an equilibrated normal matrix (unit-norm columns): the same cut as `_bordered_solve`, so a
    column the selection kept is kept by the refit too."""
    s, V = np.linalg.eigh(G)
    keep = s > SPAN_TOL * max(float(np.diag(G).max()), 1e-300)
    return (V[:, keep] / s[keep]) @ V[:, keep].T


def _norms(X: np.ndarray) -> np.ndarray:
    """(K,) Euclidean norm of each column of X (N, r, K) over all rows; 1 for an all-zero column."""
    n = np.sqrt(np.einsum("nrk,nrk->k", X, X))
    return np.where(n > 0, n, 1.0)


TOUCH_RTOL = 1e-10  # a channel whose share of a candidate's columns is below this (in amplitude) is not touched


def columns_on(E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(channels E touches, the norms of `_norms`) of candidate columns E (N, r, K), in one pass over E.

    A channel is touched when its energy is more than rounding residue of the largest channel's: which channels a
    candidate acts on sets the held-out SSE it is judged by, so that set must not hang on a 1e-17 that one CPU's
    kernels make exactly zero and another's do not."""
    energy = np.einsum("nrk,nrk->rk", E, E)
    n = np.sqrt(energy.sum(axis=0))
    per_channel = energy.sum(axis=1)
    touched = per_channel > TOUCH_RTOL**2 * max(float(per_channel.max(initial=0.0)), 1e-300)
    return np.flatnonzero(touched), np.where(n > 0, n, 1.0)


def _bordered_solve(Ginv: np.ndarray, B: np.ndarray, C: np.ndarray, gd: np.ndarray, ge: np.ndarray) -> np.ndarray:
    """Least squares of the normal equations [[G, B], [Bᵀ, C]] x = [gd, ge] whose leading d×d block G has the
    (cached) pseudo-inverse Ginv: a Schur complement on the K candidate columns, K small, instead of a new (d + K)
    solve. Candidate directions the design already spans (Schur complement ~ 0 against their own scale) get 0.
    Leading dimensions of every argument are a batch (each held-out block's solve at once)."""
    GiB = Ginv @ B
    S = C - np.swapaxes(B, -1, -2) @ GiB
    s, V = np.linalg.eigh(S)
    scale = np.abs(np.diagonal(C, axis1=-2, axis2=-1)).max(axis=-1, keepdims=True)
    keep = s > SPAN_TOL * np.maximum(scale, 1e-300)
    rhs = ge - _matvec(np.swapaxes(GiB, -1, -2), gd)
    proj = _matvec(np.swapaxes(V, -1, -2), rhs)
    th = _matvec(V, np.divide(proj, s, out=np.zeros_like(proj), where=keep))
    return np.concatenate([_matvec(Ginv, gd) - _matvec(GiB, th), th], axis=-1)


def _matvec(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """M v over leading batch dimensions: M (..., m, k), v (..., k) -> (..., m)."""
    return (M @ v[..., None])[..., 0]


def _quadratic(M: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., r) uᵀ M_c v for each of the r matrices M_c of M (..., r, m, k), as one matrix-vector product."""
    *lead, r, m, k = M.shape
    return _matvec(_matvec(M.reshape(*lead, r * m, k), v).reshape(*lead, r, m), u)


def _sse(G: np.ndarray, g: np.ndarray, yy: np.ndarray, x: np.ndarray,
         extra: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Per channel, the SSE (y − [D E] x)ᵀ(y − [D E] x) from the normal statistics: G (r, d, d), g (r, d), yy (r,)
    of D, and `extra` = (DᵀE (r, d, K), EᵀE (r, K, K), Eᵀy (r, K)) of the candidate columns E, if any; leading
    dimensions (of x too) are a batch."""
    d = G.shape[-1]
    xd = x[..., :d]
    sse = _quadratic(G, xd, xd) - 2 * _matvec(g, xd) + yy
    if extra is not None:
        DE, EE, Ey = extra
        xe = x[..., d:]
        sse += 2 * _quadratic(DE, xd, xe) + _quadratic(EE, xe, xe) - 2 * _matvec(Ey, xe)
    return sse


@dataclass
class Design:
    """Per (block, channel) statistics of the weighted system D x = y, D = [Z, accepted effect columns].

    Every column is scaled to unit norm inside (G, g, the pseudo-inverses, the bordered solves): a candidate's
    columns can be 1e-6 of the design's (a Stribeck curve that lives only near q̇ = 0), and a cut relative to the
    largest eigenvalue would drop them in one solve and keep them in another. `fit` returns x in D's own units.

    A candidate E is judged by its cross products with [D y] alone: D is kept channel by channel, [D y] of a channel
    one contiguous (N, d + 1) array, so each (block, channel) is one product that reads only that channel's rows,
    and the (d + K)-square normal matrices are never assembled."""

    D: np.ndarray  # (N, r, d) weighted columns (after __post_init__, a view of the channel-major copy)
    y: np.ndarray  # (N, r) weighted right-hand side
    bounds: np.ndarray  # (B + 1,) sample index where each contiguous time block starts, and N
    G: np.ndarray = field(init=False)  # (B, r, d, d)
    g: np.ndarray = field(init=False)  # (B, r, d)
    yy: np.ndarray = field(init=False)  # (B, r)
    rows: np.ndarray = field(init=False)  # (B, r) rows that count (nonzero weight)
    inv_folds: np.ndarray = field(init=False)  # (B, d, d) pseudo-inverse of each fold's training normal matrix
    inv_all: np.ndarray = field(init=False)  # (d, d) the same over all blocks
    scale: np.ndarray = field(init=False)  # (d,) norm of each column of D; G, g are of D / scale
    # the last candidate's `cross` (a candidate is fitted, then cross-validated: the same E twice in a row)
    _crossed: tuple = field(init=False, default=(None, None), repr=False)
    # `cross_many`'s results by id(E), with E itself (so the id stays that E's): until `forget`
    _batch: dict = field(init=False, default_factory=dict, repr=False)

    @property
    def n_blocks(self) -> int:
        return len(self.bounds) - 1

    def _block(self, b: int) -> slice:
        return slice(int(self.bounds[b]), int(self.bounds[b + 1]))

    def __post_init__(self) -> None:
        N, r, d = self.D.shape
        B = self.n_blocks
        self._Dy = np.empty((r, N, d + 1))  # per channel [D y], contiguous
        self._Dy[:, :, :d] = self.D.transpose(1, 0, 2)
        self._Dy[:, :, d] = self.y.T
        self.D = self._Dy[:, :, :d].transpose(1, 0, 2)
        self.G, self.g, self.yy, self.rows = np.zeros((B, r, d, d)), np.zeros((B, r, d)), np.zeros((B, r)), np.zeros((B, r))
        for b in range(B):
            P = self._Dy[:, self._block(b)]  # (r, n, d + 1)
            Q = P.transpose(0, 2, 1) @ P  # per channel one BLAS product: G, g and yy together
            self.G[b], self.g[b], self.yy[b] = Q[:, :d, :d], Q[:, :d, d], Q[:, d, d]
            self.rows[b] = (np.abs(P[:, :, :d]).sum(axis=2) > 0).sum(axis=1)
        self.scale = _norms(self.D)
        self.G /= np.outer(self.scale, self.scale)
        self.g /= self.scale
        # the sums every solve starts from: over channels (per block), over blocks (per channel), over both
        self._G_block, self._g_block = self.G.sum(axis=1), self.g.sum(axis=1)
        self._G_channel, self._g_channel, self._yy_channel = self.G.sum(axis=0), self.g.sum(axis=0), self.yy.sum(axis=0)
        self._G_all, self._g_all = self._G_block.sum(axis=0), self._g_block.sum(axis=0)
        self.inv_all = _pinv(self._G_all)
        self.inv_folds = np.stack([_pinv(self._G_all - self._G_block[b]) for b in range(B)])

    def cross(self, E: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(D'E, E'E, E'y) per (block, channel) for extra columns E (N, r, K), both scaled to unit-norm columns, and
        E's column norms."""
        if self._crossed[0] is E:
            return self._crossed[1]
        held = self._batch.get(id(E))
        out = held[1] if held is not None and held[0] is E else self._cross_products([E])[0]
        self._crossed = (E, out)
        return out

    def cross_many(self, Es: list[np.ndarray]) -> None:
        """`cross` of several candidates in one pass over D, kept for `cross` until `forget`."""
        for E, out in zip(Es, self._cross_products(Es)):
            self._batch[id(E)] = (E, out)

    def _cross_products(self, Es: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """`cross` of each E. Per channel, the columns of every candidate on it side by side, one product with [D y]
        per block: these products are bound by reading D (a candidate has 1-6 columns), so D is read once for all
        of them rather than once for each. Each candidate's EᵀE per block comes from one batched product per width:
        a round holds hundreds of candidates, and a product each (block by block) was mostly Python's overhead."""
        B, r, d = self.n_blocks, self.D.shape[1], self.D.shape[2]
        touched = [columns_on(E) for E in Es]
        widths = [E.shape[2] for E in Es]
        stats = [(np.zeros((B, r, d, K)), np.zeros((B, r, K, K)), np.zeros((B, r, K))) for K in widths]
        blocks = [self._block(b) for b in range(B)]
        for c in range(r):
            on = [i for i, (active, _) in enumerate(touched) if c in active]  # a candidate touches few channels
            if not on:
                continue
            columns = np.concatenate([Es[i][:, c] for i in on], axis=1)  # (N, ΣK), contiguous
            ends = np.cumsum([widths[i] for i in on])
            starts = ends - [widths[i] for i in on]
            # (B, d + 1, ΣK): D'E and y'E of all of them at once, block by block
            M = np.stack([self._Dy[c, sel].T @ columns[sel] for sel in blocks])
            for i, lo, hi in zip(on, starts, ends):
                DE, _, Ey = stats[i]
                DE[:, c], Ey[:, c] = M[:, :d, lo:hi], M[:, d, lo:hi]
            for K in sorted({widths[i] for i in on}):  # E'E: the candidates of one width as one (m, N, K) stack
                group = [(i, lo) for i, lo in zip(on, starts) if widths[i] == K]
                cols = np.stack([columns[:, lo:lo + K] for _, lo in group])
                EE = np.stack([cols[:, sel].transpose(0, 2, 1) @ cols[:, sel] for sel in blocks])  # (B, m, K, K)
                for j, (i, _) in enumerate(group):
                    stats[i][1][:, c] = EE[:, j]
        for (_, e), (DE, EE, Ey) in zip(touched, stats):  # to unit-norm columns, in place
            DE /= np.outer(self.scale, e)
            EE /= np.outer(e, e)
            Ey /= e
        return [(DE, EE, Ey, e) for (_, e), (DE, EE, Ey) in zip(touched, stats)]

    def forget(self) -> None:
        """Drop what `cross_many` kept (and the candidates' columns it held)."""
        self._batch.clear()
        self._crossed = (None, None)

    def columns_of(self, E: np.ndarray, keep: list[int]) -> np.ndarray:
        """E[:, :, keep], with its `cross` statistics sliced from E's rather than computed again (each column is
        scaled on its own, so the slice is exact): a candidate judged again on fewer of its columns."""
        DE, EE, Ey, e = self.cross(E)
        sub = E[:, :, keep]
        self._crossed = (sub, (DE[..., keep], EE[:, :, keep][:, :, :, keep], Ey[..., keep], e[keep]))
        return sub

    def cv_sse(self, E: np.ndarray | None) -> np.ndarray:
        """(B, r) held-out SSE of each block and channel, fitting on the other blocks (every fold's solve at once)."""
        if E is None:
            return _sse(self.G, self.g, self.yy, _matvec(self.inv_folds, self._g_all - self._g_block))
        DE, EE, Ey, _ = self.cross(E)
        DE_block, EE_block, Ey_block = DE.sum(axis=1), EE.sum(axis=1), Ey.sum(axis=1)
        DE_all, EE_all, Ey_all = DE_block.sum(axis=0), EE_block.sum(axis=0), Ey_block.sum(axis=0)
        x = _bordered_solve(self.inv_folds, DE_all - DE_block, EE_all - EE_block, self._g_all - self._g_block,
                            Ey_all - Ey_block)
        return _sse(self.G, self.g, self.yy, x, (DE, EE, Ey))

    def fit(self, E: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(x over all blocks in the columns' own units, in-sample SSE per channel)."""
        if E is None:
            x = self.inv_all @ self._g_all
            return x / self.scale, _sse(self._G_channel, self._g_channel, self._yy_channel, x)
        DE, EE, Ey, e = self.cross(E)
        DE_channel, EE_channel, Ey_channel = DE.sum(axis=0), EE.sum(axis=0), Ey.sum(axis=0)
        x = _bordered_solve(self.inv_all, DE_channel.sum(axis=0), EE_channel.sum(axis=0), self._g_all,
                            Ey_channel.sum(axis=0))
        sse = _sse(self._G_channel, self._g_channel, self._yy_channel, x, (DE_channel, EE_channel, Ey_channel))
        return x / np.concatenate([self.scale, e]), sse

    def fold_blind(self, share: float = 0.99) -> np.ndarray:
        """(d,) True for a coordinate that some fold (every block but one) cannot determine: less than `share` of it
        lies in that fold's span (the diagonal of the projector G⁺G), so its replicate there is the pseudo-inverse's
        choice, not an estimate (an effect inside one block; two F/T steps that differ only there)."""
        span = np.einsum("bij,bjk->bik", self.inv_folds, self._G_all[None] - self._G_block)
        return (np.diagonal(span, axis1=1, axis2=2) < share).any(axis=0)

    def fold_fits(self) -> list[np.ndarray]:
        """x (own units) fitted on all blocks but b, for each b: the block jackknife's replicates."""
        return [self.inv_folds[b] @ (self._g_all - self._g_block[b]) / self.scale for b in range(self.n_blocks)]


WORSE_TOLERANCE = 0.05  # a fix is refused when a channel's held-out RMS grows by over 5 % ...
WORSE_NOISE = 1.0  # ... and by over its noise std (worse_channels)


@dataclass
class Trial:
    candidate: Candidate
    channels: np.ndarray  # row channels it acts on
    before_blocks: np.ndarray  # (B,) held-out SSE on those channels, per block
    after_blocks: np.ndarray
    p_value: float

    @property
    def cv_before(self) -> float:
        return float(self.before_blocks.sum())

    @property
    def cv_after(self) -> float:
        return float(self.after_blocks.sum())

    @property
    def gain(self) -> float:
        return 1.0 - self.cv_after / self.cv_before if self.cv_before > 0 else 0.0


def evaluate(design: Design, cand: Candidate, weights: np.ndarray, base_cv: np.ndarray,
             E: np.ndarray | None = None) -> Trial:
    """The candidate's columns E, weighted like the rows (1/σ, 0 at rest; made here if not given), against the
    current design; its p-value is left NaN (`robust_p_value` costs a pass over the rows: only the best candidate
    of a round gets one)."""
    if E is None:
        E = weighted_columns(cand.values, weights)
    channels = columns_on(E)[0]
    before = base_cv[:, channels].sum(axis=1)
    if cand.positive:
        k = E.shape[2]
        if not np.all(design.fit(E)[0][-k:][list(cand.positive)] > 0):  # a negative Stribeck bump or mass: never named
            return Trial(cand, channels, before, before, float("nan"))
    cv = design.cv_sse(E)
    return Trial(cand, channels, before, cv[:, channels].sum(axis=1), float("nan"))


def worse_channels(before_cv: np.ndarray, after_cv: np.ndarray, rows: np.ndarray) -> list[tuple[int, float, bool]]:
    """(row channel, relative increase) of every channel whose held-out error a fix makes worse.

    Worse: the held-out RMS grows by over 5 % and by over the channel's noise std (the rows are in noise units).
    A change smaller than the noise is not held against a fix: a true base tilt, refitted, moves a PWM channel at
    1.3× its floor by 0.2× the noise, while a wrong F/T gain matrix moved the real iCub leg sensor's fy from 27× to
    37×. `before_cv`, `after_cv`: (B, r) held-out SSE per block; `rows`: (B, r) rows per block. Returns the relative
    growth of the RMS."""
    n = np.maximum(rows.sum(axis=0), 1)
    was, now = np.sqrt(before_cv.sum(axis=0) / n), np.sqrt(after_cv.sum(axis=0) / n)
    out = []
    for c in np.flatnonzero(was > 0):
        ratio, diff = float(now[c] / was[c]), float(now[c] - was[c])
        # on either threshold's band the channel counts as worse: the fix is refused rather than named on one CPU only
        near = borderline(ratio, 1 + WORSE_TOLERANCE) or borderline(diff, WORSE_NOISE)
        if (ratio > 1 + WORSE_TOLERANCE or borderline(ratio, 1 + WORSE_TOLERANCE)) and \
                (diff > WORSE_NOISE or borderline(diff, WORSE_NOISE)):
            out.append((int(c), ratio - 1, near))
    return out


def robust_p_value(design: Design, E: np.ndarray, batch: int) -> float:
    """p-value of H0: θ = 0 for the extra columns E (N, r, K), by a Wald test with a batch-means (HAC) covariance.

    Frisch–Waugh: Ẽ = E minus its projection on D, θ = (ẼᵀẼ)⁻¹ Ẽᵀy. The score of sample t is s_t = Σ_r Ẽ_tr e_tr
    (e the residual of the fit with E); summed over consecutive batches of `batch` samples, long against the
    residual's correlation time, the batch sums S_b are nearly independent, so Ω = Σ_b S_b S_bᵀ estimates the
    score's covariance whatever the autocorrelation and heteroscedasticity within a batch. W = θᵀ V⁻¹ θ with
    V = M⁻¹ Ω M⁻¹ (M = ẼᵀẼ), and (m − K)/(K (m − 1)) W ~ F(K, m − K) over m batches (Hotelling's T²); at
    least K + MIN_DOF batches, shorter than `batch` samples if need be."""
    n, k = E.shape[0], E.shape[2]
    Ds = design.D / design.scale
    beta = design.inv_all @ np.einsum("nri,nrk->ik", Ds, E)
    Et = E - np.einsum("nri,ik->nrk", Ds, beta)
    x, _ = design.fit(E)
    e = design.y - design.D @ x[: design.D.shape[2]] - E @ x[design.D.shape[2] :]
    M = np.einsum("nrk,nrl->kl", Et, Et)
    Minv = np.linalg.pinv(M)
    theta = Minv @ np.einsum("nrk,nr->k", Et, design.y)
    scores = np.einsum("nrk,nr->nk", Et, e)
    # m > K batches are needed to invert Ω: an effect with many columns (the F/T gain's 35) gets shorter batches
    m = min(max(n // max(batch, 1), k + MIN_DOF), n)
    S = np.stack([b.sum(axis=0) for b in np.array_split(scores, m)])
    if m <= k:
        return 1.0
    V = Minv @ (S.T @ S) @ Minv
    W = float(theta @ np.linalg.pinv(V) @ theta)
    # F(k, m − k)'s survival function (scipy.stats.f.sf's formula, from scipy.special; a W rounded below 0 is 0).
    return float(fdtrc(k, m - k, max((m - k) / (k * (m - 1)) * W, 0.0)))


def weighted_columns(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    return values * weights[:, :, None]


CROSS_BATCH_BYTES = 64 * 2**20  # candidates' weighted columns held at once for one `Design.cross_many`


def batched(design: Design, candidates: Iterable[Candidate],
            weights: np.ndarray) -> Iterator[tuple[Candidate, np.ndarray]]:
    """(candidate, its weighted columns) in turn, the columns crossed with the design a batch at a time
    (`Design.cross_many`, about CROSS_BATCH_BYTES of columns each), so a round of candidates reads D a few times,
    not once per candidate."""
    chunk: list[Candidate] = []
    size = 0

    def flush() -> Iterator[tuple[Candidate, np.ndarray]]:
        Es = [weighted_columns(c.values, weights) for c in chunk]
        design.cross_many(Es)
        yield from zip(chunk, Es)
        design.forget()

    for c in candidates:
        chunk.append(c)
        size += c.values.nbytes
        if size >= CROSS_BATCH_BYTES:
            yield from flush()
            chunk, size = [], 0
    if chunk:
        yield from flush()
