"""The library of candidate effects: each is a block of extra regressor columns on the stacked rows.

A candidate is linear in its parameters given at most one nonlinear value (a Stribeck velocity, a cogging
period, a drift time constant), which the library enumerates on a small grid; selection picks the best one.
Columns live in the rows' own units (N, Nm) before weighting; `Columns.values` is (N, r, K).

Adding an effect = one function `(ctx) -> Iterable[Candidate]` appended to `LIBRARY`, with an `interpret`
callback turning its fitted coefficients into named physical parameters.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ..model import RobotModel
from ..regressors.stack import Signals, group_row_maps, row_channels

STRIBECK_VELOCITIES = (0.005, 0.01, 0.015, 0.02, 0.03, 0.045, 0.07, 0.1)  # rad/s
COGGING_PERIODS_DEG = tuple(float(p) for p in np.round(np.geomspace(1.0, 30.0, 48), 3))  # ~7 % steps
DRIFT_TAUS = (10.0, 20.0, 30.0, 45.0, 60.0, 90.0, 130.0, 200.0, 400.0)  # s; plus "linear"
REFINE = np.linspace(-0.1, 0.1, 21)  # a chosen nonlinear value is refined on ±10 % in 1 % steps


@dataclass(frozen=True)
class Context:
    """What candidates need from one run: the model, the (decimated) signals and their time stamps."""

    model: RobotModel
    sig: Signals
    t: np.ndarray  # s, from the first sample

    @property
    def n(self) -> int:
        return self.sig.q.shape[0]

    @property
    def r(self) -> int:
        return len(row_channels(self.model))


@dataclass(frozen=True)
class Candidate:
    kind: str  # the effect's name (as `dynid simulate --effect` knows it)
    where: str  # "joint r_elbow", "motor m3", "sensor r_arm_ft"
    nonlinear: dict[str, float | str]  # the searched value(s)
    values: np.ndarray  # (N, r, K) columns in row units
    labels: tuple[str, ...]  # one per column
    interpret: Callable[[np.ndarray, np.ndarray], dict[str, float]]  # (θ, Φ of the refit) -> named parameters

    @property
    def key(self) -> str:
        return f"{self.kind} on {self.where}"


def _joint_rows(ctx: Context) -> dict[str, tuple[int, np.ndarray]]:
    """joint -> (its column in q, its (r,) share of each row): rows are L times the joint equations."""
    cfg = ctx.model.config
    out: dict[str, tuple[int, np.ndarray]] = {}
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        L, _ = group_row_maps(g)
        for li, j in enumerate(g.joints):
            share = np.zeros(ctx.r)
            share[start : start + len(g.joints)] = L[:, li]
            out[j] = (cfg.joints.index(j), share)
        start += len(g.joints)
    return out


def _motor_rows(ctx: Context) -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """motor -> (its position q_m = T q (N,), its (r,) share of each row, its group's input name)."""
    cfg = ctx.model.config
    out: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        cols = [cfg.joints.index(j) for j in g.joints]
        if g.input != "torque" and g.motors:
            _, C = group_row_maps(g)
            qm = ctx.sig.q[:, cols] @ g.coupling.T if g.coupled else ctx.sig.q[:, cols]
            for mi, m in enumerate(g.motors):
                share = np.zeros(ctx.r)
                share[start : start + len(g.joints)] = C[:, mi]
                out[m] = (qm[:, mi], share, g.input)
        start += len(g.joints)
    return out


def _on_rows(f: np.ndarray, share: np.ndarray) -> np.ndarray:
    return (f[:, None] * share[None, :])[:, :, None]


def stribeck(ctx: Context, grid: Sequence[float] = STRIBECK_VELOCITIES) -> Iterable[Candidate]:
    """Extra Coulomb friction that decays with speed: s·sign(q̇)·exp(−(q̇/v_s)²); s the extra static torque."""
    for j, (c, share) in _joint_rows(ctx).items():
        v = ctx.sig.dq[:, c]
        for vs in grid:
            f = np.sign(v) * np.exp(-((v / vs) ** 2))
            yield Candidate("stribeck", f"joint {j}", {"velocity": vs}, _on_rows(f, share), ("static_torque",),
                            lambda th, phi, vs=vs: {"static_torque": float(th[0]), "velocity": vs})


def spring(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """A torque k (q − rest) the motor must supply against a spring or cable; the constant k·rest is in the
    span of the asymmetric Coulomb columns, so only k is estimated here."""
    for j, (c, share) in _joint_rows(ctx).items():
        q = ctx.sig.q[:, c]
        yield Candidate("spring", f"joint {j}", {}, _on_rows(q - q.mean(), share), ("stiffness",),
                        lambda th, phi: {"stiffness": float(th[0])})


def cogging(ctx: Context, grid: Sequence[float] = COGGING_PERIODS_DEG) -> Iterable[Candidate]:
    """A motor torque a·sin(2π q_m / P + ψ), linear in (a cos ψ, a sin ψ); P searched (a 2 % error in P over
    20 periods of travel is a 0.4-period phase slip: the search is refined around its best value)."""
    for m, (qm, share, _) in _motor_rows(ctx).items():
        for p in grid:
            k = 2 * np.pi / np.deg2rad(p)
            values = np.concatenate([_on_rows(np.sin(k * qm), share), _on_rows(np.cos(k * qm), share)], axis=2)
            yield Candidate("cogging", f"motor {m}", {"period_deg": p}, values, ("sin", "cos"),
                            lambda th, phi, p=p: {"amplitude": float(np.hypot(th[0], th[1])), "period_deg": p})


def pwm_deadzone(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """A dead-zone of width w: the drive is gain·(u − w·sign u) while it drives, one column sign(u) with
    θ = gain·w. (The exact clip(u, ±w) form fits worse: below the width the motor mostly rests, rows dropped,
    and the filtered u near its zero crossings blurs the clip.)"""
    layout = ctx.model.layout
    for m, (_, share, kind) in _motor_rows(ctx).items():
        if kind != "pwm":
            continue
        u = ctx.sig.inputs[m]
        known = ctx.model.config.motor(m).known_gain
        gain_index = layout.block("motor_gain", m).start if known is None else None

        def interpret(th: np.ndarray, phi: np.ndarray, gi=gain_index, known=known) -> dict[str, float]:
            gain = float(phi[gi]) if gi is not None else float(known)
            return {"width": float(th[0] / gain) if gain else float("nan")}

        yield Candidate("pwm_deadzone", f"motor {m}", {}, _on_rows(np.sign(u), share), ("gain_x_width",), interpret)


def ft_drift(ctx: Context, grid: Sequence[float] = DRIFT_TAUS) -> Iterable[Candidate]:
    """An F/T offset that moves with time: per axis d_k·g(t), g = 1 − exp(−t/τ) (τ searched) or t/T."""
    cfg = ctx.model.config
    t = ctx.t - ctx.t[0]
    shapes: list[tuple[dict[str, float | str], np.ndarray]] = [
        ({"shape": "thermal", "tau": tau}, 1 - np.exp(-t / tau)) for tau in grid
    ]
    if grid is DRIFT_TAUS:
        shapes.append(({"shape": "linear"}, t / max(t[-1], 1e-9)))
    for i, s in enumerate(cfg.ft_sensors):
        for nonlinear, g in shapes:
            values = np.zeros((ctx.n, ctx.r, 6))
            for k in range(6):
                values[:, 6 * i + k, k] = g
            labels = tuple(f"{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz"))

            def interpret(th: np.ndarray, phi: np.ndarray, nonlinear=nonlinear) -> dict[str, float]:
                out: dict[str, float] = {f"d{c}": float(v) for c, v in zip(labels, th)}
                out["force"] = float(np.mean(np.abs(th[:3])))
                out["torque"] = float(np.mean(np.abs(th[3:])))
                if "tau" in nonlinear:
                    out["tau"] = float(nonlinear["tau"])
                return out

            yield Candidate("ft_drift", f"sensor {s.name}", nonlinear, values, labels, interpret)


LIBRARY: dict[str, Callable[..., Iterable[Candidate]]] = {
    "stribeck": stribeck,
    "spring": spring,
    "cogging": cogging,
    "pwm_deadzone": pwm_deadzone,
    "ft_drift": ft_drift,
}

SEARCHED = {"stribeck": "velocity", "cogging": "period_deg", "ft_drift": "tau"}


def refined(ctx: Context, best: Candidate) -> list[Candidate]:
    """Candidates of the same effect and place on a fine grid around the best searched value."""
    key = SEARCHED.get(best.kind)
    if key is None or key not in best.nonlinear:
        return []
    value = float(best.nonlinear[key])
    return [c for c in LIBRARY[best.kind](ctx, tuple(float(v) for v in value * (1 + REFINE))) if c.where == best.where]


# Effects of dynid's simulator this library does not model yet: named in the report as not ruled out.
NOT_IN_LIBRARY = ("armature", "payload", "pwm_delay", "coupling_error", "load_friction", "base_tilt", "ft_gain")
