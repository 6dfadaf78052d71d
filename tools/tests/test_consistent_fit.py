"""Physically consistent estimation (dynid.identify.consistent, docs/consistency.md).

- The SDP against independent references: with no constraint binding it is the unconstrained weighted least
  squares; with constraints binding it equals the same problem written directly on the stacked rows (not on the
  Gram), with the pseudo-inertia written out by hand, solved by another solver (SCS).
- Simulated arm, held-out seeds (short runs): the consistent fit's validation residual within 1 % of the
  unconstrained fit's, and every body physical.
- A short, poor run whose unconstrained fit is unphysical: the consistent fit is physical.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid

from dynid.config.robot_config import load_config
from dynid.identify.consistent import ConsistentProblem, ConsistentSettings
from dynid.identify.plausibility import implausible
from dynid.identify.validation import load_run
from dynid.robot.model import RobotModel
from dynid.robot.pseudo_inertia import is_physical

fitmod = importlib.import_module("dynid.identify.fit")


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    return RobotModel(load_config("icub_right_arm"))


def synthetic(arm: RobotModel, truth: np.ndarray, seed: int = 0, rows: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """A full-rank stacked system A Φ = b + noise, rows in noise units as the fit's are (columns of mixed scales)."""
    rng = np.random.default_rng(seed)
    p = len(arm.layout)
    # each column scaled inversely to its parameter's size, as a regressor's are (inertia columns are large)
    A = rng.standard_normal((rows, p)) * (rng.uniform(20, 200, p) / (np.abs(truth) + 1e-4))[None, :]
    return A, A @ truth + rng.standard_normal(rows)


def physical_truth(arm: RobotModel) -> np.ndarray:
    """CAD inertia, positive friction, nominal gains: strictly inside every constraint."""
    phi = fitmod.prior_parameters(arm)
    for kind in ("joint_friction", "motor_friction"):
        for b in arm.layout.blocks_of(kind):
            phi[b.slice] = [0.2, 0.2, 0.5, 0.5]
    return phi


def ols(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(A, b, rcond=None)[0]


def test_with_no_constraint_binding_it_is_the_unconstrained_least_squares(arm: RobotModel) -> None:
    truth = physical_truth(arm)
    A, b = synthetic(arm, truth)
    reference = ols(A, b)  # the independent answer: numpy's least squares on the stacked rows
    prior = fitmod.prior_parameters(arm)
    problem = ConsistentProblem(arm, prior, np.nan_to_num(arm.cad_parameters(), nan=0.0), A.T @ A)
    phi = problem.solve(A.T @ A, reference, 0.0)
    active = problem.active(phi)
    assert not any(active[k] for k in ("pseudo_inertia", "sphere", "friction", "gain")), active
    se = np.sqrt(np.diag(np.linalg.inv(A.T @ A)))  # each parameter's standard error (unit noise)
    assert np.max(np.abs(phi - reference) / se) < 1e-2  # the same estimate, to a hundredth of its error
    residual = lambda x: float(np.sum((A @ x - b) ** 2))  # noqa: E731
    assert residual(phi) <= residual(reference) * (1 + 1e-8)


def test_a_tool_beyond_the_sphere_stays_with_pseudo_inertia_only(arm: RobotModel) -> None:
    """A physical body whose mass sits beyond its sphere (a 0.4 kg ball of 10 cm radius 0.6 m out on the hand): the
    sphere binds and moves it; with `sphere` off (`--consistent pseudo-inertia`) nothing binds and the estimate is the
    least squares."""
    truth = physical_truth(arm)
    body = len(arm.bodies) - 1
    s = arm.layout.span("inertial").start + 10 * body
    m, c, r = 0.4, np.array([0.6, 0.0, 0.0]), 0.1
    inertia = m * (0.4 * r**2 * np.eye(3) + c @ c * np.eye(3) - np.outer(c, c))  # a solid ball, about the body's frame
    truth[s:s + 10] += [m, *(m * c), inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2],
                        inertia[2, 2]]  # INERTIAL_FIELDS' order
    A, b = synthetic(arm, truth, seed=2)
    reference = ols(A, b)
    cad = np.nan_to_num(arm.cad_parameters(), nan=0.0)
    residual = lambda x: float(np.sum((A @ x - b) ** 2))  # noqa: E731
    found = {}
    for sphere in (True, False):
        # prior = truth: λ₀'s pull (on every direction here) costs nothing, as in the first test
        problem = ConsistentProblem(arm, truth, cad, A.T @ A, ConsistentSettings(sphere=sphere))
        phi = problem.solve(A.T @ A, reference, 0.0)
        found[sphere] = (problem.active(phi), residual(phi))
    assert found[True][0]["sphere"] == [arm.bodies[body].name], found[True][0]
    assert found[True][1] > residual(reference) + 100  # the sphere costs the fit far more than the noise
    assert not any(found[False][0][k] for k in ("pseudo_inertia", "sphere", "friction", "gain")), found[False][0]
    assert found[False][1] <= residual(reference) * (1 + 1e-8)


