"""`dynid gaps`: where the model and the data disagree, which missing effect explains it, and the gap after.

1. Signals of the run (the fit's own derivative filter), decimated to at most `max_samples` samples, split into
   contiguous time blocks; rows weighted by 1/σ, rows at rest dropped (as the fit does).
2. Baseline: the standard model (inertia, F/T offsets, Coulomb + viscous friction, gains) refitted on the run.
   Against a given model (`--model`) its inertias are held and the rest is refitted: offsets, friction and
   gains drift from day to day, the bodies do not, and a payload shows only against known bodies.
   Per channel: held-out RMS against the noise floor, and where it grows (speed regime, time).
3. Forward selection over the candidate library (dynid.robot.effect_library) by cross-validated reduction of the
   held-out error of the channels each candidate acts on; stop when the best one is not significant.
4. Refit with the named effects; held-out RMS per channel after.
With supply tracking (the default) steps 2–4 run twice; the second pass sees the inputs corrected by the supply
ratio estimated from the first pass's residual (`run`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..errors import DataError
from ..identify.fit import FitSettings, SignalSource
from ..identify.supply import SupplyTracking, smoothed_ratios
from ..margins import above, borderline, borderline_log
from ..io.dataset import Dataset
from ..robot.effect_library import LIBRARY, NEEDS_GIVEN_MODEL, Candidate, Context, refined
from ..robot.effects import UNITS
from ..robot.model import RobotModel
from ..robot.outputs import divisors, output_channels
from ..robot.regressors.stack import Signals, fill_rows, row_channels
from .episodes import format_episode, residual_episodes
from .profile import profile
from .refit import reference_phi, refit
from .selection import (WORSE_TOLERANCE, Design, Trial, batched, evaluate, robust_p_value, weighted_columns,
                        worse_channels)
from .steps import (FT_STEP, cad_offsets_with_steps, declared_candidates, describe, format_levels, format_step,
                    found_candidates, limit_events, offset_levels, prune)

MAX_SAMPLES = 6000  # decimated samples kept: the filtered signals are smooth, and selection stays seconds
N_BLOCKS = 5
MIN_GAIN = 0.20  # relative held-out SSE reduction on the channels an effect acts on
ALPHA = 0.01  # family-wise level of the robust Wald test, Bonferroni over the candidates of a round
BATCH_S = 2.0  # s per batch of the robust test: about one reaching motion; control runs' score variance stops growing there
MIN_BATCHES = 10
MAX_EFFECTS = 4
WORSE_THAN_GIVEN = 1.2  # the refit's error over the given model's own, beyond which the refit is said to be worse
CONFIDENT = 0.6  # share of its channels' excess over FLOOR a named effect must remove to be trusted
# A later effect on channels an earlier one already explained, removing less than this share of what the earlier one
# removed, is tentative: its gain is most likely the earlier effect's shape not fitting exactly (measured: after a
# 3× Coulomb elbow Stribeck, an armature of 0.004 kg m² takes 0.7 % of what the Stribeck took, near the stops).
SECONDARY = 0.1
# The held-out RMS (× noise) below which a channel counts as explained: what the standard model leaves on a plant
# with no hidden effect (measured: the shoulder pitch's pwm.m0 at 1.37× with supply tracking; pwm.m0/m1 at
# 1.8–2.4× with constant gains, from the supply's variation and stiction).
FLOOR = 1.5
FLOOR_CONSTANT_GAINS = 2.0
CHUNK = 20_000


@dataclass(frozen=True)
class Settings:
    max_samples: int = MAX_SAMPLES
    n_blocks: int = N_BLOCKS
    min_gain: float = MIN_GAIN
    alpha: float = ALPHA
    max_effects: int = MAX_EFFECTS
    supply: SupplyTracking | None = SupplyTracking()  # None: constant gains (one pass)
    keep_tentative: bool = False  # write tentative effects into the augmented model too (named ones always are)
    # Declared change points of the F/T offsets (the data's own seconds): steps taken as known, not searched
    # (`--steps`, the configuration's `ft_steps`; dynid.gaps.steps)
    steps: tuple[float, ...] = ()


MIN_SAMPLES = 2000


def _collect(model: RobotModel, ds: Dataset, stride: int) -> tuple[Context, np.ndarray, np.ndarray, np.ndarray]:
    """(context, A (N, r, p) unweighted, b (N, r), weights (N, r)) of every `stride`-th sample."""
    source = SignalSource(model, ds, FitSettings(), instruments=False)
    sigs, As, bs, ws, ts, dus = [], [], [], [], [], []
    for lo in range(0, ds.n_samples, CHUNK):
        sig, _, w = source(lo, min(lo + CHUNK, ds.n_samples))
        keep = slice((-lo) % stride, None, stride)  # global sample indices that are multiples of stride
        dus.append(sig.inputs)  # the filtered inputs at the full rate: a delay candidate shifts them by whole samples
        sig, w = sig.slice(keep), w[keep]
        A, b = _rows(model, sig)
        sigs.append(sig), As.append(A), bs.append(b), ws.append(w), ts.append(ds.t[lo:min(lo + CHUNK, ds.n_samples)][keep])
    sig = Signals(
        np.vstack([s.q for s in sigs]), np.vstack([s.dq for s in sigs]), np.vstack([s.ddq for s in sigs]),
        {k: np.concatenate([s.inputs[k] for s in sigs]) for k in sigs[0].inputs},
        {k: np.concatenate([s.tau[k] for s in sigs]) for k in sigs[0].tau},
        {k: np.vstack([s.ft[k] for s in sigs]) for k in sigs[0].ft},
        None,  # a payload's known torques are already in b (_rows, per chunk)
        None if sigs[0].gravity is None else np.vstack([s.gravity for s in sigs]),
    )
    t = np.concatenate(ts)
    full = {k: np.concatenate([d[k] for d in dus]) for k in dus[0]}
    index = np.arange(0, ds.n_samples, stride)
    rate = (ds.n_samples - 1) / max(float(ds.t[-1] - ds.t[0]), 1e-12)
    ctx = Context(model, sig, t - ds.t[0], inputs_full=full, index_full=index, rate=rate, t0=float(ds.t[0]))
    return ctx, np.concatenate(As), np.concatenate(bs), np.concatenate(ws)


def _rms_per_channel(sse: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """RMS in noise units (weighted rows): 1.0 is the noise floor."""
    return np.sqrt(sse / np.maximum(rows, 1))


def _where(model: RobotModel, ctx: Context, resid: np.ndarray, weights: np.ndarray) -> list[dict]:
    """Where each channel's residual (noise units) grows: by speed regime of its joints, and over time."""
    out = []
    speed = np.abs(ctx.sig.dq).max(axis=1)
    regimes = {"slow (<0.05 rad/s)": speed < 0.05, "medium": (speed >= 0.05) & (speed < 0.5), "fast (≥0.5 rad/s)": speed >= 0.5}
    thirds = np.array_split(np.arange(ctx.n), 3)
    for c, ch in enumerate(output_channels(model)):
        live = weights[:, c] > 0
        row: dict = {"channel": ch.name, "by_speed": {}, "by_time": []}
        for name, mask in regimes.items():
            m = mask & live
            row["by_speed"][name] = float(np.sqrt(np.mean(resid[m, c] ** 2))) if m.any() else None
        for idx in thirds:
            m = live[idx]
            row["by_time"].append(float(np.sqrt(np.mean(resid[idx][m, c] ** 2))) if m.any() else None)
        out.append(row)
    return out


