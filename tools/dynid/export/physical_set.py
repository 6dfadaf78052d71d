"""The physically consistent full inertial set nearest CAD that reproduces the identified base parameters.

An identification determines only the base parameters β = Φ_b + K Φ_d (dynid.robot.regressors.base); a URDF needs
all ten parameters of every link, and a simulator needs them physical. This module solves, per URDF link l of the
identified bodies (a body is one Pinocchio joint's rigid set of links: fixed joints and locked joints merge links):

    min  Σ_l ‖(φ_l − φ_l,CAD) / s_l‖²
    s.t. β(Σ_l A_l φ_l) = β̂                      (the base-parameter projection, equality)
         J(φ_l) ⪰ 0 for every variable link     (the pseudo-inertia: some mass distribution has φ_l)

with φ_l in the link's own frame, A_l the linear map to its body's frame (J ↦ T J Tᵀ, T the link's placement), and
s_l a per-parameter scale that makes masses, first moments and inertias weigh comparably: with m the link's CAD
mass and L = √(tr Σ_CAD / m) the RMS distance of its CAD mass from its frame's origin (at least 1 cm), the scales
are m for the mass, m·L for the first moments and m·L² for the inertias (a link without CAD mass borrows its
body's). Links without CAD mass stay massless, except the link that carries the body's frame, which is always
free.

The equality is built in, not left to the solver's tolerance: the full sets that satisfy it are written as
φ = φ₀ + S N z, with φ₀ the model file's own full set (carried by the body's frame link, the other links at CAD)
and N an orthonormal basis of the null space of the scaled constraint. So a model whose full Φ is physical keeps
reproducing its base parameters to round-off, whatever the solver does with z; the solver (cvxpy with Clarabel)
only moves along directions the data cannot see. A model whose own set is physical is never refused: on the
cone's boundary (a point mass, a flat body: no strict interior for an interior-point solver) the problem is solved
relaxed by RELAXED, and the set moves from the model's own towards that optimum only as far as every link stays at
least as physical as the model's own (a bisection on the step).

When no physical full set reproduces β̂ (the unconstrained fit may give such β̂), `nearest_physical_set` raises
`NotReproducible`, unless `allow_residual` is set: then it finds the physical set whose base parameters are
nearest β̂ (in units of their standard errors), and among those the one nearest CAD, and states the residual.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..robot.pseudo_inertia import PSEUDO_INERTIA_BASIS, parameters_of, pseudo_inertia

MIN_LENGTH = 0.01  # m: the smallest length scale of a link (a point mass at its frame's origin has none)
MARGIN = 1e-9  # scaled pseudo-inertias are kept ⪰ MARGIN·1, so every written link is strictly physical
PHYSICAL_TOL = 1e-7  # a scaled pseudo-inertia eigenvalue above −PHYSICAL_TOL counts as physical (solver round-off)
RELAXED = 1e-6  # the relaxation used when the model's own set sits on the cone's boundary
RESIDUAL_TIE = 1e-4  # with --nearest-physical: the weight of the distance to CAD beside the base residual


class NotReproducible(Exception):
    """No physical full set reproduces the identified base parameters."""


@dataclass(frozen=True)
class LinkPart:
    """One URDF link inside an identified body."""

    link: str
    body: int  # index of the body in the robot model's layout
    A: np.ndarray  # (10, 10): the body-frame parameters of this link's φ (in its own frame)
    cad: np.ndarray  # (10,) φ from the URDF's <inertial>, in the link frame
    carries_body_frame: bool  # the link whose frame is the body's (it takes the identified difference)

    @property
    def variable(self) -> bool:
        return self.carries_body_frame or self.cad[0] > 0


@dataclass
class PhysicalSet:
    links: dict[str, np.ndarray]  # link -> φ in its own frame (variable links only)
    distance: float  # ‖(φ − φ_CAD)/s‖ over the variable links
    base_residual: np.ndarray  # β(φ) − β̂ (round-off unless allow_residual)
    min_eigenvalue: float  # the smallest eigenvalue of the scaled pseudo-inertias
    solver: str
    status: str
    notes: list[str] = field(default_factory=list)


def transform_matrix(placement: np.ndarray) -> np.ndarray:
    """(10, 10): φ in a frame F ↦ φ in the frame where F sits at `placement` (4×4 homogeneous), via J' = T J Tᵀ."""
    T = np.asarray(placement, float)
    return np.column_stack([parameters_of(T @ PSEUDO_INERTIA_BASIS[k] @ T.T) for k in range(10)])