def hand_written_pseudo_inertia(phi: object, cp: object) -> object:
    """J = [[½ tr(I)·1 − I, h], [hᵀ, m]] written out entry by entry (not through robot/pseudo_inertia.py's basis)."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = (phi[k] for k in range(10))
    half = 0.5 * (ixx + iyy + izz)
    rows = [[half - ixx, -ixy, -ixz, hx], [-ixy, half - iyy, -iyz, hy], [-ixz, -iyz, half - izz, hz], [hx, hy, hz, m]]
    if cp is np:
        return np.array(rows, float)
    return cp.bmat([[cp.reshape(e, (1, 1), order="F") for e in row] for row in rows])


def test_with_constraints_binding_it_is_the_problem_on_the_stacked_rows_solved_by_scs(arm: RobotModel) -> None:
    """b from an unphysical Φ (negative masses, negative friction): the SDP on the Gram, by Clarabel, equals the SDP
    on the rows themselves with the pseudo-inertia written by hand, by SCS."""
    import cvxpy as cp

    truth = physical_truth(arm)
    inertial = arm.layout.span("inertial")
    bad = truth.copy()
    bad[inertial.start + 30] = -0.8  # a body of negative mass
    bad[inertial.start + 54:inertial.start + 60] *= -1  # an inertia turned inside out
    fr = arm.layout.blocks_of("joint_friction")[0]
    bad[fr.start + 2] = -0.3  # negative viscous friction
    A, b = synthetic(arm, bad, seed=1, rows=1500)
    target = ols(A, b)
    prior = fitmod.prior_parameters(arm)
    cad = np.nan_to_num(arm.cad_parameters(), nan=0.0)
    settings = ConsistentSettings()
    problem = ConsistentProblem(arm, prior, cad, A.T @ A, settings)
    phi = problem.solve(A.T @ A, target, 0.0)
    active = problem.active(phi)
    assert active["pseudo_inertia"] and f"{fr.owner}.fv_pos" in active["friction"], active
    for k in range(len(arm.bodies)):
        assert is_physical(phi[inertial.start + 10 * k: inertial.start + 10 * k + 10]), arm.bodies[k].name

    # The reference: minimise ‖AΦ − b‖² itself (same tiny pull to the prior), the same constraints written anew.
    p = len(arm.layout)
    x = cp.Variable(p)
    sigma = problem.sigma
    scale = np.sqrt(problem.c)
    objective = cp.sum_squares(A @ x - b) / scale**2 + 1e-9 * cp.sum_squares(cp.multiply(1 / sigma, x - prior))
    cons = []
    for k, s in enumerate(problem.bodies.starts):
        T = np.diag(problem.bodies.scale[k])
        J = hand_written_pseudo_inertia(x[s:s + 10], cp)
        J_cad = hand_written_pseudo_inertia(cad[s:s + 10], np) if cad[s] > 0 else np.zeros((4, 4))
        cons.append(T @ (J - settings.epsilon * np.asarray(J_cad, float)) @ T >> 0)
        R = problem.bodies.radius[k]
        cons.append(x[s] - 0.5 * (x[s + 4] + x[s + 6] + x[s + 9]) / R**2 >= settings.epsilon * cad[s])
    cons += [x[i] >= 0 for i in problem.friction]
    cons += [x[i] >= settings.gain_floor * prior[i] for i in problem.gains]
    cp.Problem(cp.Minimize(objective), cons).solve(solver="SCS", eps=1e-9, max_iters=200_000)
    reference = x.value
    residual = lambda v: float(np.sum((A @ v - b) ** 2))  # noqa: E731
    # the same optimum: the residuals agree to SCS's accuracy, and so do the parameters the data determine
    assert abs(residual(phi) - residual(reference)) <= 1e-4 * residual(reference)
    assert residual(phi) >= residual(target)  # constraints cost fit on the identification data, never gain it
    assert np.linalg.norm(A @ (phi - reference)) <= 1e-2 * np.linalg.norm(A @ (target - phi))


# ---------------------------------------------------------------------------------------------------------------
# Simulated arm: held-out seeds, short runs

SEEDS = (11, 12)
SIM_S = 60


@pytest.fixture(scope="module")
def short_runs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    root = tmp_path_factory.mktemp("consistent")
    runs = []
    for seed in SEEDS:
        out = root / f"seed{seed}"
        done = dynid("simulate", "--kind", "identification", "--duration", str(SIM_S), "--seed", str(seed),
                     "--out", str(out))
        assert done.returncode == 0, done.stderr
        runs.append(out)
    return runs


def validation_residual(model: Path, validation: Path) -> tuple[float, dict]:
    """The weighted validation residual: the mean over output channels of (RMS of e / the channel's noise)²."""
    done = dynid("validate", "--model", str(model), "--data", str(validation), "--json", "-")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    ratios = [c["ratio_to_noise"] for c in result["channels"].values()]
    return float(np.mean(np.square(ratios))), result


def test_simulated_held_out_seeds_lose_nothing_and_stay_physical(short_runs: list[Path], default_experiments,
                                                                 tmp_path: Path) -> None:
    validation = default_experiments["validation"]
    for run in short_runs:
        residual = {}
        for mode in ("off", "on"):
            out = tmp_path / f"{run.name}-{mode}.json"
            done = dynid("fit", "--data", str(run), "--consistent", mode, "--out", str(out))
            assert done.returncode == 0, done.stderr
            residual[mode], _ = validation_residual(out, validation)
            if mode == "on":
                record = json.loads(out.read_text())
                assert record["consistent"]["status"] == "solved"
                assert record["plausibility"] == [], record["plausibility"]
                model = RobotModel(load_config("icub_right_arm"))
                phi = np.array([record["parameters"][n] for n in model.layout.names])
                inertial = model.layout.span("inertial").start
                for k, body in enumerate(model.bodies):
                    assert is_physical(phi[inertial + 10 * k: inertial + 10 * k + 10]), (run.name, body.name)
                print(f"{run.name}: λ = {record['consistent']['lambda']}, active {record['consistent']['active']}")
        print(f"{run.name}: validation residual off {residual['off']:.4f}, on {residual['on']:.4f} "
              f"({100 * (residual['on'] / residual['off'] - 1):+.2f} %)")
        assert residual["on"] <= 1.01 * residual["off"], (run.name, residual)


def test_a_poor_run_is_unphysical_unconstrained_and_physical_consistent(default_experiments) -> None:
    """8 s of the default run: the unconstrained fit has implausible bodies, the consistent one none. OLS: on so short
    a run two of IV's ten jackknife folds do not settle, and IV then determines nothing (test_decision_margins)."""
    model = RobotModel(load_config("icub_right_arm"))
    ds = load_run(str(default_experiments["identification"]), model, (0.0, 8.0))
    off = fitmod.fit(model, [ds], fitmod.FitSettings(estimator="ols", consistent=False, workers=1))
    assert implausible(model, off.phi), "the short run is not poor enough to show anything"
    on = fitmod.fit_statistics(model, off.statistics, fitmod.FitSettings(estimator="ols", consistent=True), off.samples)
    assert on.chosen == "consistent" and on.consistent["status"] == "solved"
    assert implausible(model, on.phi) == []
    # physical at little cost to the fit: the channels' residual variance on the identification data, relative to
    # the unconstrained fit's, is no larger on average (measured: F/T channels −3…+16 %, the PWMs −99…+4 %)
    ratio = on.residual_variance["consistent"] / off.residual_variance["ols"]
    print("residual variance, consistent / unconstrained:", np.round(ratio, 3))
    assert np.mean(ratio) <= 1.0, ratio


def test_a_solver_failure_is_one_line_and_the_fit_keeps_the_unconstrained_estimate(arm: RobotModel, monkeypatch) -> None:
    import cvxpy as cp

    from dynid.errors import DataError

    truth = physical_truth(arm)
    A, b = synthetic(arm, truth, rows=500)
    prior = fitmod.prior_parameters(arm)
    problem = ConsistentProblem(arm, prior, np.nan_to_num(arm.cad_parameters(), nan=0.0), A.T @ A)

    def broken(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise cp.error.SolverError("Solver 'X' failed. Try another solver")

    monkeypatch.setattr(problem.problem, "solve", broken)
    with pytest.raises(DataError) as e:
        problem.solve(A.T @ A, ols(A, b), 0.0)
    assert "\n" not in str(e.value) and "--consistent off" in str(e.value)

    def failing(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise DataError("the physically consistent fit failed (SCS: infeasible); rerun with --consistent off")

    monkeypatch.setattr(fitmod, "consistent_fit", failing)
    from types import SimpleNamespace

    p = len(arm.layout)
    stats = SimpleNamespace(p=p, gram=np.zeros((2, 1, p + 1, p + 1)))
    base = SimpleNamespace(dependent=np.zeros(0, int), independent=np.arange(p), K=np.zeros((p, 0)))
    estimate = fitmod.Estimate("iv", np.zeros(p), np.zeros(p), truth, {})
    record, consistent = fitmod._consistent(arm, stats, base, estimate, np.zeros((0, p)), prior)
    assert consistent is None and record["status"] == "failed" and record["from"] == "iv"