def _supply_corrected(model: RobotModel, ctx: Context, resid: np.ndarray, w: np.ndarray, phi: np.ndarray,
                      tracking: SupplyTracking) -> tuple[Context, np.ndarray]:
    """(the context with each motor's input u replaced by u / r, at the decimated and the full rate alike, r its
    two-sided supply ratio estimated from `resid` (weighted rows, what a first pass left); (N, n_out) r). The drive
    torque is gain·s(t)·u and r = 1/s (dynid.identify.supply), so u / r is the input a constant-gain model should see."""
    e_rows = np.divide(resid, w, out=np.zeros_like(resid), where=w > 0)
    e_out = e_rows / divisors(model, phi)
    ratio = smoothed_ratios(model, tracking, FitSettings().min_speed, e_out, ctx.sig, ctx.t)
    inputs, full = dict(ctx.sig.inputs), dict(ctx.inputs_full or {})
    for o in output_channels(model):
        if o.kind == "input":
            inputs[o.motor] = inputs[o.motor] / ratio[:, o.row]
            if o.motor in full and ctx.index_full is not None:  # the delay candidate's full-rate inputs
                at = np.arange(len(full[o.motor]))
                full[o.motor] = full[o.motor] / np.interp(at, ctx.index_full, ratio[:, o.row])
    return replace(ctx, sig=replace(ctx.sig, inputs=inputs), inputs_full=full or None), ratio