def _length(phi: np.ndarray) -> float | None:
    if phi[0] <= 0:
        return None
    sigma = pseudo_inertia(phi)[:3, :3]
    return max(float(np.sqrt(max(np.trace(sigma), 0.0) / phi[0])), MIN_LENGTH)


def scales(parts: list[LinkPart]) -> list[tuple[float, float]]:
    """(mass scale, length scale) per link, as the module docstring says."""
    body_mass: dict[int, float] = {}
    body_length: dict[int, float] = {}
    for p in parts:
        body_mass[p.body] = body_mass.get(p.body, 0.0) + max(float(p.cad[0]), 0.0)
        length = _length(p.cad)
        if length is not None:
            body_length[p.body] = max(body_length.get(p.body, 0.0), length)
    out = []
    for p in parts:
        m = float(p.cad[0]) if p.cad[0] > 0 else (body_mass[p.body] or 1.0)
        length = _length(p.cad) or body_length.get(p.body, 0.1)
        out.append((m, length))
    return out


def parameter_scale(mass: float, length: float) -> np.ndarray:
    return np.array([mass] + [mass * length] * 3 + [mass * length**2] * 6)


def nearest_physical_set(
    parts: list[LinkPart],
    body_phi: np.ndarray,
    base_map: np.ndarray,
    base_sigma: np.ndarray | None = None,
    allow_residual: bool = False,
    own: bool = False,
) -> PhysicalSet:
    """The nearest-CAD physical link set whose bodies reproduce `base_map @ body_phi`; with `own`, no search: the
    model's own bodies, each one's difference to CAD on the link that carries its frame (a consistent fit's set).

    body_phi: (10·n_bodies,) the model's full inertial set (it reproduces β̂); base_map: (rank, 10·n_bodies), the
    inertial columns of the base-parameter map (β̂ − its other columns' part = base_map @ body_phi); base_sigma: the
    base parameters' standard errors (for the residual's units when `allow_residual`).
    """
    import cvxpy as cp

    n_bodies = body_phi.size // 10
    var = [p for p in parts if p.variable]
    fixed = [p for p in parts if not p.variable]
    sc = [parameter_scale(*ms) for p, ms in zip(parts, scales(parts)) if p.variable]
    lengths = [ms[1] for p, ms in zip(parts, scales(parts)) if p.variable]
    masses = [ms[0] for p, ms in zip(parts, scales(parts)) if p.variable]

    # φ₀: the model's body sets, the difference to CAD on the link that carries the body's frame.
    phi0 = [p.cad.copy() for p in var]
    for k in range(n_bodies):
        carried = sum((p.A @ p.cad for p in parts if p.body == k), np.zeros(10))
        carrier = next((i for i, p in enumerate(var) if p.body == k and p.carries_body_frame), None)
        if carrier is None:
            raise ValueError(f"body {k} has no link carrying its frame")
        phi0[carrier] = phi0[carrier] + np.linalg.solve(var[carrier].A, body_phi[10 * k : 10 * k + 10] - carried)
    # The constraint on the scaled variables u (φ_l = φ₀_l + s_l ⊙ u_l): M u = 0 keeps β exactly.
    n = 10 * len(var)
    M = np.zeros((base_map.shape[0], n))
    for i, p in enumerate(var):
        M[:, 10 * i : 10 * i + 10] = base_map[:, 10 * p.body : 10 * p.body + 10] @ p.A @ np.diag(sc[i])
    d0 = np.concatenate([(phi0[i] - p.cad) / sc[i] for i, p in enumerate(var)])
    # Scaled pseudo-inertia basis per link: D J D with D = diag(1/L, 1/L, 1/L, 1)/√m, so its eigenvalues are O(1).
    bases = []
    for i in range(len(var)):
        D = np.diag([1 / lengths[i]] * 3 + [1.0]) / np.sqrt(masses[i])
        bases.append(np.einsum("ab,kbc,cd->kad", D, PSEUDO_INERTIA_BASIS, D))

    def link_phi(u: np.ndarray, i: int) -> np.ndarray:
        return phi0[i] + sc[i] * u[10 * i : 10 * i + 10]

    def min_eig(u: np.ndarray) -> float:
        return min(float(np.linalg.eigvalsh(np.tensordot(link_phi(u, i), bases[i], axes=1))[0]) for i in range(len(var)))

    def psd(u_expr, margin: float) -> list:
        cons = []
        for i in range(len(var)):
            phi_i = phi0[i] + cp.multiply(sc[i], u_expr[10 * i : 10 * i + 10])
            J = sum(phi_i[k] * bases[i][k] for k in range(10))
            cons.append((J + J.T) / 2 >> margin * np.eye(4))
        return cons

    if own:
        u = np.zeros(n)
        links = {p.link: link_phi(u, i) for i, p in enumerate(var)}
        links.update({p.link: p.cad.copy() for p in fixed if p.link not in links})
        return PhysicalSet(links, float(np.linalg.norm(d0)), M @ u, min_eig(u), "none", "the model's own set")
    N = scipy.linalg.null_space(M, rcond=1e-12) if M.shape[0] else np.eye(n)
    z = cp.Variable(N.shape[1])
    notes: list[str] = []
    u = None
    status = "infeasible"
    for margin in (MARGIN, 0.0):
        problem = cp.Problem(cp.Minimize(cp.sum_squares(d0 + N @ z)), psd(N @ z, margin))
        status = _solve(problem)
        if status in ("optimal", "optimal_inaccurate") and z.value is not None:
            u = N @ z.value
            if min_eig(u) >= -PHYSICAL_TOL:
                break
            u = None
    if u is None and min_eig(np.zeros(n)) >= -PHYSICAL_TOL:
        # The model's own full set is physical but on the cone's boundary (a consistent fit's active constraint: a
        # point mass, a flat body), where an interior-point solver finds no strict interior. Solve slightly relaxed,
        # then step back from the model's own set towards that optimum only as far as every link stays physical.
        problem = cp.Problem(cp.Minimize(cp.sum_squares(d0 + N @ z)), psd(N @ z, -RELAXED))
        status = _solve(problem)
        target = N @ z.value if z.value is not None else np.zeros(n)
        floor = min(0.0, min_eig(np.zeros(n)))  # never less physical than the model's own set
        lo, hi = 0.0, 1.0
        if min_eig(target) < floor:
            for _ in range(60):
                mid = (lo + hi) / 2
                lo, hi = (mid, hi) if min_eig(mid * target) >= floor else (lo, mid)
        else:
            lo = 1.0
        u = lo * target
        status = f"{status} (relaxed by {RELAXED:g}, then {lo:.3g} of the way from the model's own set)"
    residual = np.zeros(base_map.shape[0])
    if u is None:
        if not allow_residual:
            raise NotReproducible(status)
        sigma = np.where(np.asarray(base_sigma) > 0, base_sigma, 1.0) if base_sigma is not None else np.ones(M.shape[0])
        W = M / sigma[:, None]
        v = cp.Variable(n)
        problem = cp.Problem(cp.Minimize(cp.sum_squares(W @ v) + RESIDUAL_TIE * cp.sum_squares(d0 + v)),
                             psd(v, MARGIN))
        status = _solve(problem)
        if v.value is None:
            raise NotReproducible(status)
        u = v.value
        residual = M @ u  # β(φ) − β̂ (M carries the scales: the base map of the change)
        notes.append("no physical full set reproduces the identified base parameters: this is the nearest one, "
                     f"base residual {np.sqrt(np.mean((residual / sigma) ** 2)):.3g} standard errors RMS")
    links = {p.link: link_phi(u, i) for i, p in enumerate(var)}
    for p in fixed:
        links.setdefault(p.link, p.cad.copy())
    distance = float(np.linalg.norm(d0 + u))
    if u is not None and not allow_residual:
        residual = M @ u
    return PhysicalSet(links, distance, residual, min_eig(u), "Clarabel", status, notes)


def _solve(problem) -> str:
    import cvxpy as cp

    try:
        with warnings.catch_warnings():  # an inaccurate solution is judged by its status and checked eigenvalues
            warnings.simplefilter("ignore")
            problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError:
        return "solver_error"
    return str(problem.status)
