"""A load one run carries and the others do not, when no --payload says so: the pooled fit averages it into the robot.

Each run in turn is given a payload of its own, a point mass at the configuration's `payload_frame` (the column
`A·v`, v = `RobotModel.payload_parameters(1 kg)`, on that run's rows only), fitted with the base parameters on the
weighted Grams the fit already holds, so no pass over the data. A run is named when its own mass

- lowers the pooled weighted residual by at least MIN_DROP of it (of what the runs named before it leave), and
- stands MIN_SIGMAS standard errors from zero, the error a jackknife over that run's own time blocks (so the model's
  error, correlated in time, widens it as the data's noise would not).

Only where every row's right-hand side is measured: with unknown motor gains the inputs are columns and the rows of
a run without a payload have none (Traversaro et al.'s formulation), so a run's own mass can zero them and the drop
says nothing; there the test is not run.

Forward selection: the run that lowers the residual most is named first and keeps its mass; the others are tested
again beside it (before, every unloaded run asks for the load's share with the opposite sign). Two runs left free are
one difference (+m on one, -m on the other remove the same residual): the one asking for a load is named. The two
thresholds are set between measured cases, not derived from a test's distribution: the time blocks' jackknife over
one run's few blocks, and the best of several candidates, make its σ a scale, not a p-value.

Measured on the UR10e's five identification runs (tools/benchmarks/run_payloads.py): the 2.805 kg run without its
--payload lowers the residual by 48 % with +1.90 kg at tool0 (34 standard errors; a point at tool0's origin, where the
load's centre of mass is not), then the other four by 0.00-0.04 % with -0.02…+0.06 kg; the four unloaded runs alone
0.00-0.03 % with -0.015…+0.014 kg (under one standard error).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..errors import ConfigError
from ..robot.model import RobotModel
from .regression import jackknife_se, restricted_solve
from .statistics import Statistics

MIN_DROP = 0.05  # of the pooled weighted residual sum of squares (measured: loaded 48 %, unloaded ≤ 1.0 %)
MIN_SIGMAS = 10.0  # (loaded 34, unloaded ≤ 6.5)
TIE_RTOL = 1e-9  # drops this close (relative) are one: two runs, one difference


@dataclass(frozen=True)
class ApparentPayload:
    run: int
    mass_kg: float  # at the payload frame's origin
    standard_error_kg: float
    residual_drop: float  # share of the pooled weighted residual sum of squares the run's own mass removes

    def to_json(self) -> dict[str, Any]:
        return {"run": self.run, "mass_kg": self.mass_kg, "standard_error_kg": self.standard_error_kg,
                "residual_drop": self.residual_drop}


def apparent_payloads(model: RobotModel, stats: Statistics, independent: Sequence[int],
                      declared: Sequence[bool], min_drop: float = MIN_DROP,
                      min_sigmas: float = MIN_SIGMAS) -> list[ApparentPayload]:
    """The runs (index into the fit's runs) whose rows ask for a load of their own, in the order named.

    `independent`: the base parameters' columns (BaseParameters.independent); `declared`: per run, whether a
    --payload was given for it (such a run is not a candidate: its load is the user's; its rows stay in the pool)."""
    if stats.n_runs < 2 or stats.p == 0 or model.layout.blocks_of("motor_gain"):
        return []
    try:
        v = np.zeros(stats.p + 1)
        v[model.layout.span("inertial")] = model.payload_parameters(1.0)
    except ConfigError:  # no payload frame the robot carries: nothing to test
        return []
    blocks = stats.gram.sum(axis=1)  # (B, p+1, p+1), the channels summed
    runs = [blocks[stats.block_run == r].sum(axis=0) for r in range(stats.n_runs)]
    pool = _Pool(blocks.sum(axis=0), list(independent), v)
    named: list[ApparentPayload] = []
    candidates = [r for r in range(stats.n_runs) if not declared[r] and np.any(stats.block_run == r)]
    while candidates:
        freed = [a.run for a in named]
        base_ss = pool.residual(runs, freed)[1]
        if not base_ss > 0:
            break
        fits = {r: pool.residual(runs, [*freed, r]) for r in candidates}
        drops = {r: base_ss - ss for r, (_, ss) in fits.items()}
        # Two runs left free are one difference: either run's own mass removes the same residual (+m on one, -m on the
        # other, the base parameters taking the rest). Among drops equal to rounding, the run asking for a load.
        top = max(drops.values())
        tied = [r for r in candidates if drops[r] >= top - TIE_RTOL * max(abs(top), base_ss)]
        best = max(tied, key=lambda r: fits[r][0][-1])
        mass = fits[best][0][-1]
        se = _jackknife(pool, blocks, runs, stats.block_run, freed, best)
        if drops[best] < min_drop * base_ss or not abs(mass) >= min_sigmas * se:
            break
        named.append(ApparentPayload(best, float(mass), float(se), float(drops[best] / base_ss)))
        candidates.remove(best)
    return named


def payload_frame(model: RobotModel) -> str:
    """The frame the apparent masses sit at: the configuration's `payload_frame`, else the last moving link's."""
    return model.config.payload_frame or model.bodies[-1].name


def refusal_hint(model: RobotModel, stats: Statistics, independent: Sequence[int], declared: Sequence[bool]) -> str:
    """For a fit refused as determining nothing across its runs: the runs that carry a load the others do not, if
    any ("" else): such a run makes every run-left-out estimate move, which reads as runs that disagree."""
    loads = apparent_payloads(model, stats, independent, declared)
    return "".join(f"; run {a.run + 1} (in --data order) asks for {a.mass_kg:+.3g} kg at {payload_frame(model)} "
                   f"beyond what the others carry (± {a.standard_error_kg:.2g}): a load not given? (--payload MASS, one "
                   "per --data)" for a in loads)


@dataclass(frozen=True)
class _Pool:
    total: np.ndarray  # (p+1, p+1) [A b]ᵀW²[A b] over every run
    independent: list[int]
    v: np.ndarray  # (p+1,) a unit payload's parameters, 0 at b

    def residual(self, runs: list[np.ndarray], freed: Sequence[int],
                 total: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """(each freed run's mass, the weighted residual sum of squares) of base parameters plus one payload column
        per freed run, from Grams alone."""
        G = self.total if total is None else total
        idx, k, b = self.independent, len(self.independent), G.shape[0] - 1
        n = k + len(freed)
        N, g = np.zeros((n, n)), np.zeros(n)
        N[:k, :k], g[:k] = G[np.ix_(idx, idx)], G[idx, b]
        for a, r in enumerate(freed):
            u = runs[r] @ self.v  # [A b]ᵀ of the run's rows times its payload column
            N[:k, k + a] = N[k + a, :k] = u[idx]
            N[k + a, k + a], g[k + a] = self.v @ u, u[b]  # freed runs share no rows: 0 between their columns
        x = restricted_solve(N, g, np.zeros(n))
        return x[k:], float(G[b, b] - 2 * x @ g + x @ N @ x)


def _jackknife(pool: _Pool, blocks: np.ndarray, runs: list[np.ndarray], block_run: np.ndarray,
               freed: list[int], run: int) -> float:
    """Standard error of `run`'s mass over its own time blocks, each left out in turn (inf with fewer than two)."""
    own = np.flatnonzero(block_run == run)
    if own.size < 2:
        return float("inf")
    masses = []
    for k in own:
        without = list(runs)
        without[run] = runs[run] - blocks[k]
        masses.append(pool.residual(without, [*freed, run], pool.total - blocks[k])[0][-1])
    return float(jackknife_se(np.asarray(masses)))
