"""Base parameters: the numerical rank of A and the identifiable combinations of Φ.

Columns are first scaled to unit norm (the rank must not depend on units). The rank is the number of
singular values above `rtol` times the largest; column pivoting (`pivot_columns`, QR's rule with ties broken by
the parameters' order) then picks that many well-conditioned columns as the base parameters' representatives
(Gautier's numerical method). Every other column is a
combination of them, A_d = A_b K, so only β = Φ_b + K Φ_d is identifiable. Everything works from a p×p
triangular factor accumulated over chunks of rows, so a long experiment needs no fully stacked A.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ...margins import borderline_log
from ..model import RobotModel
from .stack import DEFAULT_CHUNK, DEFAULT_MIN_SPEED, Signals, StackedSystem, build_stacked, iter_stacked, row_weights

DEFAULT_RTOL = 1e-8


@dataclass(frozen=True)
class BaseParameters:
    names: tuple[str, ...]  # all of Φ
    rank: int
    independent: np.ndarray  # indices of Φ_b (the base parameters' representatives)
    dependent: np.ndarray  # indices of Φ_d
    K: np.ndarray  # (rank, n_dependent): β = Φ_b + K Φ_d
    singular_values: np.ndarray  # of the column-normalised weighted A, descending
    unidentifiable: tuple[str, ...]  # parameters with a zero column (they act on no row)
    rtol: float = DEFAULT_RTOL  # the rank cut, relative to the largest singular value

    @property
    def on_the_cut(self) -> np.ndarray:
        """Singular values (relative to the largest) that sit on the rank cut's band (dynid.margins): left out of
        the rank, and worth saying so, since another CPU's rounding could count them in."""
        rel = self.singular_values / self.singular_values[0] if self.singular_values.size and self.singular_values[0] > 0 \
            else np.zeros(0)
        return np.array([r for r in rel if borderline_log(float(r), self.rtol)])

    @property
    def condition_number(self) -> float:
        s = self.singular_values[: self.rank]
        return float(s[0] / s[-1]) if self.rank else float("inf")  # nothing excited at all

    def base(self, phi: np.ndarray) -> np.ndarray:
        """β = Φ_b + K Φ_d."""
        return phi[self.independent] + self.K @ phi[self.dependent]

    def combinations(self, tol: float = 1e-10) -> list[str]:
        """Each base parameter as a readable combination, e.g. 'r_hand.mcz + 0.0415·r_hand.m'."""
        out = []
        for i, col in enumerate(self.independent):
            terms = [self.names[col]]
            for j, d in enumerate(self.dependent):
                k = self.K[i, j]
                if abs(k) > tol:
                    terms.append(f"{'-' if k < 0 else '+'} {abs(k):.6g}·{self.names[d]}")
            out.append(" ".join(terms))
        return out


def triangular_factor(chunks: Iterable[tuple[np.ndarray, np.ndarray]], p: int) -> np.ndarray:
    """R (p×p) with RᵀR = AᵀA, accumulated a chunk of rows at a time: memory stays p×p + one chunk."""
    R = np.zeros((0, p))
    for A, _ in chunks:
        R = scipy.linalg.qr(np.vstack([R, A]), mode="r", check_finite=False)[0][: min(p, R.shape[0] + A.shape[0])]
    return R


def base_parameters_from_factor(R: np.ndarray, names: tuple[str, ...], rtol: float = DEFAULT_RTOL) -> BaseParameters:
    """Base-parameter structure from a triangular factor of the weighted A (see `triangular_factor`)."""
    p = R.shape[1]
    R = np.vstack([R, np.zeros((max(0, p - R.shape[0]), p))])
    norms = np.linalg.norm(R, axis=0)  # = column norms of A
    zero = norms <= rtol * norms.max()
    scale = np.where(zero, 1.0, norms)
    Rn = R / scale  # a factor of the column-normalised A
    sv = scipy.linalg.svdvals(Rn)
    # The singular values show a clean gap; a QR diagonal may not. One on the cut's band is left out (dynid.margins).
    rank = int(sum(1 for v in sv if v > rtol * sv[0] and not borderline_log(float(v / sv[0]), rtol)))
    independent = pivot_columns(Rn, rank)
    dependent = np.setdiff1d(np.arange(p), independent)
    Ks = np.linalg.lstsq(Rn[:, independent], Rn[:, dependent], rcond=None)[0] if dependent.size else np.zeros((rank, 0))
    K = Ks * scale[dependent][None, :] / scale[independent][:, None]
    K[np.abs(K) < 1e-12 * max(1.0, float(np.abs(K).max(initial=0.0)))] = 0.0  # round-off, not structure
    return BaseParameters(
        names=tuple(names),
        rank=rank,
        independent=independent,
        dependent=dependent,
        K=K,
        singular_values=sv,
        unidentifiable=tuple(names[i] for i in np.flatnonzero(zero)),
        rtol=rtol,
    )


