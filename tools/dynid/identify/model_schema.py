"""The shape of a model file's sections, checked when it is read (dynid.identify.model_file.load_model).

The commands read deep into a model file (`detector.calibrated.threshold`, `base.independent`, `data[0].path`);
a section of the wrong JSON type, or a key lost to a flipped bit, used to end validate, detect, export and report
with a traceback (issue 22's sweep). Every section the typed model (dynid.identify.model_sections) is built from is
described here, and a file that does not match is refused with one line naming the first key that is wrong.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import DataError


@dataclass(frozen=True)
class Opt:
    """An optional key (absent or null are both fine)."""

    spec: Any


@dataclass(frozen=True)
class ListOf:
    spec: Any


@dataclass(frozen=True)
class MapOf:
    """An object whose values all match `spec` (keys are names)."""

    spec: Any


NUMBER, TEXT, INTEGER, FLAG = "a number", "a string", "an integer", "true or false"
ANY = "anything"

_DETECTOR = {"variant": TEXT, "variance": ListOf(NUMBER), "threshold": NUMBER, "alpha": NUMBER,
             "min_speed": NUMBER, "n": INTEGER}
_ESTIMATOR = {"values": ListOf(NUMBER), "standard_errors": ListOf(NUMBER), "detail": Opt(MapOf(ANY)),
              "parameters": Opt(MapOf(NUMBER))}

_MOMENTUM = {"variance": ListOf(NUMBER), "tau_variance": ListOf(NUMBER), "threshold": NUMBER,
             "alpha": NUMBER, "min_speed": NUMBER, "band_sigmas": NUMBER, "bandwidth_hz": NUMBER,
             "ft_thresholds": MapOf(NUMBER), "calibration_samples": INTEGER,
             "velocity_window_s": NUMBER, "quantiles": MapOf(ANY)}
_OBSERVER = {"alpha": NUMBER, "bandwidth_hz": NUMBER, "velocity_window_s": NUMBER, "band_sigmas": NUMBER,
             "measured": FLAG, "detector": _MOMENTUM, "calibration": Opt(TEXT), "in_sample": Opt(_MOMENTUM)}

# Top-level sections: each may be absent (robot, parameters and outputs are required, and model_file.load_model says
# so first), but one that is there must have this shape; null is refused where the readers take the section as an
# object, allowed where null means "off" (supply_tracking, consistent).
SECTIONS: dict[str, Any] = {
    "robot": {"name": TEXT, "config_digest": TEXT, "config_source": TEXT, "config_text": Opt(TEXT),
              "urdf": Opt(TEXT), "noise_per_channel": Opt(MapOf(NUMBER))},
    "outputs": {"channels": ListOf(TEXT), "residual_variance": ListOf(NUMBER), "units": Opt(ListOf(TEXT)),
                "noise_std": Opt(ListOf(NUMBER))},
    "settings": {"min_speed": Opt(NUMBER), "n_mode": Opt(TEXT), "alpha": Opt(NUMBER), "estimator": Opt(TEXT),
                 "consistent": Opt(FLAG), "consistent_sphere": Opt(FLAG), "cad_pull": Opt(FLAG),
                 "n_components": Opt(INTEGER), "blocks": Opt(INTEGER), "instrument_window_s": Opt(NUMBER)},
    "detector": {"paper": _DETECTOR, "calibrated": _DETECTOR, "calibration_samples": INTEGER,
                 "calibrated_t2_quantiles": {"levels": ListOf(NUMBER), "values": ListOf(NUMBER)},
                 "calibration": Opt(TEXT), "in_sample": Opt(_DETECTOR)},
    "base": {"rank": INTEGER, "combinations": ListOf(TEXT), "independent": ListOf(TEXT), "dependent": ListOf(TEXT),
             "K": ListOf(ANY), "values": ListOf(NUMBER), "standard_errors": ListOf(NUMBER),
             "identified": ListOf(FLAG)},
    "estimators": MapOf(_ESTIMATOR),
    "data": ListOf({"path": TEXT, "sha256": Opt(TEXT), "samples": Opt(INTEGER), "duration_s": Opt(NUMBER),
                    "payload": Opt({"mass": NUMBER, "com": Opt(ListOf(NUMBER))}), "window": Opt(ListOf(ANY)),
                    "bad_rows": Opt(MapOf(ANY)), "joint_range_deg": Opt(MapOf(ListOf(NUMBER)))}),
    "cad_ft_offsets": ListOf(NUMBER),
    "n_components": INTEGER,
    "estimator": TEXT,
    "supply_tracking": Opt(MapOf(ANY)),
    "effects": ListOf(MapOf(ANY)),
    "gaps": MapOf(ANY),
    "derivatives": MapOf(ANY),
    "cv": MapOf(ANY),
    "jackknife": MapOf(ANY),
    "consistent": Opt({"status": TEXT, "from": TEXT}),
    "plausibility": ListOf(MapOf(ANY)),
    "fit_time_s": NUMBER,
    # the fit's time blocks and the Φ fitted without each (dynid.identify.model_sections.FoldsSection); absent in
    # older files, whose detectors were calibrated in-sample
    "folds": {"run": ListOf(INTEGER), "samples": ListOf(ListOf(INTEGER)), "parameters": ListOf(ListOf(NUMBER)),
              "in_sample": Opt(ListOf(INTEGER))},
    # the momentum observer calibrated at fit time (dynid.detect.momentum_t2.observer_record); absent in older files
    "observer": {"version": INTEGER, "data_sha256": ListOf(Opt(TEXT)), "detect": Opt(_OBSERVER),
                 "monitor": Opt(_OBSERVER)},
}


def _fits(value: Any, spec: Any) -> bool:
    """`value` is of the scalar kind `spec` names."""
    if spec == ANY:
        return True
    if spec == FLAG:
        return isinstance(value, bool)
    if spec == TEXT:
        return isinstance(value, str)
    if spec == INTEGER:
        return isinstance(value, int) and not isinstance(value, bool)
    # NUMBER: JSON's NaN and Infinity are refused too (a variance or a threshold that is not finite)
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check(value: Any, spec: Any, where: str) -> str | None:
    """The first problem of `value` against `spec`, as a phrase naming its place; None if it matches."""
    if isinstance(spec, Opt):
        return None if value is None else _check(value, spec.spec, where)
    if isinstance(spec, ListOf):
        if not isinstance(value, list):
            return f"'{where}' must be a list"
        return next((p for i, v in enumerate(value) if (p := _check(v, spec.spec, f"{where}[{i}]"))), None)
    if isinstance(spec, MapOf):
        if not isinstance(value, dict):
            return f"'{where}' must be an object"
        return next((p for k, v in value.items() if (p := _check(v, spec.spec, f"{where}.{k}"))), None)
    if isinstance(spec, dict):
        if not isinstance(value, dict):
            return f"'{where}' must be an object"
        for key, sub in spec.items():
            if key not in value and not isinstance(sub, Opt):
                return f"'{where}' lacks '{key}'"
            problem = _check(value.get(key), sub, f"{where}.{key}")
            if problem:
                return problem
        return None
    return None if _fits(value, spec) else f"'{where}' must be {spec}"


def check_sections(document: dict[str, Any], path: str) -> None:
    """Refuse a model file whose sections do not have the shape the commands read (one line, the first problem)."""
    for key, spec in SECTIONS.items():
        problem = _check(document[key], spec, key) if key in document else None
        if problem:
            raise DataError(f"{path}: not a valid dynid model file: {problem}")
