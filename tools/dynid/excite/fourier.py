"""Finite Fourier series joint trajectories (Swevers, Ganseman, Tükel, De Schutter, Van Brussel, 1997).

Joint j follows, with ω = 2π f the base (angular) frequency and L harmonics,

    q_j(t) = q0_j + Σ_l  a_jl/(ω l) · sin(ω l t) − b_jl/(ω l) · cos(ω l t)
    q̇_j(t) =        Σ_l  a_jl · cos(ω l t) + b_jl · sin(ω l t)
    q̈_j(t) =        Σ_l  ω l (−a_jl · sin(ω l t) + b_jl · cos(ω l t))

so q, q̇, q̈ are exact, band-limited to L·f, and periodic with period 1/f. **At rest at both ends**: the
coefficients satisfy Σ_l a_jl = 0 (q̇(0) = 0) and Σ_l l·b_jl = 0 (q̈(0) = 0), and the duration is a whole number
of periods, so the end is the start again, at rest. The two constraints are built into the parametrisation (the
coefficients live in their null space, `rest_basis`), so every vector of free coefficients starts and ends at
rest, and the optimiser never has to hold them. Everything is linear in (q0, a, b): limits on a time grid are
linear inequalities, and shrinking a joint's (a, b) shrinks its motion about q0 without moving q0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def rest_basis(harmonics: int) -> np.ndarray:
    """(2L, 2L − 2): an orthonormal basis of the (a, b) of one joint with Σ a_l = 0 and Σ l b_l = 0."""
    L = harmonics
    constraints = np.zeros((2, 2 * L))
    constraints[0, :L] = 1.0
    constraints[1, L:] = np.arange(1, L + 1)
    _, _, vt = np.linalg.svd(constraints)
    return vt[2:].T


@dataclass(frozen=True)
class FourierTrajectory:
    """q0 (J,), a and b (J, L), base frequency (Hz) and duration (s, a whole number of periods)."""

    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    base_frequency: float
    duration: float

    @property
    def omega(self) -> float:
        return 2 * np.pi * self.base_frequency

    @property
    def harmonics(self) -> int:
        return self.a.shape[1]

    @property
    def period(self) -> float:
        return 1.0 / self.base_frequency

    def basis(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """(sin(ωlt), cos(ωlt), ωl) on the grid t: (N, L), (N, L), (L,)."""
        wl = self.omega * np.arange(1, self.harmonics + 1)
        phase = np.outer(np.asarray(t, float), wl)
        return np.sin(phase), np.cos(phase), wl

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, q̇, q̈ (N, J) at the times t."""
        s, c, wl = self.basis(t)
        q = self.q0 + (s / wl) @ self.a.T - (c / wl) @ self.b.T
        dq = c @ self.a.T + s @ self.b.T
        ddq = (-s * wl) @ self.a.T + (c * wl) @ self.b.T
        return q, dq, ddq

    def scaled(self, factors: np.ndarray) -> FourierTrajectory:
        """Each joint's motion about q0 scaled by its factor (J,): rest at the ends is kept."""
        f = np.asarray(factors, float)[:, None]
        return FourierTrajectory(self.q0.copy(), self.a * f, self.b * f, self.base_frequency, self.duration)

    def as_dict(self, joints: tuple[str, ...]) -> dict:
        return {
            "base_frequency_hz": self.base_frequency, "period_s": self.period, "harmonics": self.harmonics,
            "duration_s": self.duration, "periods": int(round(self.duration * self.base_frequency)),
            "joints": {j: {"q0": float(self.q0[i]), "a": self.a[i].tolist(), "b": self.b[i].tolist()}
                       for i, j in enumerate(joints)},
        }


class Parametrisation:
    """The free coefficients z = [q0 (J) | c (J × (2L − 2))] ↔ a trajectory at rest at both ends.

    (a_j, b_j) = N c_j with N = `rest_basis(L)`. Positions, velocities and accelerations on a grid are linear in z:
    `grid_maps` gives the (N·J, len(z)) matrices, from which the limits become linear inequalities.
    """

    def __init__(self, joints: int, harmonics: int, base_frequency: float, duration: float) -> None:
        self.J, self.L = joints, harmonics
        self.f, self.duration = base_frequency, duration
        self.N = rest_basis(harmonics)
        self.k = self.N.shape[1]

    @property
    def size(self) -> int:
        return self.J * (1 + self.k)

    def trajectory(self, z: np.ndarray) -> FourierTrajectory:
        z = np.asarray(z, float)
        q0 = z[: self.J]
        ab = z[self.J :].reshape(self.J, self.k) @ self.N.T  # (J, 2L)
        return FourierTrajectory(q0.copy(), ab[:, : self.L], ab[:, self.L :], self.f, self.duration)

    def vector(self, traj: FourierTrajectory) -> np.ndarray:
        c = np.hstack([traj.a, traj.b]) @ self.N  # N is orthonormal and (a, b) lies in its span
        return np.concatenate([traj.q0, c.ravel()])

    def grid_maps(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Matrices Mq, Mv, Ma (N·J, size) with q.ravel() = Mq z (sample-major, then joint), and so on."""
        probe = FourierTrajectory(np.zeros(self.J), np.zeros((self.J, self.L)), np.zeros((self.J, self.L)), self.f,
                                  self.duration)
        s, c, wl = probe.basis(t)
        n = len(t)
        per_q = np.hstack([s / wl, -c / wl]) @ self.N  # (n, k): one joint's q from its c
        per_v = np.hstack([c, s]) @ self.N
        per_a = np.hstack([-s * wl, c * wl]) @ self.N
        maps = []
        for per, offset in ((per_q, 1.0), (per_v, 0.0), (per_a, 0.0)):
            M = np.zeros((n, self.J, self.size))
            for j in range(self.J):
                M[:, j, j] = offset
                M[:, j, self.J + j * self.k : self.J + (j + 1) * self.k] = per
            maps.append(M.reshape(n * self.J, self.size))
        return maps[0], maps[1], maps[2]
