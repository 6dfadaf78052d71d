"""The gap workflow's selection statistics (dynid.gaps.selection) against independent references: least squares on
the stacked rows, the batched cross products against one candidate's, the robust test's level on autocorrelated
residuals; the control runs of other arms, and the Stribeck shape. (test_gaps.py runs `dynid gaps` end to end.)"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

pytestmark = pytest.mark.numerics


def test_batched_cross_products_are_each_candidates_own() -> None:
    """`Design.cross_many` (a round's candidates against one read of the design) gives each candidate the statistics
    `cross` computes for it alone: candidates on one channel, on several, on every one, of different widths."""
    from dynid.gaps.selection import Design, batched
    from dynid.robot.effect_library import Candidate

    rng = np.random.default_rng(7)
    n, r, d = 900, 5, 6
    D, y = rng.normal(size=(n, r, d)), rng.normal(size=(n, r))
    bounds = np.linspace(0, n, 4).astype(int)
    Es = []
    for channels, k in (([1], 2), ([0, 3], 1), (list(range(r)), 3), ([4], 1)):
        E = np.zeros((n, r, k))
        E[:, channels] = rng.normal(size=(n, len(channels), k))
        Es.append(E)
    alone = [Design(D, y, bounds).cross(E) for E in Es]
    design = Design(D, y, bounds)
    design.cross_many(Es)
    for E, own in zip(Es, alone):
        for got, want in zip(design.cross(E), own):
            assert np.allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    design.forget()
    assert not design._batch
    # `batched` hands each candidate its own weighted columns, crossed in batches
    weights = np.abs(rng.normal(size=(n, r)))
    cands = [Candidate("test", f"candidate {i}", {}, E, tuple(f"c{k}" for k in range(E.shape[2])), lambda th, phi: {})
             for i, E in enumerate(Es)]
    seen = [(c, E) for c, E in batched(design, cands, weights)]
    assert [c for c, _ in seen] == cands
    assert all(np.array_equal(E, c.values * weights[:, :, None]) for c, E in seen)


def test_candidate_solve_matches_least_squares() -> None:
    """The Schur-complement solve of a candidate against the cached design equals a plain least-squares fit of
    the augmented design (numpy's lstsq), in held-out and in-sample error; a candidate inside the design's span
    changes nothing."""
    from dynid.gaps.selection import Design

    rng = np.random.default_rng(3)
    n, r, d = 400, 2, 5
    D = rng.normal(size=(n, r, d))
    E = rng.normal(size=(n, r, 2))
    y = D @ rng.normal(size=d) + E @ np.array([0.5, -0.2]) + 0.01 * rng.normal(size=(n, r))
    design = Design(D, y, np.linspace(0, n, 5).astype(int))
    cv = design.cv_sse(E)
    X = np.concatenate([D, E], axis=2)
    for b in range(4):
        train = np.r_[0 : 100 * b, 100 * (b + 1) : n]
        x = np.linalg.lstsq(X[train].reshape(-1, d + 2), y[train].reshape(-1), rcond=None)[0]
        e = y[100 * b : 100 * (b + 1)] - X[100 * b : 100 * (b + 1)] @ x
        assert np.allclose(cv[b], (e**2).sum(axis=0), rtol=1e-8)
    inside = D[:, :, :1] * 2.0 - D[:, :, 2:3]
    assert np.allclose(design.cv_sse(inside), design.cv_sse(None), rtol=1e-8)


def test_tiny_candidate_is_kept_by_selection_and_refit_alike() -> None:
    """A candidate whose columns are 1e-7 of the design's (a narrow Stribeck curve, alive only near q̇ = 0) is
    judged by the bordered solve and then refitted as part of a new Design: both must keep it, with the same
    coefficient and SSE as numpy's lstsq (before the column scaling, the refit's eigenvalue cut dropped it and the
    "after" column showed no change)."""
    from dynid.gaps.selection import Design

    rng = np.random.default_rng(5)
    n, r, d = 600, 2, 4
    D = rng.normal(size=(n, r, d)) * np.array([1e3, 1.0, 30.0, 1e2])
    E = np.zeros((n, r, 1))
    E[::7, 0, 0] = 1e-4 * rng.normal(size=E[::7].shape[0])  # sparse and tiny
    y = D @ rng.normal(size=d) + E[:, :, 0] * 2e4 + 0.01 * rng.normal(size=(n, r))
    bounds = np.linspace(0, n, 4).astype(int)
    design = Design(D, y, bounds)
    x_sel, sse_sel = design.fit(E)
    X = np.concatenate([D, E], axis=2)
    ref = np.linalg.lstsq(X.reshape(-1, d + 1), y.reshape(-1), rcond=None)[0]
    assert np.isclose(x_sel[-1], ref[-1], rtol=1e-6), (x_sel[-1], ref[-1])
    augmented = Design(X, y, bounds)
    x_ref, sse_ref = augmented.fit(None)
    assert np.allclose(x_ref, ref, rtol=1e-6), (x_ref, ref)
    # Both SSEs come from the normal equations, (Gx)·x − 2g·x + y·y: the cancellation leaves an absolute rounding
    # error of a few eps times y·y (1e9 here, against an SSE near 0.06), whatever the CPU's kernels.
    rounding = 64 * np.finfo(float).eps * float((y**2).sum())
    assert np.allclose(sse_ref, sse_sel, rtol=0, atol=rounding), (sse_ref - sse_sel, rounding)
    assert np.allclose(augmented.cv_sse(None), design.cv_sse(E), rtol=0, atol=rounding)
    assert sse_ref.sum() < 0.5 * design.fit(None)[1].sum()  # the column matters: it was not a no-op


def _ar1(rng: np.random.Generator, n: int, rho: float) -> np.ndarray:
    e = rng.normal(size=n) * np.sqrt(1 - rho**2)
    x = np.zeros(n)
    for i in range(1, n):
        x[i] = rho * x[i - 1] + e[i]
    return x


def test_robust_test_keeps_its_level_on_autocorrelated_residuals() -> None:
    """An unrelated smooth column against an autocorrelated residual (AR(1), ρ 0.95, as the shoulder's PWM
    residual): the rows-independent F-test rejects at 5 % in most runs; the batch-means Wald test near its level,
    and it still finds a real effect of that column."""
    from dynid.gaps.selection import Design, robust_p_value

    rng = np.random.default_rng(11)
    n, reps = 3000, 100
    robust, naive, power = [], [], []
    for _ in range(reps):
        D = np.stack([np.ones(n), _ar1(rng, n, 0.99), rng.normal(size=n)], axis=1)[:, None, :]
        cand = _ar1(rng, n, 0.98)[:, None, None]
        y = (D[:, 0] @ np.array([0.5, 1.0, -0.3]) + _ar1(rng, n, 0.95))[:, None]
        bounds = np.linspace(0, n, 6).astype(int)
        robust.append(robust_p_value(Design(D, y, bounds), cand, 100))
        X = np.concatenate([D, cand], axis=2)[:, 0]
        r0 = y[:, 0] - D[:, 0] @ np.linalg.lstsq(D[:, 0], y[:, 0], rcond=None)[0]
        r1 = y[:, 0] - X @ np.linalg.lstsq(X, y[:, 0], rcond=None)[0]
        naive.append(sps.f.sf((r0 @ r0 - r1 @ r1) / (r1 @ r1 / (n - 4)), 1, n - 4))
        power.append(robust_p_value(Design(D, y + 0.5 * cand[:, :, 0], bounds), cand, 100))
    print(f"rejections at 5 %: robust {np.mean(np.array(robust) < 0.05):.2f}, F-test {np.mean(np.array(naive) < 0.05):.2f}; "
          f"power at 1e-3 {np.mean(np.array(power) < 1e-3):.2f}")
    assert np.mean(np.array(robust) < 0.05) <= 0.15
    assert np.mean(np.array(naive) < 0.05) >= 0.4  # the failure the robust test exists for
    assert np.mean(np.array(power) < 1e-3) >= 0.8


CONTROL_SEEDS = (1, 2, 3, 4, 5)  # seeds 1 and 2 named a shoulder effect under the rows-independent F-test


def test_control_runs_of_other_arms_name_nothing() -> None:
    """30 s control runs, experiment and arm seeds 1–5 (no hidden effect): nothing named, though the shoulder's
    residual (supply variation, stiction) gives some candidate ≥ 20 % held-out gain on at least one of them, which
    the robust test then rejects."""
    from dynid.config.robot_config import load_config
    from dynid.gaps.workflow import MIN_GAIN, run
    from dynid.robot.model import RobotModel
    from dynid.simulation import SimulationSettings, simulate

    config = load_config("icub_right_arm")
    model = RobotModel(config)
    rejected = []
    for seed in CONTROL_SEEDS:
        sim = simulate(config, SimulationSettings(duration=30.0, seed=seed, robot_seed=seed))
        result = run(model, sim.dataset, log=lambda *a: None)
        assert result["effects"] == [], (seed, result["effects"])
        if result["not_significant"] is not None:
            assert result["not_significant"]["cv_gain"] >= MIN_GAIN
            rejected.append((seed, result["not_significant"]["effect"], result["not_significant"]["p_value"]))
    print("rejected by the robust test:", rejected)
    assert rejected


def test_stribeck_shape_and_joint_shares_against_independent_references() -> None:
    """The one Stribeck curve (fit, augmented model, monitor) against its formula's values, and the one joint →
    row share map against the regressor stack: a joint's Coulomb column in A is its share times the regressor."""
    from dynid.config.robot_config import load_config
    from dynid.robot.model import RobotModel
    from dynid.robot.regressors.friction import friction_regressor, stribeck_shape
    from dynid.robot.regressors.stack import Signals, fill_rows, joint_row_shares, row_channels

    v = np.array([-0.08, -0.04, 0.0, 0.02, 0.04])
    assert np.allclose(stribeck_shape(v, 0.04), [-np.exp(-4.0), -np.exp(-1.0), 0.0, np.exp(-0.25), np.exp(-1.0)])
    model = RobotModel(load_config("icub_right_arm"))
    n, nj = 3, len(model.config.joints)
    rng = np.random.default_rng(2)
    q, dq = rng.uniform(-0.3, 0.3, (n, nj)), rng.uniform(0.1, 0.5, (n, nj))
    motors = [m for g in model.config.actuation for m in g.motors]
    sig = Signals(q, dq, np.zeros((n, nj)), {m: np.full(n, 0.1) for m in motors},
                  {j: np.zeros(n) for j in model.config.joints}, {s.name: np.zeros((n, 6)) for s in model.config.ft_sensors})
    A, b = np.zeros((n, len(row_channels(model)), len(model.layout))), np.zeros((n, len(row_channels(model))))
    fill_rows(model, sig, A, b)
    shares = joint_row_shares(model)
    assert sorted(shares) == sorted(j for g in model.config.actuation for j in g.joints)  # the rows' joints
    for j, (c, share) in shares.items():
        col = model.layout.block("joint_friction", j).start
        assert np.allclose(A[:, :, col], friction_regressor(dq[:, c])[:, 0, None] * share[None, :]), j
