"""The gap workflow as one call: a run (and optionally the model it should match) → the gaps found, the effects
named, and the augmented model that carries them (what `dynid gaps` and `dynid.find_gaps` run)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ..identify.model_file import IdentifiedModel
from ..identify.supply import SupplyTracking
from ..identify.transfer import outside_fit
from ..io.dataset import Dataset
from ..robot.effects import Effect
from ..robot.model import RobotModel
from .refit import augmented_model
from .workflow import Settings, run


@dataclass(frozen=True)
class Gaps:
    result: dict[str, Any]  # `dynid gaps --json` (docs/formats.md)
    effects: list[Effect]  # named effects the augmented model predicts with
    folded: list[Effect]  # payloads named, already added to their links' inertial parameters
    # What the augmented model is built from, on demand.
    _model: RobotModel = field(repr=False)
    _ds: Dataset = field(repr=False)
    _phi: np.ndarray = field(repr=False)
    _given: IdentifiedModel | None = field(repr=False)
    _cad_ft_offsets: np.ndarray | None = field(repr=False, default=None)  # CAD's offsets beside the named F/T steps

    def augmented_model(self) -> IdentifiedModel:
        """The refit Φ with its effects, and T² recalibrated with them on the run (a few seconds: built on demand)."""
        return augmented_model(self._model, self._ds, self.result["data"], self.result, self._phi, self.effects,
                               self._given, folded=self.folded, cad_ft_offsets=self._cad_ft_offsets)


def find_gaps(model: RobotModel, ds: Dataset, data_label: str, given: IdentifiedModel | None = None,
              supply_tracking: bool = True, log: Callable[[str], None] = print, keep_tentative: bool = False,
              steps: Sequence[float] | None = None) -> Gaps:
    """Refit the standard model on the run (holding `given`'s inertias when there is one), name the missing
    effects that explain the gap on held-out blocks, and build the augmented model. Supply tracking follows the
    given model's (a model fitted with it off keeps constant gains here too). The augmented model carries the
    named effects; tentative ones only with `keep_tentative`. `steps`: known change points of the F/T offsets (the
    data's own seconds), taken as known rather than searched; None: the configuration's `ft_steps`."""
    reference = None
    if given is not None:
        if given.effects:
            raise InputError(f"{given.path} is already an augmented model (it names effects); give the standard "
                             "model it came from")
        reference = (given.path or "model", given.phi)
    supply = None
    if supply_tracking:
        supply = given.supply_tracking if given is not None else SupplyTracking()
    known = tuple(model.config.ft_steps if steps is None else steps)
    if known and not model.config.ft_sensors:
        raise InputError(f"--steps: {model.config.name} has no F/T sensor whose offset could step")
    result = run(model, ds, Settings(supply=supply, keep_tentative=keep_tentative, steps=known), reference=reference,
                 log=log)
    augmented = result.pop("_augmented")
    result["data"] = data_label
    if given is not None:  # where the given model's fit never went: why its gap may be its inertias' extrapolation
        result["outside_given_fit"] = outside_fit(given, ds.joints, ds.q, model.joint_limits)
    # a payload is already in Φ (its link's inertial parameters): the model file lists only effects it predicts with
    effects = [e for e in augmented["effects"] if e.kind != "payload"]
    folded = [e for e in augmented["effects"] if e.kind == "payload"]
    return Gaps(result, effects, folded, model, ds, augmented["phi"], given, augmented["cad_ft_offsets"])
