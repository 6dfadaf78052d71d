"""Physically consistent estimation (issue 21): the fit's estimate, moved the least the data allow to a Φ whose every
body has a mass distribution, whose friction is dissipative and whose motor gains have the configured sign.

The problem is a semidefinite programme (Wensing, Kim and Slotine, RA-L 2018; Sousa and Cortesão, IJRR 2014),
solved by Clarabel through cvxpy (docs/consistency.md says why):

    minimise    ‖F (Φ − Φ̂)‖²  +  λ·c · Σ_inertial ((Φ_i − Φ_CAD,i) / σ_i)²  +  λ₀·c · ‖P_null ((Φ − Φ_prior) / σ)‖²
    subject to  J(φ_b) ⪰ ε · J(φ_b,CAD)                  every body b (the pseudo-inertia, robot/pseudo_inertia.py)
                m_b − tr Σ_b / R_b² ≥ ε · m_b,CAD         every body: density-realizable inside a sphere of radius R_b
                                                          (unless `sphere` is off: J ⪰ 0 alone, any mass distribution)
                fc±, fv± ≥ 0                              every joint and motor friction coefficient
                sign(g_nom) · g ≥ GAIN_FLOOR · |g_nom|    every unknown motor gain

- Φ̂ is the fit's own unconstrained estimate (IV by default: its instruments are kept), FᵀF = AᵀW²A the weighted
  Gram of the run (`statistics.Statistics`): the objective is the weighted residual's growth when Φ moves away from
  Φ̂. For least squares it *is* ‖W(AΦ − b)‖² up to a constant (the normal equations); for IV it is the minimum-
  distance projection of the IV estimate in the data's metric, which leaves the IV estimate unchanged when no
  constraint binds.
- The Gram sees only the base combinations: the directions the data cannot see (the full Φ's non-identifiable
  part) are free, and that is what the LMIs use first, at no cost to the fit. λ₀ (tiny, fixed) keeps them at the
  prior where no constraint needs them, so the solution is unique; it acts on those directions only (`null`), so
  the combinations the data determine are never pulled.
- λ pulls the inertial parameters towards CAD, and is chosen by cross-validation over the fit's time blocks
  (held-out weighted residual; λ = 0 is a candidate, and a λ > 0 must beat it by more than one standard error of
  the folds' paired differences: `choose_lambda`).
- σ_i are natural scales: per body m, m·ℓ, m·ℓ² (CAD mass, ℓ the link's extent); other parameters by their
  column of the Gram. c normalises the objective so that λ = 1 weighs a natural unit of each inertial parameter
  as much as the data do on average.
- R_b is the radius `plausibility.py` allows the centre of mass (1.5 × the link's extent + 5 cm): the three
  robots' URDFs describe their links by meshes only, so no box or cylinder exists to bound them tighter.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import DataError
from ..robot.model import RobotModel
from ..robot.parameters import FRICTION_FIELDS
from ..robot.pseudo_inertia import PSEUDO_INERTIA_BASIS, pseudo_inertia
from .plausibility import COM_MARGIN_FACTOR, COM_MARGIN_M, link_extent

LAMBDAS: tuple[float, ...] = (0.0, 1e-4, 1e-3, 1e-2, 1e-1)  # candidates for the pull towards CAD
LAMBDA_FLOOR = 1e-12  # λ₀: uniqueness in the directions the data do not see
EPSILON = 1e-3  # J ⪰ ε·J_CAD: strictly inside the cone, so rounding never shows a body on the wrong side
GAIN_FLOOR = 0.1  # a gain below a tenth of its nominal value is no motor's
CV_TIE = 1e-3  # a λ > 0 must also lower the held-out residual by this much (relative) to be chosen
ACTIVE_RTOL = 1e-6  # a constraint binds when its slack is below this, relative to its scale (the solver's ends near 1e-10)


@dataclass
class ConsistentSettings:
    lambdas: tuple[float, ...] = LAMBDAS
    epsilon: float = EPSILON
    gain_floor: float = GAIN_FLOOR
    solver: str = "CLARABEL"
    # the density-realizable sphere (off: J ⪰ 0 alone, for a body that carries mass beyond its reach, e.g. a tool)
    sphere: bool = True


@dataclass
class ConsistentResult:
    phi: np.ndarray
    lam: float
    active: dict
    cv: dict
    folds: list[np.ndarray] = field(default_factory=list)  # the fold solutions at the chosen λ (for the jackknife)
    solve_time_s: float = 0.0
    solver: str = ""
    solver_status: str = ""
    settings: ConsistentSettings = field(default_factory=ConsistentSettings)

    def record(self) -> dict:
        return {"lambda": self.lam, "active": self.active, "cv": self.cv, "solver": self.solver,
                "solver_status": self.solver_status, "solve_time_s": self.solve_time_s,
                "epsilon": self.settings.epsilon, "gain_floor": self.settings.gain_floor,
                "sphere": self.settings.sphere}


def _factor(gram: np.ndarray) -> np.ndarray:
    """F with FᵀF = G (as dynid.identify.fit's, which imports this module)."""
    d = np.sqrt(np.clip(np.diag(gram), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    lam, V = np.linalg.eigh(gram / np.outer(d, d))
    return (np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T) * d[None, :]


@dataclass
class _Bodies:
    """Per body: the Φ slice, its CAD pseudo-inertia, the congruence T that brings J to O(1), the sphere radius."""

    starts: list[int]
    names: list[str]
    j_cad: list[np.ndarray]
    scale: list[np.ndarray]  # diag of T
    mass: list[float]
    radius: list[float]
    length: list[float]


def _bodies(model: RobotModel, cad: np.ndarray) -> _Bodies:
    start = model.layout.span("inertial").start
    out = _Bodies([], [], [], [], [], [], [])
    for k, body in enumerate(model.bodies):
        s = start + 10 * k
        phi = cad[s:s + 10]
        reach = link_extent(model, k)
        extent = max(reach, 0.02)  # the scales' length (a link that reaches nowhere still has a size)
        m = max(float(phi[0]), 1e-3)
        out.starts.append(s)
        out.names.append(body.name)
        out.j_cad.append(pseudo_inertia(phi) if phi[0] > 0 else np.zeros((4, 4)))
        out.scale.append(np.array([1 / extent, 1 / extent, 1 / extent, 1.0]) / np.sqrt(m))
        out.mass.append(m)
        out.radius.append(COM_MARGIN_FACTOR * reach + COM_MARGIN_M)
        out.length.append(extent)
    return out


def natural_scales(model: RobotModel, gram: np.ndarray, bodies: _Bodies) -> np.ndarray:
    """σ_i: a natural size of each parameter (inertial: m, m·ℓ, m·ℓ²; others: 1/√G_ii relative to the inertial)."""
    p = gram.shape[0]
    sigma = np.ones(p)
    for s, m, ell in zip(bodies.starts, bodies.mass, bodies.length):
        sigma[s] = m
        sigma[s + 1:s + 4] = m * ell
        sigma[s + 4:s + 10] = m * ell**2
    inertial = np.zeros(p, bool)
    inertial[model.layout.span("inertial")] = True
    d = np.diag(gram)
    ref = np.mean(d[inertial] * sigma[inertial] ** 2) if inertial.any() else 1.0
    ref = ref if ref > 0 else 1.0
    for i in np.flatnonzero(~inertial):
        sigma[i] = np.sqrt(ref / d[i]) if d[i] > 0 else 1.0
    return sigma


class ConsistentProblem:
    """The SDP, built once (cvxpy parameters for the Gram factor, the target and λ) and solved per fold and λ."""

    def __init__(self, model: RobotModel, prior: np.ndarray, cad: np.ndarray, gram: np.ndarray,
                 settings: ConsistentSettings = ConsistentSettings(), null: np.ndarray | None = None) -> None:
        """`null` (p, k): a basis of the directions of Φ the data cannot see (the base parameters' [−K; 1] columns);
        λ₀ acts on those only, so the combinations the data determine are never pulled. None: on every direction."""
        import cvxpy as cp  # noqa: PLC0415 - only a consistent fit needs it

        self.cp = cp
        self.model, self.settings = model, settings
        self.prior, self.cad = prior, cad
        p = len(model.layout)
        self.p = p
        self.bodies = _bodies(model, cad)
        self.sigma = natural_scales(model, gram, self.bodies)
        S = self.sigma
        # c: the data's weight of one natural unit, averaged over the inertial parameters
        inertial = np.zeros(p, bool)
        inertial[model.layout.span("inertial")] = True
        self.inertial = inertial
        d = np.diag(gram)
        self.c = float(np.mean(d[inertial] * S[inertial] ** 2)) if inertial.any() else float(np.mean(d * S**2))
        self.c = self.c if self.c > 0 else 1.0
        # the Gram's factor times diag(σ): the objective stays in the rows' noise units (rows are weighted by 1/σ),
        # where a change below 1 is below the noise, and the solver's tolerances mean the same on every robot
        self.F = cp.Parameter((p, p))
        self.target = cp.Parameter(p)  # Φ̂ (the unconstrained estimate)
        # λ enters as √λ·(z + (Φ̂ − Φ_CAD)/σ) on the inertial entries, with √λ and √λ·(Φ̂ − Φ_CAD)/σ as parameters: a
        # product of two parameters would not be DPP, and every solve would compile the problem anew
        self.root_lam = cp.Parameter(nonneg=True)
        self.cad_offset = cp.Parameter(int(inertial.sum()))
        z = cp.Variable(p)  # Φ = Φ̂ + σ ⊙ z
        self.z = z
        phi = self.target + cp.multiply(S, z)
        to_cad = self.root_lam * z[inertial] + self.cad_offset
        to_prior = z + cp.multiply(1 / S, self.target - prior)
        if null is not None:  # the orthogonal projection on the unseen directions, in z's coordinates (σ-scaled)
            U = np.linalg.qr(null / S[:, None])[0] if null.shape[1] else np.zeros((p, 0))
            to_prior = U.T @ to_prior
        objective = (cp.sum_squares(self.F @ z) + cp.sum_squares(to_cad)
                     + LAMBDA_FLOOR * self.c * cp.sum_squares(to_prior))
        cons = []
        eps = settings.epsilon
        for b, s in enumerate(self.bodies.starts):
            T = self.bodies.scale[b]
            TT = np.outer(T, T)
            J = sum(phi[s + k] * (PSEUDO_INERTIA_BASIS[k] * TT) for k in range(10)) - eps * self.bodies.j_cad[b] * TT
            cons.append(0.5 * (J + J.T) >> 0)
            if not settings.sphere:
                continue
            R = self.bodies.radius[b]
            m_cad = self.bodies.mass[b]
            trace_sigma = 0.5 * (phi[s + 4] + phi[s + 6] + phi[s + 9])  # tr Σ = ½ tr I
            cons.append((phi[s] - trace_sigma / R**2 - eps * float(cad[s] > 0) * m_cad) / m_cad >= 0)
        layout = model.layout
        self.friction = [blk.start + i for kind in ("joint_friction", "motor_friction") for blk in layout.blocks_of(kind)
                         for i, f in enumerate(blk.names) if f.split(".")[-1] in FRICTION_FIELDS]
        if self.friction:
            idx = np.array(self.friction)
            cons.append(cp.multiply(1 / S[idx], phi[idx]) >= 0)
        self.gains = [blk.start for blk in layout.blocks_of("motor_gain")]
        if self.gains:
            idx = np.array(self.gains)
            nominal = prior[idx]
            sign = np.where(nominal < 0, -1.0, 1.0)
            cons.append(cp.multiply(sign / S[idx], phi[idx]) >= settings.gain_floor * np.abs(nominal) / S[idx])
        self.constraints = cons
        self.problem = cp.Problem(cp.Minimize(objective), cons)

    def solve(self, gram: np.ndarray, target: np.ndarray, lam: float) -> np.ndarray:
        """Φ for the Gram `gram` (AᵀW²A, p×p) and the unconstrained estimate `target`."""
        cp = self.cp
        self.F.value = _factor(gram) * self.sigma[None, :]
        self.target.value = target
        root = np.sqrt(lam * self.c)
        self.root_lam.value = root
        self.cad_offset.value = root * (target - self.cad)[self.inertial] / self.sigma[self.inertial]
        solvers = [self.settings.solver] + [s for s in ("CLARABEL", "SCS") if s != self.settings.solver]
        last = ""
        for solver in solvers:
            try:
                with warnings.catch_warnings():  # "may be inaccurate": the status says so, and the record keeps it
                    warnings.simplefilter("ignore")
                    self.problem.solve(solver=solver)
            except (cp.error.SolverError, cp.error.DCPError, ValueError, ArithmeticError) as e:
                last = f"{solver}: {str(e).splitlines()[0] if str(e) else e.__class__.__name__}"
                continue
            if self.problem.status in ("optimal", "optimal_inaccurate") and self.z.value is not None:
                self.solver, self.status = solver, self.problem.status
                return target + self.sigma * np.asarray(self.z.value)
            last = f"{solver}: {self.problem.status}"
        raise DataError(f"the physically consistent fit failed ({last}); rerun with --consistent off")

    def active(self, phi: np.ndarray) -> dict:
        """Which constraints bind at Φ: bodies whose pseudo-inertia (or sphere) is at its bound, friction and gains."""
        out: dict = {"pseudo_inertia": [], "sphere": [], "friction": [], "gain": [], "min_eigenvalue": {}}
        names = self.model.layout.names
        eps = self.settings.epsilon
        for b, s in enumerate(self.bodies.starts):
            T = self.bodies.scale[b]
            TT = np.outer(T, T)
            J = (pseudo_inertia(phi[s:s + 10]) - eps * self.bodies.j_cad[b]) * TT
            lo = float(np.linalg.eigvalsh(J)[0])
            name = self.bodies.names[b]
            out["min_eigenvalue"][name] = float(np.linalg.eigvalsh(pseudo_inertia(phi[s:s + 10]) * TT)[0])
            if lo < ACTIVE_RTOL * max(1.0, float(np.abs(J).max())):
                out["pseudo_inertia"].append(name)
            if not self.settings.sphere:
                continue
            R, m_cad = self.bodies.radius[b], self.bodies.mass[b]
            slack = (phi[s] - 0.5 * (phi[s + 4] + phi[s + 6] + phi[s + 9]) / R**2) / m_cad - eps * float(self.cad[s] > 0)
            if slack < ACTIVE_RTOL:
                out["sphere"].append(name)
        for i in self.friction:
            if phi[i] / self.sigma[i] < ACTIVE_RTOL:
                out["friction"].append(names[i])
        for i in self.gains:
            nominal = self.prior[i]
            if (np.sign(nominal or 1.0) * phi[i] - self.settings.gain_floor * abs(nominal)) / self.sigma[i] < ACTIVE_RTOL:
                out["gain"].append(names[i])
        return out


def choose_lambda(press: np.ndarray) -> int:
    """The column of `press` (folds × λ, λ = 0 first) to keep: the λ of least held-out residual, if it beats λ = 0 by
    more than the folds' own spread (one standard error of the paired difference summed over folds); else λ = 0. A
    pull towards CAD biases every parameter it touches, so it has to earn its place."""
    total = press.sum(axis=0)
    best = int(np.argmin(total))
    if best == 0:
        return 0
    diff = press[:, best] - press[:, 0]
    se = np.sqrt(diff.size) * diff.std(ddof=1) if diff.size > 1 else 0.0
    return best if -diff.sum() > max(se, CV_TIE * total[0]) else 0


def consistent_fit(model: RobotModel, gram_blocks: np.ndarray, target: np.ndarray, fold_targets: list[np.ndarray],
                   prior: np.ndarray, settings: ConsistentSettings = ConsistentSettings(),
                   null: np.ndarray | None = None) -> ConsistentResult:
    """The consistent Φ on the whole run, λ chosen by cross-validation over its time blocks.

    gram_blocks: (B, p+1, p+1) per time block, the weighted [A b]ᵀ[A b]; target: the unconstrained Φ̂ on the whole
    run; fold_targets[k]: the unconstrained Φ̂ without block k (the jackknife's); null: the unseen directions (see
    `ConsistentProblem`)."""
    started = time.perf_counter()
    p = len(model.layout)
    total = gram_blocks.sum(axis=0)
    cad = np.nan_to_num(model.cad_parameters(), nan=0.0)
    problem = ConsistentProblem(model, prior, cad, total[:p, :p], settings, null)
    B = gram_blocks.shape[0]
    lambdas = list(settings.lambdas)
    press = np.zeros((B, len(lambdas)))  # held-out weighted residual, per fold and λ
    fold_solutions: list[list[np.ndarray]] = [[] for _ in lambdas]
    for k in range(B):
        train = total - gram_blocks[k]
        held = gram_blocks[k]
        for j, lam in enumerate(lambdas):
            phi = problem.solve(train[:p, :p], fold_targets[k], lam)
            x = np.append(phi, -1.0)
            press[k, j] = float(x @ held @ x)
            fold_solutions[j].append(phi)
    best = choose_lambda(press)
    lam = lambdas[best]
    phi = problem.solve(total[:p, :p], target, lam)
    active = problem.active(phi)
    cv = {"lambdas": lambdas, "press": press.sum(axis=0).tolist(), "chosen": lam}
    return ConsistentResult(phi, lam, active, cv, fold_solutions[best], time.perf_counter() - started,
                            problem.solver, problem.status, settings)