TIE_RTOL = 1e-6  # residual norms within this share of the largest are a tie, broken by the parameters' order


def pivot_columns(X: np.ndarray, rank: int) -> np.ndarray:
    """The `rank` columns of X that column-pivoted QR picks (Gautier's numerical base parameters: at each step the
    column with the largest residual after projecting out those already picked), sorted, with ties broken by
    column order. A tie is common (two links' Izz that only ever appear summed, twice the same column) and LAPACK's
    pivoting breaks it by the last bits of the norms, which differ from CPU to CPU: the base parameters' names, and
    which combinations are determined, would differ with them. Gram–Schmidt, projected twice for orthogonality."""
    X = np.array(X, dtype=float)
    picked: list[int] = []
    for _ in range(rank):
        norms = np.einsum("ij,ij->j", X, X)
        norms[picked] = -1.0
        j = int(np.flatnonzero(norms >= (1 - TIE_RTOL) * norms.max())[0])
        picked.append(j)
        q = X[:, j] / np.sqrt(norms[j])
        for _ in range(2):
            X -= np.outer(q, q @ X)
        X[:, j] = 0.0
    return np.sort(np.array(picked, dtype=int))


def base_parameters(system: StackedSystem, rtol: float = DEFAULT_RTOL) -> BaseParameters:
    """Numerical rank and base-parameter structure of a stacked system (rows weighted by their noise)."""
    Aw, bw = system.weighted()
    return base_parameters_from_factor(triangular_factor([(Aw, bw)], Aw.shape[1]), system.parameter_names, rtol)


def data_base_parameters(
    model: RobotModel, sig: Signals, rtol: float = DEFAULT_RTOL, min_speed: float | None = DEFAULT_MIN_SPEED
) -> BaseParameters:
    """The structure that a recorded experiment actually excites, with bounded memory.

    Rows at rest (`dynid.robot.regressors.stack.rows_at_rest`) are left out, as the fit leaves them out: samples where
    a joint stands still would otherwise seem to separate Coulomb levels that only static friction sets.
    """
    weights = row_weights(model, sig, min_speed).ravel()

    def weighted_chunks() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        start = 0
        for A, b in iter_stacked(model, sig, DEFAULT_CHUNK):
            ww = weights[start : start + A.shape[0]]
            start += A.shape[0]
            yield A * ww[:, None], b * ww

    R = triangular_factor(weighted_chunks(), len(model.layout))
    return base_parameters_from_factor(R, model.layout.names, rtol)


def exciting_signals(model: RobotModel, n_samples: int = 2000, seed: int = 0) -> Signals:
    """Random states within the joint limits and random inputs: the structural (best-case) excitation."""
    rng = np.random.default_rng(seed)
    cfg = model.config
    lo = np.array([model.joint_limits[j][0] for j in cfg.joints])
    hi = np.array([model.joint_limits[j][1] for j in cfg.joints])
    finite = np.isfinite(lo) & np.isfinite(hi) & (hi - lo < 100)
    lo, hi = np.where(finite, lo, -np.pi), np.where(finite, hi, np.pi)
    n = cfg.joints.__len__()
    q = rng.uniform(lo, hi, (n_samples, n))
    dq = rng.normal(0.0, 1.0, (n_samples, n))
    ddq = rng.normal(0.0, 5.0, (n_samples, n))
    inputs = {m: rng.uniform(-0.5, 0.5, n_samples) for g in cfg.actuation if g.input != "torque" for m in g.motors}
    tau = {j: np.zeros(n_samples) for j in cfg.joints_with_input("torque")}
    ft = {s.name: np.zeros((n_samples, 6)) for s in cfg.ft_sensors}
    gravity = None
    if cfg.gravity_imu:  # a tilting base: gravity takes any direction, which can make more parameters identifiable
        g = rng.normal(size=(n_samples, 3))
        gravity = g / np.linalg.norm(g, axis=1, keepdims=True) * np.linalg.norm(cfg.gravity)
    return Signals(q, dq, ddq, inputs, tau, ft, None, gravity)


def structural_base_parameters(model: RobotModel, n_samples: int = 2000, seed: int = 0) -> BaseParameters:
    return base_parameters(build_stacked(model, exciting_signals(model, n_samples, seed)))
