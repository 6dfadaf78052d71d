"""The pseudo-inertia of a body: its 10 inertial parameters as one 4×4 matrix that is positive semidefinite exactly
when some mass distribution has them (Wensing, Kim and Slotine, "Linear Matrix Inequalities for Physically
Consistent Inertial Parameter Identification", RA-L 2018).

With φ = [m, h = m·c, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (Pinocchio's ``toDynamicParameters()`` order, inertia about the
body frame's origin):

    J(φ) = [[Σ, h], [hᵀ, m]],   Σ = ½ tr(I)·1 − I   (the second moment ∫ x xᵀ dm)

J is linear in φ, so it is written once as a basis, J(φ) = Σ_k φ_k E_k, which serves numpy (`pseudo_inertia`) and
a convex solver alike (the solver's expression is ``sum(phi[k] * E[k])``).
"""

from __future__ import annotations

import numpy as np


def _basis() -> np.ndarray:
    e = np.zeros((10, 4, 4))
    e[0, 3, 3] = 1.0                                   # m
    for axis in range(3):                              # h = m·c
        e[1 + axis, axis, 3] = e[1 + axis, 3, axis] = 1.0
    # I = [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]; Σ = ½ tr(I)·1 − I
    diagonal = {4: 0, 6: 1, 9: 2}                      # Ixx, Iyy, Izz
    for k, axis in diagonal.items():
        e[k, :3, :3] += 0.5 * np.eye(3)
        e[k, axis, axis] -= 1.0
    for k, (a, b) in {5: (0, 1), 7: (0, 2), 8: (1, 2)}.items():  # Ixy, Ixz, Iyz
        e[k, a, b] = e[k, b, a] = -1.0
    e.flags.writeable = False
    return e


PSEUDO_INERTIA_BASIS: np.ndarray = _basis()
"""(10, 4, 4): J(φ) = Σ_k φ_k · PSEUDO_INERTIA_BASIS[k]."""


def pseudo_inertia(phi_body: np.ndarray) -> np.ndarray:
    """The 4×4 pseudo-inertia of one body's 10 parameters."""
    phi = np.asarray(phi_body, float).reshape(10)
    return np.tensordot(phi, PSEUDO_INERTIA_BASIS, axes=1)


def parameters_of(j: np.ndarray) -> np.ndarray:
    """The 10 parameters of a pseudo-inertia (the inverse of `pseudo_inertia`)."""
    j = np.asarray(j, float)
    sigma = j[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma      # I = tr(Σ)·1 − Σ
    return np.array([j[3, 3], j[0, 3], j[1, 3], j[2, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1],
                     inertia[0, 2], inertia[1, 2], inertia[2, 2]])


def is_physical(phi_body: np.ndarray, tol: float = 0.0) -> bool:
    """Whether some mass distribution has these parameters: J(φ) ⪰ −tol·1 and m > 0."""
    phi = np.asarray(phi_body, float)
    return bool(phi[0] > 0 and np.linalg.eigvalsh(pseudo_inertia(phi))[0] >= -tol)