def _rows(model: RobotModel, sig: Signals) -> tuple[np.ndarray, np.ndarray]:
    n, r = sig.q.shape[0], len(row_channels(model))
    A, b = np.zeros((n, r, len(model.layout))), np.zeros((n, r))
    fill_rows(model, sig, A, b)
    return A, b


def run(model: RobotModel, ds: Dataset, settings: Settings = Settings(), reference: tuple[str, np.ndarray] | None = None,
        log=print) -> dict:
    """The whole workflow on one run; `reference` = (label, Φ) of a given model, whose gap on the run is shown too.

    With supply tracking (the default, as `dynid fit` has it), it runs twice: the first pass's residual, after its
    named effects, gives each motor's supply ratio (dynid.identify.supply, two-sided), and the second pass (whose result
    this is) analyses the run with the inputs corrected by it. The ratio is estimated after the effects, so a
    named effect is not learned as supply variation; a sample whose residual is past the gate never updates it."""
    started = time.perf_counter()
    if ds.n_samples < MIN_SAMPLES:
        rate = (ds.n_samples - 1) / ds.duration if ds.duration > 0 else float("nan")
        raise DataError(f"the run has {ds.n_samples} samples; the gap analysis needs at least {MIN_SAMPLES} "
                        f"({MIN_SAMPLES / rate:.3g} s at this run's {rate:.4g} Hz): held-out blocks of fewer hold "
                        "too little to compare")
    stride = max(1, int(np.ceil(ds.n_samples / settings.max_samples)))
    if not any(o.kind == "input" for o in output_channels(model)):  # torque-sensed joints only: no supply to track
        settings = replace(settings, supply=None)
    ctx, A, b, w = _collect(model, ds, stride)
    kept = "every sample" if stride == 1 else f"one sample in {stride}"
    log(f"gaps: {ds.n_samples} samples ({ds.duration:.0f} s), {kept} kept, {settings.n_blocks} held-out time blocks"
        + (", inertias held at the given model's" if reference is not None else "")
        + (", two passes (supply tracking)" if settings.supply is not None else ""))
    if settings.steps:  # a declared point outside the window changes nothing here: say so
        outside = [p for p in settings.steps if not ds.t[0] < p < ds.t[-1]]
        log(f"gaps: declared F/T change points {', '.join(f'{p:g}' for p in settings.steps)} s"
            + (f"; outside the data ({ds.t[0]:.6g}–{ds.t[-1]:.6g} s): {', '.join(f'{p:g}' for p in outside)} s"
               if outside else ""))
    result = _analyse(model, ctx, A, b, w, settings, reference)
    if settings.supply is not None:
        first = result
        ctx, ratio = _supply_corrected(model, ctx, first.pop("_residual"), w, first["_augmented"]["phi"], settings.supply)
        result = _analyse(model, ctx, *_rows(model, ctx.sig), w, settings, reference)
        inputs = [o for o in output_channels(model) if o.kind == "input"]
        result["supply"] = {
            **settings.supply.as_dict(),
            "ratio_range": {o.name: [float(ratio[:, o.row].min()), float(ratio[:, o.row].max())] for o in inputs},
            "first_pass": {"effects": [f"{e['name']} on {e['where']}" for e in first["effects"]],
                           "after_over_noise": {g["channel"]: g["after_over_noise"] for g in first["gap"]}},
        }
    else:
        result["supply"] = None
    result.pop("_residual")
    result["samples"], result["kept_every"] = ds.n_samples, stride
    for ep in result["episodes"]:  # the data's own seconds, as --from/--to take them
        ep["from_s"] += float(ds.t[0])
        ep["to_s"] += float(ds.t[0])
    result["t0_s"] = float(ds.t[0])  # the profile's time edges start from it
    result["declared_steps"] = list(settings.steps)
    result["seconds"] = time.perf_counter() - started
    return result


