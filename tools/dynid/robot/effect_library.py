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
import pinocchio as pin

from .model import RobotModel
from .regressors.friction import friction_regressor, stribeck_shape
from .regressors.rigid_body import rigid_body_regressors
from .regressors.stack import Signals, group_row_maps, joint_row_shares, motor_velocities, row_channels

STRIBECK_VELOCITIES = (0.005, 0.01, 0.015, 0.02, 0.03, 0.045, 0.07, 0.1)  # rad/s
COGGING_PERIODS_DEG = tuple(float(p) for p in np.round(np.geomspace(1.0, 30.0, 48), 3))  # ~7 % steps
DRIFT_TAUS = (10.0, 20.0, 30.0, 45.0, 60.0, 90.0, 130.0, 200.0, 400.0)  # s; plus "linear"
DELAYS_MS = (1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 18.0, 27.0, 40.0, 60.0, 90.0, 135.0)
REFINE = np.linspace(-0.1, 0.1, 21)  # a chosen nonlinear value is refined on ±10 % in 1 % steps


@dataclass(frozen=True)
class Context:
    """What candidates need from one run: the model, the (decimated) signals and their time stamps."""

    model: RobotModel
    sig: Signals
    t: np.ndarray  # s, from the first sample
    phi: np.ndarray | None = None  # the standard model refitted on the run: bilinear effects linearise about it
    rigid: np.ndarray | None = None  # (N, r) its rigid-body part of every row (the predicted wrench on F/T rows)
    inputs_full: dict[str, np.ndarray] | None = None  # each filtered input at the full rate (before decimation)
    index_full: np.ndarray | None = None  # (N,) the kept samples' indices into the full rate
    rate: float = 0.0  # Hz of the full rate
    # (N, r, n_inertial) the rigid-body columns of every link's inertial parameters, when the gap is measured
    # against a given model whose inertias are held (`dynid gaps --model`): only then can a payload be named
    inertial_columns: np.ndarray | None = None
    t0: float = 0.0  # the data's own seconds at t = 0 (an F/T step is at times of the data, dynid.gaps.steps)

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
    positive: tuple[int, ...] = ()  # the θ that must be > 0 for the fit to be this effect (a Stribeck bump, a mass)

    @property
    def key(self) -> str:
        return f"{self.kind} on {self.where}"


def _joint_rows(ctx: Context) -> dict[str, tuple[int, np.ndarray]]:
    return joint_row_shares(ctx.model)


def _motor_rows(ctx: Context, x: str = "q") -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """motor -> (its coordinate T x (N,) for x = q, dq or ddq, its (r,) share of each row, its group's input)."""
    cfg = ctx.model.config
    out: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        cols = [cfg.joints.index(j) for j in g.joints]
        if g.input != "torque" and g.motors:
            _, C = group_row_maps(g)
            xj = getattr(ctx.sig, x)[:, cols]
            xm = xj @ g.coupling.T if g.coupled else xj
            for mi, m in enumerate(g.motors):
                share = np.zeros(ctx.r)
                share[start : start + len(g.joints)] = C[:, mi]
                out[m] = (xm[:, mi], share, g.input)
        start += len(g.joints)
    return out


def _gain(ctx: Context, phi: np.ndarray | None, m: str) -> float:
    """Motor m's gain (Nm per unit duty): the configured one if known, else the fitted one in `phi`."""
    known = ctx.model.config.motor(m).known_gain
    if known is not None:
        return float(known)
    if phi is None:
        return float("nan")
    return float(phi[ctx.model.layout.block("motor_gain", m).start])


def _on_rows(f: np.ndarray, share: np.ndarray) -> np.ndarray:
    return (f[:, None] * share[None, :])[:, :, None]


