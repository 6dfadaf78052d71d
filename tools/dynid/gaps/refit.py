"""The refit with the named effects, as an augmented model: full Φ, each effect's parameters with block-jackknife
standard errors, and the model file `dynid gaps --out` writes (dynid.identify.model_file, dynid.robot.effects)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..identify.fit import FitSettings
from ..identify.model_file import IdentifiedModel, robot_record
from ..identify.model_sections import ALPHA, GapsSection
from ..identify.regression import jackknife_se
from ..io.dataset import Dataset
from ..pipeline import DetectorSettings, build_model
from ..robot.effect_library import Candidate, Context
from ..robot.effects import Effect
from ..robot.model import RobotModel
from ..robot.regressors.stack import DEFAULT_MIN_SPEED
from .selection import Design


def reference_phi(model: RobotModel, given: np.ndarray | None) -> np.ndarray:
    """What fills the directions the run cannot see: the given model's Φ, else CAD inertia and zeros."""
    return np.asarray(given, float) if given is not None else np.nan_to_num(model.cad_parameters(), nan=0.0)


def refit(current: Design, V: np.ndarray, accepted: list[Candidate], ctx: Context,
          phi_ref: np.ndarray) -> tuple[np.ndarray, list[Effect]]:
    """(Φ, effects) of the final fit. Φ = Φ_ref outside the identifiable subspace V, the fit inside it (V has no
    component along held parameters, which keep Φ_ref's). A payload's ten parameters are added to its link's
    inertial parameters in Φ: the augmented model is then a standard one for it (the monitor needs nothing new).
    Standard errors: block jackknife (the rows are correlated within a block, not across blocks); none for an
    effect that a fold cannot determine (Design.fold_blind: a short F/T step inside one block, two steps that differ
    only in one block), whose replicate there is the solver's choice, not an estimate."""
    dof = V.shape[1]
    x = current.fit(None)[0]  # the selection's own solve (same column scaling, same cut)
    folds = current.fold_fits()
    blind = current.fold_blind()
    layout = ctx.model.layout

    def full(xx: np.ndarray) -> np.ndarray:
        phi = phi_ref - V @ (V.T @ phi_ref) + V @ xx[:dof]
        start = dof
        for c in accepted:
            k = c.values.shape[2]
            if c.kind == "payload":
                block = layout.block("inertial", c.where.partition(" ")[2])
                phi[block.start : block.stop] += xx[start : start + k]
            start += k
        return phi

    phi = full(x)
    effects, start = [], dof
    for c in accepted:
        k = c.values.shape[2]
        th = x[start : start + k]
        params = dict(c.interpret(th, phi))
        jack = [c.interpret(xb[start : start + k], full(xb)) for xb in folds]
        undetermined: set[str] = set()  # the parameters that move with a coordinate some fold cannot determine
        if blind[start : start + k].any():
            moved = th.copy()
            moved[blind[start : start + k]] += 1.0 + np.abs(moved[blind[start : start + k]])
            alt = c.interpret(moved, phi)
            undetermined = {n for n, v in params.items() if isinstance(v, (int, float)) and alt.get(n) != v}
        se: dict[str, float | None] = {}
        for name in params:
            if (name in c.nonlinear or not isinstance(params[name], (int, float))  # searched, or a label / matrix
                    or name in undetermined):
                se[name] = None
                continue
            se[name] = float(jackknife_se(np.array([j[name] for j in jack], float)))
        if c.kind == "spring":  # the column was q − mean(q) of this run: the rest position the torque is zero at
            j = ctx.model.config.joints.index(c.where.partition(" ")[2])
            params["rest"], se["rest"] = float(ctx.sig.q[:, j].mean()), None
        start += k
        effects.append(Effect(c.kind, c.where, params, se, tuple(float(v) for v in th), dict(c.nonlinear)))
    return phi, effects


def augmented_model(model: RobotModel, ds: Dataset, data_path: str, result: dict, phi: np.ndarray,
                    effects: list[Effect], given: IdentifiedModel | None, alpha: float = ALPHA,
                    min_speed: float = DEFAULT_MIN_SPEED, folded: Sequence[Effect] = (),
                    cad_ft_offsets: np.ndarray | None = None) -> IdentifiedModel:
    """The model file of the refit: the given model's sections (or fresh ones), the refitted Φ, the effects,
    Λ and the T² detector recalibrated on the run with the effects (so detect and export see the augmented
    residuals), through dynid.pipeline.build_model as `dynid fit` does. Sections that describe the given model's
    own fit (base, estimators, cv) are dropped: they no longer describe these parameters. `folded`: payloads
    named and already added to Φ, recorded for the reader. `cad_ft_offsets`: the CAD inertia's offsets fitted on the
    run beside the named F/T steps (dynid.gaps.steps), which then replace the given model's."""
    if given is not None and given.calibrated is not None:
        alpha, min_speed = given.calibrated.alpha, given.calibrated.min_speed
    start = given if given is not None else IdentifiedModel(robot_record(model.config), {})
    sections = replace(
        start, base=None, estimators={}, cv=None, n_components=None, fit_time_s=None, estimator="gaps",
        settings=replace(start.settings, estimator="gaps", alpha=alpha, min_speed=min_speed),
        named_effects=tuple(effects),
        cad_ft_offsets=start.cad_ft_offsets if cad_ft_offsets is None else cad_ft_offsets,
        gaps=GapsSection(result.get("given_model"), result["gap"], result["thresholds"], result["rank"],
                         result["blocks"], [e.as_dict() for e in folded]))  # payloads, added to their links' Φ
    tracking = given.supply_tracking if given is not None else None  # kept: detect will track too
    return build_model(model, phi, [ds], [data_path], sections, FitSettings(min_speed=min_speed),
                       detector=DetectorSettings(alpha), tracking=tracking, effects=effects).model