def _analyse(model: RobotModel, ctx: Context, A: np.ndarray, b: np.ndarray, w: np.ndarray, settings: Settings,
             reference: tuple[str, np.ndarray] | None) -> dict:
    """Baseline, selection and refit on the collected rows (`run`'s steps 2–4)."""
    n, r, p = A.shape
    inertial = model.layout.span("inertial")
    held = np.zeros(p)  # Φ held at the given model's: its inertias (none without a given model)
    if reference is not None:
        held[inertial] = reference[1][inertial]
        ctx = replace(ctx, inertial_columns=A[:, :, inertial])
    Aw, y = A * w[:, :, None], (b - A @ held) * w
    if reference is not None:
        Aw[:, :, inertial] = 0.0  # held columns: V gets no component along them
    # Identifiable subspace of the standard model on this run: Z = A V (columns the data cannot see dropped).
    flat = Aw.reshape(-1, Aw.shape[2])
    G = flat.T @ flat
    s, V = np.linalg.eigh(G)
    V = V[:, s > 1e-10 * s.max()]
    bounds = np.linspace(0, n, settings.n_blocks + 1).astype(int)
    design = Design(Aw @ V, y, bounds)
    dof = V.shape[1]
    channels = output_channels(model)

    base_cv = design.cv_sse(None)
    x0, sse0 = design.fit(None)
    before = _rms_per_channel(base_cv.sum(axis=0), design.rows.sum(axis=0))
    resid0 = y - design.D @ x0
    given = None
    if reference is not None:  # not fitted on this run: its error over all rows is already out of sample
        e = y - Aw @ reference[1]  # = (b − AΦ_ref)·w: the held part of Φ_ref is already in y
        given = _rms_per_channel((e**2).sum(axis=0), design.rows.sum(axis=0))

    # Bilinear candidates (gains, gravity, F/T gain) linearise about the baseline refit.
    phi0 = held + V @ x0
    ctx = replace(ctx, phi=phi0, rigid=A[:, :, inertial] @ phi0[inertial])
    candidates: list[Candidate] = [c for make in LIBRARY.values() for c in make(ctx)]
    # F/T offset steps: at the declared change points (taken as known, below), else between those ruptures finds
    declared = declared_candidates(ctx, settings.steps) if settings.steps else []
    candidates += [] if settings.steps else found_candidates(ctx, resid0)[0]
    named: list[dict] = []
    tried: list[Trial] = []
    on_edge: list[dict] = []  # decisions whose statistic sat on its threshold's band (dynid.margins)
    not_significant: dict | None = None  # the round's best by held-out gain, when the robust test rejected it
    accepted_E: list[np.ndarray] = []
    accepted: list[Candidate] = []
    current = design
    cur_cv = base_cv
    taken: set[str] = set()
    duration = float(ctx.t[-1] - ctx.t[0]) if ctx.n > 1 else 0.0
    batch = max(1, min(int(round(BATCH_S * n / max(duration, 1e-9))), n // MIN_BATCHES))  # samples per batch (target)
    # Each named effect keeps the held-out SSE per block and channel before and after its own round: what a step's
    # `held_out` reports is its own change, not that of every effect named after it on the same channels.
    for c in declared:  # known steps: in the fix whatever their held-out gain (it is reported)
        Ew = weighted_columns(c.values, w)
        tr = replace(evaluate(current, c, w, cur_cv), p_value=robust_p_value(current, Ew, batch))
        accepted_E.append(Ew)
        accepted.append(c)
        taken.add(_key(c))
        current = Design(np.concatenate([design.D] + accepted_E, axis=2), y, bounds)
        named.append({"trial": tr, "cv_before": cur_cv})
        cur_cv = named[-1]["cv_after"] = current.cv_sse(None)
    declared_cv = cur_cv  # what a found effect is judged against when it makes a channel worse
    for _ in range(settings.max_effects):
        trials = [prune(current, c, w, cur_cv, E) if c.kind == FT_STEP else evaluate(current, c, w, cur_cv, E)
                  for c, E in batched(current, [c for c in candidates if _key(c) not in taken], w)]
        if not trials:
            break
        best = max(trials, key=lambda tr: tr.gain)
        fine = [evaluate(current, c, w, cur_cv, E) for c, E in batched(current, refined(ctx, best.candidate), w)]
        best = max([best, *fine], key=lambda tr: tr.gain)
        # best per effect/place, for the report of what was ruled out
        tried = trials
        reaches, near = above(best.gain, settings.min_gain)
        if near:
            on_edge.append(_edge("min_cv_gain", best.candidate.key, best.gain, settings.min_gain, "not named"))
        if not reaches:
            break
        c = best.candidate
        Ew = weighted_columns(c.values, w)
        best = replace(best, p_value=robust_p_value(current, Ew, batch))
        level = settings.alpha / len(trials)
        if borderline_log(best.p_value, level):
            on_edge.append(_edge("alpha", c.key, best.p_value, level, "not significant"))
        if best.p_value > level or borderline_log(best.p_value, level):
            not_significant = {"effect": c.key, "search": dict(c.nonlinear), "cv_gain": best.gain,
                               "p_value": best.p_value, "level": level}
            break
        accepted_E.append(Ew)
        accepted.append(c)
        taken.add(_key(c))
        current = Design(np.concatenate([design.D] + accepted_E, axis=2), y, bounds)
        named.append({"trial": best, "cv_before": cur_cv})
        cur_cv = named[-1]["cv_after"] = current.cv_sse(None)

    # The fix is never accepted when it makes a channel worse on held-out blocks: the last-named effects are
    # dropped until no channel is (a greedy round may hurt a channel that a later effect repairs, so this is
    # judged on the whole fix, not per round).
    refused: list[dict] = []
    while len(accepted) > len(declared):  # declared steps are kept: the user knows them
        worse = worse_channels(declared_cv, cur_cv, current.rows)
        if not worse:
            break
        c, item = accepted.pop(), named.pop()
        accepted_E.pop()
        refused.append({"effect": c.key, "search": dict(c.nonlinear), "cv_gain": item["trial"].gain,
                        "worse": {channels[k].name: rel for k, rel, _ in worse}})
        on_edge += [_edge("worse_channel", f"{c.key}: {channels[k].name}", rel, WORSE_TOLERANCE, "refused")
                    for k, rel, near in worse if near]
        current = Design(np.concatenate([design.D] + accepted_E, axis=2), y, bounds) if accepted_E else design
        cur_cv = current.cv_sse(None)

    # Final refit with every named effect; coefficients in row units (the columns were weighted like the rows).
    # Φ outside the run's identifiable subspace keeps the given model's (or CAD) values (dynid.gaps.refit).
    resid_after = y - current.D @ current.fit(None)[0]
    phi, fitted = refit(current, V, accepted, ctx, reference_phi(model, reference[1] if reference else None))
    explained_floor = FLOOR if settings.supply is not None else FLOOR_CONSTANT_GAINS
    effects: list[dict] = []
    removed: list[tuple[set[int], float, str]] = []  # (channels, held-out SSE removed, name) of each effect so far
    for i, (f, c, item) in enumerate(zip(fitted, accepted, named)):
        tr: Trial = item["trial"]
        took = tr.cv_before - tr.cv_after
        primary = None
        for chans, r0, name in removed:  # on the band: secondary (tentative), the conservative answer
            if chans & set(tr.channels.tolist()) and (took < SECONDARY * r0 or borderline(took, SECONDARY * r0)):
                primary = name
                if borderline(took, SECONDARY * r0):
                    on_edge.append(_edge("secondary", f"{f.kind} on {f.where}", took / r0, SECONDARY, "tentative"))
                break
        removed.append((set(tr.channels.tolist()), took, f"{f.kind} on {f.where}"))
        # An effect of the wrong shape also lowers a large residual by a fair share (a Stribeck curve on a quadratic
        # drag): it is trusted only when it removes most of its channels' excess over FLOOR.
        floor = explained_floor**2 * current.rows[:, tr.channels].sum()
        excess_before = max(float(base_cv[:, tr.channels].sum() - floor), 1e-12)
        explained = 1.0 - max(float(cur_cv[:, tr.channels].sum() - floor), 0.0) / excess_before
        enough, near = above(explained, CONFIDENT)
        if near:
            on_edge.append(_edge("confident", f"{f.kind} on {f.where}", explained, CONFIDENT, "tentative"))
        effects.append({"name": f.kind, "where": f.where, "parameters": f.parameters,
                        "units": {k: UNITS.get(k, "") for k in f.parameters},
                        "standard_errors": f.standard_errors, "search": dict(c.nonlinear), "cv_gain": tr.gain,
                        "p_value": tr.p_value, "explained": explained, "secondary_to": primary,
                        "confident": i < len(declared) or (enough and primary is None), "declared": i < len(declared)})
    # The augmented model holds what was named: a tentative effect is reported, but it enters the model file only
    # when asked (--keep-tentative), refitted without it otherwise (its columns would have taken part of the fit).
    kept = [i for i, e in enumerate(effects) if e["confident"] or settings.keep_tentative]
    if len(kept) < len(accepted):
        named_E = [accepted_E[i] for i in kept]
        current = Design(np.concatenate([design.D] + named_E, axis=2), y, bounds) if named_E else design
        phi, fitted = refit(current, V, [accepted[i] for i in kept], ctx,
                            reference_phi(model, reference[1] if reference else None))
        for i, f in zip(kept, fitted):  # what is reported of a named effect is what the model file holds
            effects[i].update(parameters=f.parameters, standard_errors=f.standard_errors)
        # the gap after (its table, where it stays, the second pass's supply estimate): the model file's
        cur_cv = current.cv_sse(None)
        resid_after = y - current.D @ current.fit(None)[0]
    after = _rms_per_channel(cur_cv.sum(axis=0), current.rows.sum(axis=0))
    for i, e in enumerate(effects):
        e["in_model"] = i in kept
    events = limit_events(ctx) if any(e["name"] == FT_STEP for e in effects) else []
    for e, item in zip(effects, named):  # a step: its change points with the limit events there, its channels' gaps
        if e["name"] == FT_STEP:  # before and after its own round
            chans = item["trial"].channels
            rows = current.rows[:, chans].sum(axis=0)
            held = _rms_per_channel(item["cv_before"][:, chans].sum(axis=0), rows)
            now = _rms_per_channel(item["cv_after"][:, chans].sum(axis=0), rows)
            e.update(describe(e, events, {channels[k].name: (float(b), float(a)) for k, b, a in zip(chans, held, now)}))

    best_by_key: dict[str, Trial] = {}
    for tr in tried:
        k = tr.candidate.key
        if k not in best_by_key or tr.gain > best_by_key[k].gain:
            best_by_key[k] = tr
    taken = {item["trial"].candidate.key for item in named}  # named above: not ruled out
    ruled_out = sorted(({"effect": k, "cv_gain": v.gain} for k, v in best_by_key.items() if k not in taken),
                       key=lambda d: -d["cv_gain"])
    return {
        "blocks": settings.n_blocks, "rank": dof,
        "thresholds": {"min_cv_gain": settings.min_gain, "alpha": settings.alpha, "batch_samples": batch,
                       "explained_floor": explained_floor, "confident": CONFIDENT, "secondary": SECONDARY,
                       "test": "Wald, batch-means covariance; alpha family-wise over a round's candidates"},
        "effects": effects,
        "gap": [{"channel": ch.name, "unit": ch.unit, "sigma": ch.sigma,
                 "before_rms": float(bf * ch.sigma), "after_rms": float(af * ch.sigma),
                 "before_over_noise": float(bf), "after_over_noise": float(af),
                 **({"given_model_rms": float(gv * ch.sigma), "given_model_over_noise": float(gv)} if given is not None else {})}
                for ch, bf, af, gv in zip(channels, before, after, given if given is not None else before)],
        "given_model": reference[0] if reference is not None else None,
        "where": _where(model, ctx, resid0, w),
        "ft_steps": offset_levels(effects),  # the named F/T steps of each sensor, summed into one offset per segment
        # when and where the residual left after the fix steps (what the library could not name)
        "episodes": residual_episodes(model, ctx.t, ctx.sig.q, resid_after, np.asarray(after)),
        "profile": profile(model, ctx, resid0, resid_after, w),  # binned, before/after: what the figures plot
        "ruled_out": ruled_out[:12],
        "not_significant": not_significant,
        "refused": refused,  # effects dropped because the fix with them made a channel worse on held-out blocks
        "borderline": on_edge,
        "not_tried": [] if reference is not None else list(NEEDS_GIVEN_MODEL),  # effects that need a given model
        "_residual": resid_after,  # weighted rows after the named effects: the supply estimate of a second pass
        # the augmented model (`dynid gaps --out`): not part of the --json result (see cli_gaps)
        "_augmented": {"phi": phi, "effects": fitted,
                       "cad_ft_offsets": cad_offsets_with_steps(ctx, A, b, w, fitted)},
    }


def _key(c: Candidate) -> str:
    """What selection takes once: an effect at a place (a step: at its times too, a sensor may step twice)."""
    return c.key + (f" {c.nonlinear['from_s']}-{c.nonlinear['to_s']}" if c.kind == FT_STEP else "")


def _edge(decision: str, subject: str, value: float, threshold: float, taken: str) -> dict:
    return {"decision": decision, "subject": subject, "value": float(value), "threshold": float(threshold),
            "taken_as": taken}


def worse_than_given(result: dict) -> list[dict]:
    """The channels whose error after the fix exceeds the given model's own by more than a fifth, above the noise:
    where the refit on DATA (and the augmented model written from it) is worse than the model given."""
    return [g for g in result["gap"] if "given_model_over_noise" in g and g["after_over_noise"] > 1.0
            and g["after_over_noise"] > WORSE_THAN_GIVEN * g["given_model_over_noise"]]


def format_report(result: dict) -> str:
    lines = []
    if result["effects"]:
        for e in result["effects"]:
            units = e.get("units", {})
            params = ", ".join((f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}")
                               + (f" {units[k]}" if units.get(k) else "")
                               for k, v in e["parameters"].items() if not isinstance(v, list))  # matrices: --json only
            lead = "declared" if e.get("declared") else "named" if e["confident"] else "tentative"
            lines.append(f"{lead}: {e['name']} on {e['where']}: {params} "
                         f"(held-out error on its channels {'−' if e['cv_gain'] >= 0 else '+'}{abs(100 * e['cv_gain']):.1f} %, "
                         f"robust p={e['p_value']:.1e})")
            if e["name"] == FT_STEP:
                lines.append(format_step(e))
            if e.get("secondary_to"):
                lines.append(f"  it removes under {100 * SECONDARY:.0f} % of what {e['secondary_to']} removed on the same "
                             "channels: likely that effect's shape not fitting exactly, not an effect of its own")
            elif not e["confident"]:
                floor = result["thresholds"]["explained_floor"]
                lines.append(f"  it removes only {100 * e['explained']:.0f} % of its channels' excess over {floor:g}× noise: "
                             "the residual's shape is not this effect's; likely an effect outside the library")
    else:
        best = result["ruled_out"][0] if result["ruled_out"] else None
        weak = result.get("not_significant")
        if result.get("refused"):
            extra = "; what the selection found made a channel worse on held-out blocks (refused, below)"
        elif weak is not None:
            extra = (f"; best candidate {weak['effect']} lowers the held-out error {100 * weak['cv_gain']:.1f} %, but not "
                     f"consistently over the run (robust p={weak['p_value']:.3g} > {weak['level']:.3g})")
        else:
            extra = f"; best candidate {best['effect']} lowers the held-out error only {100 * best['cv_gain']:.1f} %" if best else ""
        lines.append("named: nothing — no effect in the library explains a significant part of the residual" + extra)
    for e in result.get("effects", []):
        if not e.get("in_model", True):
            lines.append(f"left out of the augmented model: {e['name']} on {e['where']} (tentative; "
                         "--keep-tentative writes it)")
    lines += format_levels(result.get("ft_steps", {}))
    for edge in result.get("borderline", []):
        lines.append(f"borderline: {edge['decision']} of {edge['subject']}: {edge['value']:.6g} against "
                     f"{edge['threshold']:.6g}, taken as {edge['taken_as']} (on the threshold: another CPU's rounding "
                     "could answer otherwise)")
    for refused in result.get("refused", []):
        worse = ", ".join(f"{ch} +{100 * rel:.0f} %" for ch, rel in refused["worse"].items())
        lines.append(f"refused: {refused['effect']} (held-out error on its channels −{100 * refused['cv_gain']:.1f} %): "
                     f"the fix with it makes {worse} worse on held-out blocks")
    # With a given model, a channel its own error keeps within the floor is not unexplained: the refit is worse there
    high = sorted((g for g in result["gap"] if g["after_over_noise"] > 1.3
                   and g.get("given_model_over_noise", np.inf) > 1.3), key=lambda g: -g["after_over_noise"])
    worse = worse_than_given(result)
    if worse:
        lines.append("the refit is worse than the given model on " + ", ".join(
            f"{g['channel']} ({g['after_over_noise']:.2f}× against its {g['given_model_over_noise']:.2f}×)" for g in worse)
            + ": this run does not hold enough to refit what the given model holds there (its friction, offsets or "
              "gains); the given model is the better baseline on those channels")
    if high:
        listed = ", ".join(f"{g['channel']} {g['after_over_noise']:.2f}×" for g in high)
        untried = result["not_tried"] and f"; not tried without a given model (--model): {', '.join(result['not_tried'])}"
        lines.append(f"unexplained: {listed} its noise floor after the fix{untried or ''}")
    for ep in result.get("episodes", []):
        lines.append("  " + format_episode(ep))
    given = result.get("given_model")
    outside = result.get("outside_given_fit")
    if outside:
        lines.append("the given model's inertias were fitted on other postures; this run takes "
                     + "; ".join(f"{o['joint']} to {o['here_from_deg']:.1f}…{o['here_to_deg']:.1f}° against "
                                 f"{o['fit_from_deg']:.1f}…{o['fit_to_deg']:.1f}° in its fit "
                                 f"({100 * o['outside_share']:.0f} % of samples outside)" for o in outside[:4])
                     + (f"; {len(outside) - 4} more joints (--json)" if len(outside) > 4 else "")
                     + ": its gap there includes its extrapolation")
    head = f"{'given':>10s} " if given else ""
    lines.append(f"{'channel':24s} {head}{'before':>10s} {'after':>10s}  {'(× noise)':>18s}")
    for g in result["gap"]:
        cell = f"{g['given_model_rms']:10.4g} " if given else ""
        lines.append(f"{g['channel']:24s} {cell}{g['before_rms']:10.4g} {g['after_rms']:10.4g}  "
                     f"{g['before_over_noise']:8.2f} → {g['after_over_noise']:6.2f}  {g['unit']}")
    if given:
        lines.append(f"given: {given} on these data; before: the standard model refitted on them; after: with the named effects")
    lines.append(f"({result['seconds']:.1f} s; RMS on held-out time blocks)")
    return "\n".join(lines)
