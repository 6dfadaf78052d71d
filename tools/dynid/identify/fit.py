"""`dynid fit`: the four kinds of parameters in one regression (Traversaro et al. 2013), three estimators.

Data path: dataset → signals (q̇, q̈ estimated offline, non-causal) → row weights 1/σ, rows at rest left out →
sufficient statistics per time block (`dynid.identify.statistics`) → base parameters of the run → estimators:

- ``ols``: least squares on the base parameters, the baseline;
- ``pls``: Partial Least Squares by NIPALS on every parameter (kernel form), ν latent variables chosen by
  cross-validation on held-out time blocks;
- ``iv``: instrumental variables (IDIM-IV). In closed loop the measured PWM carries the disturbance the
  controller compensates, and the encoder-derived q̇, q̈ carry noise: both bias OLS and PLS, the motor gains
  most (the default simulated arm: −9…−11 % on the shoulder gains). The instruments are the regressor along a smoothed
  trajectory (a 0.2 s Savitzky-Golay fit: its noise is nearly independent of the fit's 31 ms derivatives),
  with each input column replaced by the model's own noise-free predicted input û(Φ̂), iterated to a fixed
  point. dynid does not know the robot's controller, so unlike DIDIM it does not simulate the closed loop.

Uncertainty: a delete-one-block jackknife over the time blocks, which keeps the residuals' autocorrelation
(rows of one sample and of neighbouring samples are not independent, so the textbook σ²(AᵀA)⁻¹ is too small).
On a short run a fold can miss a direction the whole run sees (a joint that moved one way only in the block left
out): the fold is solved on the whole run's base with those directions at the prior (`restricted_solve`), and
every base combination they involve is reported as not determined, the fold named in `FitResult.jackknife`
(the jackknife cannot estimate an error the data of one block alone carry).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from threadpoolctl import threadpool_limits

from ..errors import DataError, InputError
from ..io.dataset import Dataset
from ..io.stream import Run
from ..io.derivatives import SavitzkyGolay
from ..margins import below
from ..progress import track
from ..robot.model import RobotModel
from ..robot.outputs import output_channels
from ..robot.regressors.base import BaseParameters, base_parameters_from_factor, structural_base_parameters
from ..robot.regressors.stack import DEFAULT_MIN_SPEED, Signals, row_weights, signals_from_dataset
from .consistent import LAMBDAS, ConsistentSettings, consistent_fit
from .model_sections import DEFAULT_BLOCKS, DEFAULT_ESTIMATOR, INSTRUMENT_WINDOW_S
from .determined import at_bound, borderline_determined, sizes
from .determined import determined as determined_by
from .run_payloads import refusal_hint
from .regression import InputColumns, jackknife_se, base_least_squares, instrumental_variables, pls_path, unseen_directions
from .statistics import MIN_BLOCK_SAMPLES, Statistics, accumulate

ESTIMATORS: tuple[str, ...] = ("iv", "pls", "ols")
IV_TOL = 1e-10  # the IV iteration's fixed point: largest relative change of β̂ in one iteration
# The IV has settled when its last step moved no combination by more than 0.1 % of its value: immaterial beside the
# 10 % that determines one (a short run's rounding floor is near 1e-8; a diverging iteration's steps exceed 1).
IV_SETTLED = 1e-3
# At most one fold in this many may fail to settle: it is left out of the block jackknife (more: IV determines nothing)
UNSETTLED_FOLDS_DROPPED = 10
# Rank threshold on singular values of the column-normalised system, from the Gram matrix: its rounding floor
# sits near 1e-8 (the square root of machine precision), the iCub's last base direction near 1e-2.
BASE_RTOL = 1e-6
PRESS_TIE_RTOL = 1e-9  # held-out PRESS values this close to the least are a tie (cross_validate_nu)


@dataclass(frozen=True)
class FitSettings:
    estimator: str = DEFAULT_ESTIMATOR
    n_components: int | None = None  # PLS ν; None: cross-validated
    min_speed: float = DEFAULT_MIN_SPEED
    blocks: int = DEFAULT_BLOCKS
    instrument_window_s: float = INSTRUMENT_WINDOW_S
    iv_iterations: int = 100
    workers: int | None = None
    # Physically consistent estimation (dynid.identify.consistent, docs/consistency.md): the chosen estimator's Φ̂
    # projected onto physical parameters; the model keeps that one (estimate "consistent"), all others are reported.
    # Off by default: on the default arm it cost the live mission 2 of its 22 episodes (docs/consistency.md#default)
    consistent: bool = False
    # Its pull towards CAD, λ cross-validated over consistent.LAMBDAS; off by default: λ = 0, the data alone
    cad_pull: bool = False
    # Its density-realizable sphere about each body's frame (off: every pseudo-inertia PSD, nothing more)
    consistent_sphere: bool = True


PSEUDO_INERTIA_ONLY = "pseudo-inertia"  # `--consistent pseudo-inertia`: every J ⪰ 0, no sphere about the body's frame


@dataclass
class Estimate:
    name: str
    beta: np.ndarray  # base parameters (rank,)
    se: np.ndarray  # standard errors (rank,): the larger of the two jackknifes' where runs were jackknifed
    phi: np.ndarray  # a full Φ with these base parameters (dependent entries from the prior)
    detail: dict = field(default_factory=dict)
    se_blocks: np.ndarray | None = None  # delete-one-time-block jackknife (within runs): today's only error
    se_runs: np.ndarray | None = None  # delete-one-unit jackknife over runs (or pairs); None with one unit
    units: np.ndarray | None = None  # (units, rank) the estimate of each unit alone (directions it misses: prior)
    # (B, p) a full Φ fitted without each time block (the jackknife's folds), and which of them the jackknife kept (an
    # IV fold that did not settle is left out): each block's residual through its fold's Φ is out of sample
    folds: np.ndarray | None = None
    folds_kept: np.ndarray | None = None


@dataclass
class FitResult:
    model: RobotModel
    base: BaseParameters
    estimates: dict[str, Estimate]
    chosen: str
    cv: dict
    residual_variance: dict[str, np.ndarray]  # estimator -> per output channel, rows at rest left out
    identified: np.ndarray  # (rank,) bool: the run determines this combination
    statistics: Statistics
    samples: int
    rows_used: np.ndarray  # per row channel
    jackknife: dict = field(default_factory=dict)  # folds, and the rank-deficient ones with what they do not see
    consistent: dict | None = None  # the consistent fit's λ, active constraints, CV, solver; or its failure; None: off

    @property
    def phi(self) -> np.ndarray:
        return self.estimates[self.chosen].phi

    def borderline(self) -> dict:
        """The fit's decisions that sit on their thresholds (dynid.margins), each taken the conservative way: base
        combinations not determined, singular values not counted in the rank, an IV iteration not settled."""
        chosen = self.estimates[self.chosen]
        cad = sizes(self.model, self.base, self.statistics)
        names = self.base.combinations()
        return {"determined": [names[i] for i in np.flatnonzero(borderline_determined(chosen, cad))],
                "rank_cut": [float(v) for v in self.base.on_the_cut],
                "iv_settled": iv_settled(chosen.detail)[1]}


def instrument_signals(sig: Signals, t: np.ndarray, window_s: float) -> Signals:
    """The instrument trajectory: positions smoothed over `window_s`, with their derivatives (the long window by FFT:
    an instrument row at rest is left out with the fit's own, so its q̇ need not be exactly 0 there)."""
    try:
        smooth = SavitzkyGolay(window_s=window_s, fft=True)(t, sig.q)
    except ValueError as e:
        raise DataError(f"cannot build the IV instruments: {e}") from None
    return Signals(smooth.q, smooth.dq, smooth.ddq, sig.inputs, sig.tau, sig.ft, sig.payload, sig.gravity)


@dataclass
class SignalSource:
    """The signals of rows [lo, hi) of a dataset, computed on demand from the raw data around them.

    Every filter here (the derivative smoother, the instruments' smoother over it) is local, so a window
    widened by `margin` samples on each side gives the same values as the whole record would: memory stays
    proportional to the raw data, never to the derived signals of an hour-long log.
    """

    model: RobotModel
    dataset: Run  # in memory, or a file read a window at a time (dynid.io.stream)
    settings: FitSettings
    instruments: bool

    def __post_init__(self) -> None:
        dt = self.dataset.median_step()
        window_s = float(self.model.config.derivatives.get("window_s", SavitzkyGolay.window_s))
        if self.instruments:
            window_s += self.settings.instrument_window_s
        self.margin = int(np.ceil(window_s / dt)) + 8  # both half windows, twice over: jittered stamps

    @property
    def n_samples(self) -> int:
        return self.dataset.n_samples

    def __call__(self, lo: int, hi: int) -> tuple[Signals, Signals | None, np.ndarray]:
        """(signals, instrument signals or None, row weights) of rows [lo, hi)."""
        a, b = max(0, lo - self.margin), min(self.n_samples, hi + self.margin)
        part = self.dataset.slice(a, b)
        keep = slice(lo - a, hi - a)
        sig = signals_from_dataset(self.model, part, filter_outputs=True)
        weights = row_weights(self.model, sig, self.settings.min_speed)
        inst = None
        if self.instruments:
            inst = instrument_signals(sig, part.t, self.settings.instrument_window_s)
            weights *= row_weights(self.model, inst, self.settings.min_speed) > 0  # at rest on either trajectory
            inst = inst.slice(keep)
        return sig.slice(keep), inst, weights[keep]


def _factor(gram: np.ndarray) -> np.ndarray:
    """F with FᵀF = G (symmetric square root, through the unit-diagonal scaling for accuracy)."""
    d = np.sqrt(np.clip(np.diag(gram), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    lam, V = np.linalg.eigh(gram / np.outer(d, d))
    return (np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T) * d[None, :]


def prior_parameters(model: RobotModel) -> np.ndarray:
    """What fills the combinations the data cannot see: the CAD inertia, the configured nominal motor gains (a
    motor whose joint never moves still needs a gain to predict its input), zero for everything else."""
    prior = np.nan_to_num(model.cad_parameters(), nan=0.0)
    for b in model.layout.blocks_of("motor_gain"):
        prior[b.start] = model.config.motor(b.owner).nominal_gain
    return prior


def expand(base: BaseParameters, beta: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """A full Φ with base parameters β: Φ_d from the prior, Φ_b = β − K Φ_d (predictions depend on β only)."""
    phi = prior.copy()
    phi[base.independent] = beta - base.K @ prior[base.dependent]
    return phi


def _input_columns(model: RobotModel, base: BaseParameters) -> InputColumns:
    """The channels whose instrument is the predicted input: those whose gain the run identifies on its own. A
    gain that is no base parameter (its motor never moves, or its input never changes) has no row of Zᵀ A_b to
    instrument: that channel's raw instruments serve (the replaced entry would be the gain's, unused)."""
    independent = set(base.independent.tolist())
    return InputColumns({o.row: o.gain_index for o in output_channels(model)
                         if o.gain_index is not None and o.gain_index in independent})


def _estimate(name: str, stats: Statistics, keep: np.ndarray | None, base: BaseParameters, settings: FitSettings,
              nu: int, inputs: InputColumns | None, start: np.ndarray | None,
              prior: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """β̂ of one estimator on the blocks `keep`; base directions those blocks do not see stay at `prior` (β)."""
    sel = slice(None) if keep is None else keep
    G = stats.system(sel)
    p = stats.p
    ind = base.independent
    if name == "ols":
        return base_least_squares(G, ind, prior), {}
    if name == "pls":
        path = pls_path(G[:p, :p], G[:p, p], nu)
        coef = path[-1] if len(path) else np.zeros(p)  # no latent variable at all: Xᵀy is zero on these blocks
        return base.base(coef), {"n_components": nu}
    cross = stats.cross[sel].sum(axis=0)
    cross_b = stats.cross_b[sel].sum(axis=0)
    beta0 = start if start is not None else base_least_squares(G, ind, prior)
    beta, iterations, step = instrumental_variables(cross, cross_b, ind, beta0, inputs, settings.iv_iterations,
                                                    IV_TOL, prior)
    # `step`: the last iteration's largest relative change (rounding keeps a short run's near 1e-8, above the 1e-10
    # that ends the iteration; far above, the iterate has not settled and only its jackknife error says how far off)
    detail = {"iterations": iterations, "converged": step < IV_TOL,
              "last_step": step if np.isfinite(step) else None, "instrument_window_s": settings.instrument_window_s}
    if start is None and prior is not None:
        # A fixed point is only an answer if the iteration reaches it from elsewhere too. On a run too short for its
        # rank the map is not a contraction: its iterates wander (steps of 1–100), and where the 30th lands depends
        # on the last bit of every product (one CPU's kernels stop near 1e-5, another's at 10). A second start, the
        # prior (CAD inertia, nominal gains), must end at the same β̂: then "settled" is the same answer everywhere.
        other, _, other_step = instrumental_variables(cross, cross_b, ind, prior, inputs, settings.iv_iterations,
                                                      IV_TOL, prior)
        detail["start_spread"] = float(np.max(np.abs(other - beta) / np.maximum(np.abs(beta), 1e-12))) \
            if np.all(np.isfinite(other)) and np.isfinite(other_step) else None
    return beta, detail


def iv_settled(detail: dict) -> tuple[bool, bool]:
    """(settled, borderline) of an IV estimate's detail: its last step and, for the estimate on all blocks, the
    spread between its two starts, both under IV_SETTLED past the margin's band (dynid.margins), and every jackknife
    fold's iteration settled as well or was left out of the jackknife (at most one in UNSETTLED_FOLDS_DROPPED: a fold
    that wanders makes the standard errors, and so "determined", arbitrary: on a 0.6 s run one fold's steps end near 5
    on one CPU and 160 on another)."""
    if "last_step" not in detail:
        return True, False  # not an iteration
    measures = [detail["last_step"]] + ([detail["start_spread"]] if "start_spread" in detail else [])
    if any(m is None for m in measures) or set(detail.get("folds_unsettled", ())) - set(detail.get("folds_dropped", ())):
        return False, False
    settled = all(below(m, IV_SETTLED)[0] for m in measures)
    near = any(below(m, IV_SETTLED)[1] for m in measures)
    return settled, near


def cross_validate_nu(stats: Statistics, max_components: int) -> dict:
    """Held-out weighted residual sum of squares for ν = 1 … max, one time block held out at a time."""
    p, B = stats.p, stats.n_blocks
    total = stats.system()
    press = np.zeros(max_components)
    available = max_components  # NIPALS stops early once Xᵀy is exhausted on some training set
    for k in track(range(B), B, "cross-validating PLS"):
        held = stats.gram[k].sum(axis=0)
        train = total - held
        path = pls_path(train[:p, :p], train[:p, p], max_components)
        if not len(path):  # Xᵀy is zero without block k: this training set predicts zero
            path = np.zeros((1, p))
        available = min(available, len(path))
        for i, coef in enumerate(path[:available]):
            press[i] += held[p, p] - 2 * coef @ held[:p, p] + coef @ held[:p, :p] @ coef
    press = press[:available]
    # PRESS flattens out near the rank: values within rounding of the least are ties, and the smallest ν among them
    # is taken, so that the choice does not hang on the last bits of the sums (another CPU's kernels)
    best = int(np.flatnonzero(press <= press.min() * (1 + PRESS_TIE_RTOL))[0]) + 1
    return {"n_components": best, "candidates": list(range(1, available + 1)), "press": press.tolist()}


def run_units(payloads: Sequence[object]) -> list[int]:
    """The jackknife's units over runs, from each run's payload (falsy: none): each run is a unit, except that a
    run carrying a known payload joins the unloaded run before it (a loaded/unloaded pair fixes the scale only
    together, so the pair is the unit; loaded runs before the first unloaded one join it)."""
    units: list[int] = []
    unit, unloaded = -1, False
    for payload in payloads:
        if unit < 0 or (not payload and unloaded):
            unit, unloaded = unit + 1, False
        unloaded |= not payload
        units.append(unit)
    return units


def fit_statistics(model: RobotModel, stats: Statistics, settings: FitSettings, samples: int,
                   units: Sequence[int] | None = None, declared: Sequence[bool] = ()) -> FitResult:
    """Every estimator, its jackknife errors and the base structure, from the runs' statistics.

    With two or more units (runs, or loaded/unloaded pairs: `run_units`), each estimate has a second jackknife,
    over the units (one left out at a time), which sees what differs between runs (friction that drifts with
    temperature, a payload mounted differently); its standard error is reported beside the within-run one
    (time blocks), `se` is the larger, and a combination is determined only when both determine it. `declared`: per
    run, whether its payload was given (a refusal names the runs that ask for a load of their own, the others)."""
    p = stats.p
    G = stats.system()
    base = base_parameters_from_factor(_factor(G)[:, :p], model.layout.names, BASE_RTOL)
    if base.rank == 0:
        raise DataError("the data excite no parameter at all (does the arm move?)")
    if not np.any(G[:p, p]):
        raise DataError("the measured wrenches and joint torques are all zero (or excite no parameter): nothing "
                        "fixes the parameters' scale")
    rows_used = stats.rows.sum(axis=0)
    if rows_used.sum() < 2 * base.rank:
        raise DataError(f"too few moving samples: {int(rows_used.sum())} usable rows (rows of resting joints and "
                        f"motors are left out) for {base.rank} base parameters, which need at least "
                        f"{2 * base.rank}: does the arm move in this run?")
    check_excitation(model, base)
    if stats.n_blocks < 2:
        if settings.blocks < 2:
            raise DataError(f"--blocks {settings.blocks}: cross-validation and the jackknife need at least 2 time "
                            "blocks")
        raise DataError(f"too few samples for cross-validation: {samples} (at least {2 * MIN_BLOCK_SAMPLES} needed): "
                        "give a longer run or a wider --from/--to window")
    prior = prior_parameters(model)
    beta_prior = base.base(prior)
    # PLS has no more components than the regressor has columns (beyond the rank it runs on until Xᵀy is exhausted,
    # which floating point needs to reach least squares: tools/tests/test_estimators.py)
    if settings.n_components is not None and settings.n_components > len(model.layout):
        raise InputError(f"--n-components {settings.n_components}: PLS has at most as many latent variables as the "
                         f"regressor has columns, {len(model.layout)} here (the base parameters' rank: {base.rank})")
    cv = cross_validate_nu(stats, base.rank) if settings.n_components is None else {"n_components": settings.n_components}
    nu = int(cv["n_components"])
    names = [settings.estimator] + [e for e in ESTIMATORS if e != settings.estimator]
    inputs = None
    if stats.cross is not None:
        inputs = _input_columns(model, base)
    elif "iv" in names:
        names.remove("iv")
    B = stats.n_blocks
    folds = [np.arange(B) != k for k in range(B)]
    unseen = np.array([_unseen(stats.system(f), base) for f in folds])  # (B, rank)
    block_unit = np.asarray(units if units is not None else range(stats.n_runs))[stats.block_run]
    n_units = int(block_unit.max()) + 1
    unit_folds = [block_unit != u for u in range(n_units)] if n_units >= 2 else []
    unit_unseen = np.array([_unseen(stats.system(f), base) for f in unit_folds]).reshape(-1, base.rank)
    estimates: dict[str, Estimate] = {}
    folds_of: dict[str, np.ndarray] = {}
    for name in names:
        beta, detail = _estimate(name, stats, None, base, settings, nu, inputs, None, beta_prior)
        replicates = [_estimate(name, stats, f, base, settings, nu, inputs, beta, beta_prior) for f in folds]
        jack = np.array([b for b, _ in replicates])
        folds_of[name] = jack
        settled_folds = np.ones(len(folds), dtype=bool)
        if "last_step" in detail:  # an iteration: its jackknife error means something only if its folds settled too
            unsettled = [k for k, (_, d) in enumerate(replicates) if not iv_settled(d)[0]]
            detail["folds_unsettled"] = unsettled
            if 0 < len(unsettled) <= len(folds) // UNSETTLED_FOLDS_DROPPED:
                # One fold in ten whose iteration wanders (8 s of the default run: the fold without block 5 ends at a
                # step of 5, the nine others near 1e-7) is left out of the jackknife rather than failing the fit
                detail["folds_dropped"] = unsettled
                settled_folds[unsettled] = False
        se_blocks = jackknife_se(jack[settled_folds])
        se_runs, alone = None, None
        if unit_folds:
            runs = np.array([_estimate(name, stats, f, base, settings, nu, inputs, beta, beta_prior)[0]
                             for f in unit_folds])
            se_runs = jackknife_se(runs)
            alone = np.array([_estimate(name, stats, ~f, base, settings, nu, inputs, beta, beta_prior)[0]
                              for f in unit_folds])
        se = se_blocks if se_runs is None else np.maximum(se_blocks, se_runs)
        estimates[name] = Estimate(name, beta, se, expand(base, beta, prior), detail, se_blocks, se_runs, alone,
                                   np.array([expand(base, b, prior) for b in jack]), settled_folds)
    chosen_name = settings.estimator
    consistent = None
    if settings.consistent:
        consistent, est = _consistent(model, stats, base, estimates[chosen_name], folds_of[chosen_name], prior,
                                      ConsistentSettings(lambdas=LAMBDAS if settings.cad_pull else (0.0,),
                                                         sphere=settings.consistent_sphere))
        if est is not None:
            estimates[est.name] = est
            chosen_name = est.name
    exact: list[str] = []
    variance = {name: channel_variance(stats, e.phi, model, exact if name == chosen_name else None)
                for name, e in estimates.items()}
    if exact:
        estimates[chosen_name].detail["exact_channels"] = exact
    # A channel with rows whose residual variance is negative beyond rounding: the Gram is not one (a fault in the
    # data's arithmetic), so nothing is left to calibrate its Λ on. (A channel without rows, a motor that never moves,
    # keeps its noise variance in the detector.)
    flat = [o.name for o, v in zip(output_channels(model), variance[chosen_name])
            if rows_used[o.row] > 0 and not (np.isfinite(v) and v > 0)]
    if flat:
        raise DataError(f"the residual of {', '.join(flat)} has no positive variance (beyond rounding): the "
                        "run holds no information to calibrate the detector on (values not finite, or a run that does "
                        "not move)")
    chosen = estimates[chosen_name]
    cad = sizes(model, base, stats)
    settled, _ = iv_settled(chosen.detail)

    def determined(blocks_only: bool = False) -> np.ndarray:
        """Combinations determined by every condition, with the estimates' errors (the larger jackknife's) or, with
        `blocks_only`, the time blocks' jackknife alone."""
        of = (lambda e: replace(e, se=e.se_blocks)) if blocks_only else (lambda e: e)
        ok = determined_by(of(chosen), cad)
        if chosen_name == CONSISTENT:
            # The constraints narrow the folds' spread, but they do not make the run determine a combination: it must
            # be determined without them too, and not rest on a bound (a gain at its floor is the same in every fold)
            ok &= determined_by(of(estimates[settings.estimator]), cad) & ~at_bound(base, model, consistent)
        ok &= ~unseen.any(axis=0)  # a fold cannot see them: the jackknife has no error to give
        return ok & settled  # an iterate that still moves: neither it nor its jackknife spread means anything

    identified = determined() & ~unit_unseen.any(axis=0)  # (unit_unseen: the same for a run or pair left out)
    if not identified.any():
        loads = refusal_hint(model, stats, base.independent, list(declared) or [False] * stats.n_runs)
        within = determined(blocks_only=True) if chosen.se_runs is not None and chosen.se_blocks is not None else None
        if within is not None and within.any():
            # Determined over time blocks, but not across the runs: say that, not "a longer run"
            raise DataError(
                f"no base combination is determined to 10 % across the runs (the time blocks alone determine "
                f"{int(within.sum())} of {base.rank}): leaving out one of the {n_units} units (a run, or a loaded "
                "run with the unloaded one before it) moves every estimate by more; the runs disagree, or one "
                "unit alone sees what the others cannot (a single loaded run fixes the gains' scale): fit it "
                "alone, or add runs that see the same" + loads)
        hint = f"; the {chosen.name} iteration did not settle (try --estimator ols)" if not settled else ""
        if loads:
            raise DataError(f"the runs determine no base combination to 10 % ({samples} samples, rank {base.rank}"
                            f"{hint}){loads}")
        raise DataError(f"the run determines no base combination to 10 % ({samples} samples, rank {base.rank}{hint}): "
                        "a longer run, or one that moves every joint both ways, is needed")
    combinations = base.combinations()
    edges = stats.block_samples
    jackknife = {"folds": B, "rank_deficient": [
        {"block": k, "samples": [int(edges[k]), int(edges[k + 1])],
         "unseen": [combinations[i] for i in np.flatnonzero(unseen[k])]}
        for k in range(B) if unseen[k].any()],
        "runs": stats.n_runs, "units": n_units,
        "unit_of_run": [int(block_unit[stats.block_run == r][0]) for r in range(stats.n_runs)],
        "unit_rank_deficient": [{"unit": u, "unseen": [combinations[i] for i in np.flatnonzero(unit_unseen[u])]}
                                for u in range(len(unit_folds)) if unit_unseen[u].any()]}
    return FitResult(model, base, estimates, chosen_name, cv, variance, identified, stats, samples, rows_used,
                     jackknife, consistent)


MIN_EXCITED_SHARE = 0.5  # a run that excites fewer than this share of the structure's base directions is refused


def check_excitation(model: RobotModel, base: BaseParameters) -> None:
    """Refuse a run that excites far fewer directions than the robot's structure allows (a still arm: rank 10 or
    less of 87, one posture's outputs), naming what is missing: the joints that never move and the inputs that never
    change. A short run that misses a few directions fits, with those combinations undetermined."""
    structural = structural_base_parameters(model).rank
    if base.rank >= MIN_EXCITED_SHARE * structural:
        return
    silent = set(base.unidentifiable)
    joints = [j for j in model.config.joints if f"{j}.fc_pos" in silent and f"{j}.fc_neg" in silent]
    inputs = [n.split(".")[0] for n in silent if n.endswith(".phi_m")]
    missing = "; ".join(part for part in (
        f"joints that never move: {', '.join(joints)}" if joints else "",
        f"inputs that never change: {', '.join(inputs)}" if inputs else "") if part)
    raise DataError(f"the run excites {base.rank} of the {structural} directions this robot's structure allows: too "
                    f"little to fit ({missing or 'its motion is too small or too uniform'}); record a run that moves "
                    "every joint both ways (dynid excite designs one)")


CONSISTENT = "consistent"


def _consistent(model: RobotModel, stats: Statistics, base: BaseParameters, unconstrained: Estimate,
                jack: np.ndarray, prior: np.ndarray,
                settings: ConsistentSettings = ConsistentSettings(lambdas=(0.0,))) -> tuple[dict, Estimate | None]:
    """The consistent estimate from the unconstrained one (its fold estimates are the CV's targets), or, when the
    solver fails, the reason (the model then keeps the unconstrained estimate: docs/consistency.md)."""
    try:
        null = np.zeros((stats.p, base.dependent.size))  # Φ_ind = −K Φ_dep: what the data do not see
        null[base.dependent, np.arange(base.dependent.size)] = 1.0
        null[base.independent] = -base.K
        done = consistent_fit(model, stats.gram.sum(axis=1), unconstrained.phi,
                              [expand(base, b, prior) for b in jack], prior, settings, null)
    except DataError as e:
        return {"status": "failed", "reason": str(e), "from": unconstrained.name}, None
    record = {"status": "solved", "from": unconstrained.name, **done.record()}
    fold_betas = np.array([base.base(phi) for phi in done.folds])
    detail = dict(record)
    if "last_step" in unconstrained.detail:  # the IV iterate it starts from: settled or not
        detail["last_step"] = unconstrained.detail["last_step"]
        detail["iterations"] = unconstrained.detail.get("iterations")
    return record, Estimate(CONSISTENT, base.base(done.phi), jackknife_se(fold_betas), done.phi, detail,
                            folds=np.asarray(done.folds, float), folds_kept=np.ones(len(done.folds), dtype=bool))


def _unseen(gram: np.ndarray, base: BaseParameters) -> np.ndarray:
    """(rank,) bool: the base combinations that the rows of `gram` ([A b]ᵀ[A b]) leave undetermined, i.e. that a
    direction their base Gram does not see involves (above rounding)."""
    V = unseen_directions(gram[np.ix_(base.independent, base.independent)])
    return np.linalg.norm(V, axis=1) > 1e-8


def channel_variance(stats: Statistics, phi: np.ndarray, model: RobotModel,
                     exact: list[str] | None = None) -> np.ndarray:
    """Per output channel: the mean square of e = y − ŷ over the rows used (from the per-channel Gram).

    From the Gram, x'Gx carries a rounding error of about p·ε·|x|'|G||x|; a residual within that bound is zero to
    rounding (noise-free data the model reproduces exactly): its variance is that bound, and its name is appended to
    `exact`. Below zero beyond the bound, the value stays negative (the caller refuses it)."""
    x = np.append(phi, -1.0)  # weighted residual of a row: [a b]·[Φ; −1] = w (aΦ − b)
    outs = output_channels(model)
    G = stats.gram.sum(axis=0)
    n = np.maximum(stats.rows.sum(axis=0), 1)
    out = np.empty(len(outs))
    for o in outs:
        weighted = x @ G[o.row] @ x / n[o.row]  # mean of (aΦ − b)²/σ_row²
        rounding = len(x) * np.finfo(float).eps * (np.abs(x) @ np.abs(G[o.row]) @ np.abs(x)) / n[o.row]
        if abs(weighted) <= rounding and rounding > 0:
            weighted = rounding
            if exact is not None:
                exact.append(o.name)
        g = phi[o.gain_index] if o.gain_index is not None else o.known_gain
        out[o.row] = weighted * stats.channels[o.row].sigma ** 2 / g**2
    return out


def fit(model: RobotModel, datasets: list[Dataset], settings: FitSettings = FitSettings()) -> FitResult:
    if settings.estimator not in ESTIMATORS:
        raise DataError(f"unknown estimator '{settings.estimator}' (known: {', '.join(ESTIMATORS)})")
    total: Statistics | None = None
    samples = 0
    for i, ds in enumerate(datasets):
        # IV's instruments do not carry a payload's known torques yet: no IV when a run has one (pipeline.py)
        source = SignalSource(model, ds, settings, instruments=not ds.meta.get("payload"))
        source(0, min(ds.n_samples, 2 * source.margin))  # bad data fail here, before any worker starts
        label = "building regressors" + (f", run {i + 1} of {len(datasets)}" if len(datasets) > 1 else "")
        stats = accumulate(model, source, settings.blocks, settings.workers, label=label)
        total = stats if total is None else total + stats
        samples += ds.n_samples
    assert total is not None
    # The estimators work on p × p Grams (p ≈ 100): BLAS threads cost more than they give there (2-3× slower on a
    # shared 2-core machine, measured: docs/benchmarks.md#compiled-kernels).
    with threadpool_limits(limits=1, user_api="blas"):
        payloads = [ds.meta.get("payload") for ds in datasets]
        return fit_statistics(model, total, settings, samples, run_units(payloads), [bool(p) for p in payloads])