def stribeck(ctx: Context, grid: Sequence[float] = STRIBECK_VELOCITIES) -> Iterable[Candidate]:
    """Extra Coulomb friction that decays with speed: s·sign(q̇)·exp(−(q̇/v_s)²); s the extra static torque."""
    for j, (c, share) in _joint_rows(ctx).items():
        for vs in grid:
            yield Candidate("stribeck", f"joint {j}", {"velocity": vs}, _on_rows(stribeck_shape(ctx.sig.dq[:, c], vs), share),
                            ("static_torque",), lambda th, phi, vs=vs: {"static_torque": float(th[0]), "velocity": vs},
                            positive=(0,))


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
                out["force"] = float(np.linalg.norm(th[:3]))  # the step's size, as limit_step's
                out["torque"] = float(np.linalg.norm(th[3:]))
                if "tau" in nonlinear:
                    out["tau"] = float(nonlinear["tau"])
                return out

            yield Candidate("ft_drift", f"sensor {s.name}", nonlinear, values, labels, interpret)


def armature(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """Rotor inertia J seen in the motor coordinate: the motor also drives J·q̈_m (q̈_m = T q̈), which the link
    inertias cannot mimic because it loads only that motor's rows."""
    for m, (ddqm, share, _) in _motor_rows(ctx, "ddq").items():
        yield Candidate("armature", f"motor {m}", {}, _on_rows(ddqm, share), ("inertia",),
                        lambda th, phi: {"inertia": float(th[0])}, positive=(0,))  # a rotor inertia is > 0


def load_friction(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """Coulomb friction growing with the transmitted torque: c·|τ_m|·sign(q̇_m), one column sign(q̇_m)|τ̂_m| with
    θ = c, where τ̂_m = gain·û_m is the drive torque the standard model refitted on the run predicts (it differs
    from a gain error only where the drive opposes the motion: braking, lowering). The model's prediction, not the
    measured input: the input is the row's own output, and a column of it lets the fit explain the row by itself (a
    UR10e wrist's measured current, mostly noise and friction, took c ≈ 1: every row where the current and the
    motion share a sign then holds for any current, its noise included)."""
    if ctx.phi is None:
        return
    from .outputs import output_channels, residuals

    outputs = output_channels(ctx.model)
    e = residuals(ctx.model, ctx.phi, ctx.sig)  # y − ŷ, each channel in its own unit
    dq = _motor_rows(ctx, "dq")
    for m, (_, share, kind) in _motor_rows(ctx).items():
        if kind == "torque":
            continue
        i = next(k for k, o in enumerate(outputs) if o.kind == "input" and o.motor == m)
        predicted = _gain(ctx, ctx.phi, m) * (ctx.sig.inputs[m] - e[:, i])  # gain·û_m
        f = np.sign(dq[m][0]) * np.abs(predicted)
        yield Candidate("load_friction", f"motor {m}", {}, _on_rows(f, share), ("coefficient",),
                        lambda th, phi: {"coefficient": float(th[0])}, positive=(0,))  # friction opposes the motion


def pwm_delay(ctx: Context, grid: Sequence[float] = DELAYS_MS) -> Iterable[Candidate]:
    """The PWM stream lags the encoders by d: the drive is gain·u(t + d), one column Σ_m gain_m (u_m(t + d) − u_m(t))
    (gains of the baseline refit, u shifted at the full rate), θ ≈ 1 at the true d, which is searched. Every PWM
    motor shares the one stream clock. (Much of a delay looks like extra inertia and damping through the closed
    loop, u̇ ≈ −D q̈ + K(q̇_ref − q̇): the standard model absorbs that part.)"""
    if ctx.phi is None or ctx.inputs_full is None or ctx.index_full is None:
        return
    pwm = [(m, share) for m, (_, share, kind) in _motor_rows(ctx).items() if kind == "pwm"]
    if not pwm:
        return
    for ms in grid:
        shift = ms * 1e-3 * ctx.rate
        values = np.zeros((ctx.n, ctx.r, 1))
        for m, share in pwm:
            u = ctx.inputs_full[m]
            ahead = np.interp(np.minimum(ctx.index_full + shift, len(u) - 1), np.arange(len(u)), u)
            values += _on_rows(_gain(ctx, ctx.phi, m) * (ahead - u[ctx.index_full]), share)
        yield Candidate("pwm_delay", "pwm stream", {"ms": ms}, values, ("scale",),
                        lambda th, phi, ms=ms: {"ms": ms, "scale": -float(th[0])})


def coupling_error(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """The ratio entries of a coupled group's T (not 0, not ±1) off by a factor (1 + e), all of them or those of
    one joint's column (a joint-side pulley): the joint torques gain e·T_rᵀ τ_m, τ_m = gain ∘ u − motor friction,
    and the rows (b − AΦ) −e·L T_rᵀ τ_m; one column with θ = e (gains and motor friction of the baseline refit).
    Scaling a motor's whole row of T is a change of its gain, which the standard model fits, so on the iCub
    shoulder the all-entries error is invisible; a column's is not (the pitch's is named at 10 %; README "Model
    gaps", known limits)."""
    if ctx.phi is None:
        return
    cfg = ctx.model.config
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        rows = slice(start, start + len(g.joints))
        start += len(g.joints)
        if not (g.coupled and g.motors and g.input != "torque"):
            continue
        Tr = np.where(~np.isclose(np.abs(g.coupling), 1.0) & (g.coupling != 0), g.coupling, 0.0)
        L, _ = group_row_maps(g)
        # the motors' net torque: drive minus their own friction, which reaches the joints through T as well
        cols = [cfg.joints.index(j) for j in g.joints]
        friction = friction_regressor(motor_velocities(ctx.sig.dq[:, cols], g.coupling))  # (N, motors, 4)
        drive = np.column_stack([_gain(ctx, ctx.phi, m) * ctx.sig.inputs[m]
                                 - friction[:, mi] @ ctx.phi[ctx.model.layout.block("motor_friction", m).slice]
                                 for mi, m in enumerate(g.motors)])  # (N, motors)
        places = [(f"group {g.name}", Tr)] + [(f"joint {j}", np.where(np.arange(len(g.joints)) == k, Tr, 0.0))
                                              for k, j in enumerate(g.joints) if Tr[:, k].any()]
        for where, Tw in places:
            values = np.zeros((ctx.n, ctx.r, 1))
            values[:, rows, 0] = -drive @ (L @ Tw.T).T
            yield Candidate("coupling_error", where, {}, values, ("error",), lambda th, phi: {"error": float(th[0])})


def _inertial_rows(ctx: Context, gravity: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(N, r) rigid-body part of every row at rest (q̇ = q̈ = 0) under `gravity`, with the inertias of `phi`."""
    model, cfg = ctx.model, ctx.model.config
    saved = model.pin_model.gravity.copy()
    try:
        model.pin_model.gravity = pin.Motion(np.asarray(gravity, float), np.zeros(3))
        zero = np.zeros_like(ctx.sig.q)
        rb = rigid_body_regressors(model, ctx.sig.q, zero, zero)
    finally:
        model.pin_model.gravity = saved
    inertial = phi[model.layout.span("inertial")]
    out = np.zeros((ctx.n, ctx.r))
    for i, s in enumerate(cfg.ft_sensors):
        out[:, 6 * i : 6 * i + 6] = rb.ft[s.name] @ inertial
    start = 6 * len(cfg.ft_sensors)
    for g in cfg.actuation:
        gj = [cfg.joints.index(j) for j in g.joints]
        L, _ = group_row_maps(g)
        out[:, start : start + len(gj)] = np.einsum("rj,njp,p->nr", L, rb.tau[:, gj], inertial)
        start += len(gj)
    return out


def base_tilt(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """Gravity rotated by a small vector ω: g' ≈ g + ω × g, so the rows gain Σ_k ω_k Y(q; e_k × g) φ (the
    baseline's inertias). The rotation about g itself changes nothing and is dropped. Acts on every row."""
    if ctx.phi is None:
        return
    g = np.asarray(ctx.model.config.gravity, float)
    axes = [k for k in range(3) if np.linalg.norm(np.cross(np.eye(3)[k], g)) > 1e-9 * np.linalg.norm(g)]
    values = np.stack([_inertial_rows(ctx, np.cross(np.eye(3)[k], g), ctx.phi) for k in axes], axis=2)

    def interpret(th: np.ndarray, phi: np.ndarray) -> dict[str, float | str]:
        w = np.zeros(3)
        w[axes] = th
        out: dict[str, float | str] = {"degrees": float(np.rad2deg(np.linalg.norm(w))), "axis": "xyz"[int(np.argmax(np.abs(w)))]}
        out.update({f"deg_{'xyz'[k]}": float(np.rad2deg(w[k])) for k in range(3)})
        return out

    yield Candidate("base_tilt", "base", {}, values, tuple(f"tilt_{'xyz'[k]}" for k in axes), interpret)


def payload(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """A rigid payload on a link: its ten inertial parameters added to the link's (mass, first moment, inertia at
    the link origin), columns = the link's own rigid-body columns. Only against a given model whose inertias
    are held: a refit of the inertias absorbs any payload exactly. Named by its mass and centre of mass."""
    if ctx.inertial_columns is None:
        return
    layout = ctx.model.layout
    base = layout.span("inertial").start
    for body in ctx.model.bodies:
        block = layout.block("inertial", body.name)
        cols = ctx.inertial_columns[:, :, block.start - base : block.stop - base]
        if not np.any(cols):
            continue

        def interpret(th: np.ndarray, phi: np.ndarray) -> dict[str, float]:
            mass = float(th[0])
            c = th[1:4] / mass if mass != 0 else np.zeros(3)
            return {"mass": mass, **{f"com_{a}": float(v) for a, v in zip("xyz", c)}}

        yield Candidate("payload", f"link {body.name}", {}, cols, tuple(block.names), interpret, positive=(0,))


def _trace_free_basis() -> np.ndarray:
    """(36, 35) basis of the 6×6 matrices with zero trace: a common scale of the whole sensor is the scale of every
    inertia and motor gain at once, which the data cannot see, so only the trace-free part of E is estimated."""
    P = np.eye(36)[:, [k for k in range(36) if k % 7 != 0]]  # the 30 off-diagonal entries
    diag = np.zeros((36, 5))
    for k in range(5):  # e_k − mean of the diagonal, k < 5 (the sixth is their negative sum)
        diag[7 * k, k] = 1.0
        diag[np.arange(6) * 7, k] -= 1.0 / 6
    return np.concatenate([P, diag], axis=1)


def ft_gain(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """F/T gain and cross-talk: measured = (I + E) w + o, w the baseline's predicted wrench (not the measured one:
    that is the right-hand side itself); row a gains Σ_b E_ab w_b. E is trace-free (see `_trace_free_basis`)
    unless the inertias are held at a given model's, which fixes the scale: then all 36 entries."""
    if ctx.rigid is None:
        return
    held = ctx.inertial_columns is not None
    P = np.eye(36) if held else _trace_free_basis()
    for i, s in enumerate(ctx.model.config.ft_sensors):
        w = ctx.rigid[:, 6 * i : 6 * i + 6]
        full = np.zeros((ctx.n, ctx.r, 36))
        for a in range(6):
            full[:, 6 * i + a, 6 * a : 6 * a + 6] = w - w.mean(axis=0)
        values = full @ P

        def interpret(th: np.ndarray, phi: np.ndarray) -> dict[str, float | list]:
            E = (P @ th).reshape(6, 6)
            if held:  # the given model's inertias fix the wrench's scale: E is the sensor's own error
                return {"matrix": E.tolist(), "gain_rms": float(np.sqrt(np.mean(np.diag(E) ** 2))),
                        "crosstalk_rms": float(np.sqrt(np.mean(E[~np.eye(6, dtype=bool)] ** 2)))}
            # Not printed as gains: arm motion cannot separate E from the inertias beyond the sensor (README).
            return {"matrix": E.tolist(),
                    "note": "E (trace-free, --json) corrects the wrench; its entries are not identifiable one by one"}

        yield Candidate("ft_gain", f"sensor {s.name}", {}, values, tuple(f"E{k}" for k in range(P.shape[1])), interpret)

LIMIT_TOLERANCE = np.deg2rad(1.0)  # a joint within this of its URDF limit sits at the limit
LIMIT_MIN_SHARE = 0.02  # ... on at least this share of the samples, else it is no candidate


def limit_step(ctx: Context, grid: Sequence[float] = ()) -> Iterable[Candidate]:
    """A constant wrench on an F/T sensor while a joint sits at one of its URDF position limits.

    The rigid-body model cannot make one: a hard stop's force is internal to the sensor's distal subtree. A real
    sensor shows one all the same when something else loads it at the limit (a cable or a hose pulled taut,
    a cover touching): the iCub leg's hip sensor moves by about 25 N while the ankle rests at its 30° stop. The
    effect names the joint and the limit (in degrees, the searched value: `grid` rebuilds the given limits on a
    run where the joint may never reach them).
    """
    cfg = ctx.model.config
    q = ctx.sig.q
    for k, joint in enumerate(cfg.joints):
        for limit in ctx.model.joint_limits[joint]:
            if not np.isfinite(limit) or abs(limit) > 1e3:  # continuous joints: no limit
                continue
            limit_deg = float(np.round(np.rad2deg(limit), 6))
            at = np.abs(q[:, k] - limit) <= LIMIT_TOLERANCE
            if grid:
                if not any(abs(limit_deg - g) < 1e-6 for g in grid):
                    continue
            elif at.mean() < LIMIT_MIN_SHARE or at.all():
                continue
            for i, s in enumerate(cfg.ft_sensors):
                values = np.zeros((ctx.n, ctx.r, 6))
                for c in range(6):
                    values[:, 6 * i + c, c] = at
                labels = tuple(f"d{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz"))

                def interpret(th: np.ndarray, phi: np.ndarray, joint=joint, limit_deg=limit_deg) -> dict[str, float | str]:
                    out: dict[str, float | str] = {"joint": joint, "limit_deg": limit_deg}
                    out.update({label: float(v) for label, v in zip(labels, th)})
                    out["force"] = float(np.linalg.norm(th[:3]))
                    out["torque"] = float(np.linalg.norm(th[3:]))
                    return out

                yield Candidate("limit_step", f"sensor {s.name}", {"joint": joint, "limit_deg": limit_deg}, values,
                                labels, interpret)


LIBRARY: dict[str, Callable[..., Iterable[Candidate]]] = {
    "stribeck": stribeck,
    "spring": spring,
    "cogging": cogging,
    "pwm_deadzone": pwm_deadzone,
    "ft_drift": ft_drift,
    "armature": armature,
    "load_friction": load_friction,
    "pwm_delay": pwm_delay,
    "coupling_error": coupling_error,
    "base_tilt": base_tilt,
    "ft_gain": ft_gain,
    "payload": payload,
    "limit_step": limit_step,
}

SEARCHED = {"stribeck": "velocity", "cogging": "period_deg", "ft_drift": "tau", "pwm_delay": "ms"}


def refined(ctx: Context, best: Candidate) -> list[Candidate]:
    """Candidates of the same effect and place on a fine grid around the best searched value."""
    key = SEARCHED.get(best.kind)
    if key is None or key not in best.nonlinear:
        return []
    value = float(best.nonlinear[key])
    return [c for c in LIBRARY[best.kind](ctx, tuple(float(v) for v in value * (1 + REFINE))) if c.where == best.where]


# Effects the library names only against a given model (`dynid gaps --model`): without one, reported as not
# ruled out. A payload is a change of one link's inertial parameters, which a refit of the inertias absorbs.
NEEDS_GIVEN_MODEL = ("payload",)
