"""The pseudo-inertia basis against Pinocchio's own, and against bodies built from point masses."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dynid.robot.pseudo_inertia import is_physical, parameters_of, pseudo_inertia


@pytest.mark.parametrize("seed", range(10))
def test_matches_pinocchio_pseudo_inertia(seed: int) -> None:
    pin.seed(seed)  # pin.Inertia.Random draws from Pinocchio's own generator
    inertia = pin.Inertia.Random()
    phi = inertia.toDynamicParameters()
    np.testing.assert_allclose(pseudo_inertia(phi), inertia.toPseudoInertia().toMatrix(), atol=1e-12)
    np.testing.assert_allclose(parameters_of(pseudo_inertia(phi)), phi, atol=1e-12)


def test_point_masses_are_physical_and_a_negative_mass_is_not() -> None:
    rng = np.random.default_rng(0)
    phi = np.zeros(10)
    for _ in range(5):  # a body of five point masses: J = Σ m [x;1][x;1]ᵀ, PSD by construction
        m, x = rng.uniform(0.1, 2.0), rng.normal(size=3) * 0.1
        phi += pin.Inertia(m, x, np.zeros((3, 3))).toDynamicParameters()
    j = pseudo_inertia(phi)
    assert is_physical(phi)
    assert np.linalg.eigvalsh(j)[0] >= -1e-12
    broken = phi.copy()
    broken[0] = -1.0
    assert not is_physical(broken)
    thin = phi.copy()
    thin[4] = phi[6] + phi[9] + 1.0  # Ixx > Iyy + Izz breaks the triangle inequality
    assert not is_physical(thin)
