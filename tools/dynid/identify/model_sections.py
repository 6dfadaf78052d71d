"""The model file's sections as typed objects (dynid.identify.model_file.IdentifiedModel holds one of each).

Each section is a frozen dataclass built once from the JSON when a model file is read (after
dynid.identify.model_schema has checked its types: `from_json` only converts and checks shapes the schema cannot
state) and written back by `to_json`, key for key as `dynid fit` writes it. The readers (validate, detect, export,
gaps, report, the API) read attributes, never keys, and a default lives in one place: the dataclass field's, or the
constant it comes from. Keys this dynid does not model are kept (`extra`) and written back unchanged.

Layer: identify (detection's and export's own objects are built from these: dynid.detect.t2.Detector.of,
dynid.detect.momentum_t2.detector_from_section).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import DataError
from ..io.bad_rows import DEFAULT_POLICY
from ..robot.regressors.stack import DEFAULT_MIN_SPEED

__all__ = ["ALPHA", "CROSS_VALIDATED", "DEFAULT_BLOCKS", "DEFAULT_ESTIMATOR", "DEFAULT_MIN_SPEED", "DEFAULT_N_MODE", "INSTRUMENT_WINDOW_S",
           "N_MODES", "BaseSection", "ConsistentFit", "DataRun", "DetectorSection", "EstimatorSection", "GapsSection",
           "FoldsSection", "IN_SAMPLE", "OutputsSection", "Payload", "Quantiles",
           "RobotSection", "Settings", "T2Calibration", "Uncertainty"]

ALPHA = 0.99  # the T² detectors' confidence level, unless the fit was given another (`--alpha`)
N_MODES = ("dim", "nu")  # n of the paper's F threshold: dim(e) (the default, docs/design.md §3) or the paper's ν
DEFAULT_N_MODE = "dim"
DEFAULT_ESTIMATOR = "iv"  # the best measured on the simulated arm (README: gains within 1.2 %, against −9…−11 % for OLS and PLS)
DEFAULT_BLOCKS = 10  # time blocks of the cross-validation and the jackknife
# What the detectors' Λ and T²_α were calibrated on: each time block's residual through the Φ fitted without it (the
# default since issue 30), or the fit's own residuals (files of an earlier dynid; a gap workflow's refit)
CROSS_VALIDATED, IN_SAMPLE = "cross-validated", "in-sample"
INSTRUMENT_WINDOW_S = 0.2  # the IV instruments' smoothing window (dynid.identify.fit)

Json = dict[str, Any]


def _array(value: Any, dtype: type = float) -> np.ndarray:
    return np.asarray(value, dtype=dtype)


def _list(value: np.ndarray | Sequence | None) -> list | None:
    if value is None:
        return None
    return value.tolist() if isinstance(value, np.ndarray) else list(value)


def _extra(d: Mapping[str, Any], known: Sequence[str]) -> Json:
    return {k: v for k, v in d.items() if k not in known}


def _dropped_none(d: Json, optional: Sequence[str]) -> Json:
    """`d` without the optional keys whose value is None (a file written without them stays without them)."""
    return {k: v for k, v in d.items() if not (k in optional and v is None)}


@dataclass(frozen=True)
class RobotSection:
    """`robot`: the configuration the model was fitted for, embedded, so that the file stands alone."""

    name: str
    config_digest: str
    config_source: str
    config_text: str | None = None
    urdf: str | None = None  # the URDF's path it was fitted with (a supplied URDF is found again through it)
    noise_per_channel: dict[str, float] | None = None  # the noise it was fitted with (`fit --noise estimate`)
    extra: Json = field(default_factory=dict, compare=False)
    urdf_sha256: str | None = None  # that URDF's bytes: a model is refused on another URDF (None: a file before it)

    KEYS = ("name", "config_digest", "config_source", "config_text", "urdf", "noise_per_channel", "urdf_sha256")

    @classmethod
    def from_json(cls, d: Json) -> RobotSection:
        noise = d.get("noise_per_channel")
        return cls(d["name"], d["config_digest"], d["config_source"], d.get("config_text"), d.get("urdf"),
                   None if noise is None else {k: float(v) for k, v in noise.items()}, _extra(d, cls.KEYS),
                   d.get("urdf_sha256"))

    def to_json(self) -> Json:
        out = {"name": self.name, "config_digest": self.config_digest, "config_source": self.config_source,
               "config_text": self.config_text, "urdf": self.urdf, "noise_per_channel": self.noise_per_channel,
               "urdf_sha256": self.urdf_sha256}
        return {**_dropped_none(out, self.KEYS[3:]), **self.extra}


@dataclass(frozen=True)
class Settings:
    """`settings`: the fit's settings. A key a file lacks (written by an older dynid) takes the default here."""

    estimator: str = DEFAULT_ESTIMATOR  # "gaps" for a model `dynid gaps --out` wrote
    consistent: bool = False
    consistent_sphere: bool = True
    cad_pull: bool = False
    n_components: int | None = None  # PLS ν as given; None: cross-validated
    min_speed: float = DEFAULT_MIN_SPEED
    blocks: int = DEFAULT_BLOCKS
    instrument_window_s: float = INSTRUMENT_WINDOW_S
    alpha: float = ALPHA
    n_mode: str = DEFAULT_N_MODE
    extra: Json = field(default_factory=dict, compare=False)

    KEYS = ("estimator", "consistent", "consistent_sphere", "cad_pull", "n_components", "min_speed", "blocks",
            "instrument_window_s", "alpha", "n_mode")

    @classmethod
    def from_json(cls, d: Json) -> Settings:
        default = cls()
        given = {k: d[k] for k in cls.KEYS if d.get(k) is not None}
        number = {k: float(given[k]) for k in ("min_speed", "instrument_window_s", "alpha") if k in given}
        return cls(**{**{k: getattr(default, k) for k in cls.KEYS}, **given, **number}, extra=_extra(d, cls.KEYS))

    def to_json(self) -> Json:
        return {**{k: getattr(self, k) for k in self.KEYS}, **self.extra}


UNCERTAINTY_KEYS = ("standard_errors_blocks", "standard_errors_runs", "unit_values", "unit_spread")


@dataclass(frozen=True)
class Uncertainty:
    """An estimate's two jackknifes where runs were jackknifed (several runs or pairs): the time blocks' and the
    runs' standard errors, each run's (or pair's) own estimate and their spread; None with one run."""

    standard_errors_blocks: np.ndarray | None = None
    standard_errors_runs: np.ndarray | None = None
    unit_values: np.ndarray | None = None  # (units, rank)
    unit_spread: np.ndarray | None = None

    @classmethod
    def from_json(cls, d: Json) -> Uncertainty:
        return cls(*(None if d.get(k) is None else _array(d[k]) for k in UNCERTAINTY_KEYS))

    def to_json(self) -> Json:
        return {k: _list(getattr(self, k)) for k in UNCERTAINTY_KEYS if getattr(self, k) is not None}


@dataclass(frozen=True)
class BaseSection:
    """`base`: the base parameters β = Φ[independent] + K Φ[dependent] of the fit, with their standard errors."""

    rank: int
    combinations: tuple[str, ...]
    independent: tuple[str, ...]
    dependent: tuple[str, ...]
    K: np.ndarray  # (len(independent), len(dependent))
    values: np.ndarray
    standard_errors: np.ndarray
    identified: np.ndarray  # bool: the run determines the combination
    uncertainty: Uncertainty = field(default_factory=Uncertainty)
    extra: Json = field(default_factory=dict, compare=False)

    KEYS = ("rank", "combinations", "independent", "dependent", "K", "values", "standard_errors", "identified",
            *UNCERTAINTY_KEYS)

    @classmethod
    def from_json(cls, d: Json) -> BaseSection:
        ind, dep = tuple(d["independent"]), tuple(d["dependent"])
        lengths = {len(d[k]) for k in ("combinations", "values", "standard_errors", "identified")} | {len(ind)}
        if len(lengths) != 1:
            raise ValueError("its combinations, independent, values, standard_errors and identified differ in length")
        K = _array(d["K"])
        if K.size != len(ind) * len(dep):
            raise ValueError(f"K holds {K.size} numbers for {len(ind)} × {len(dep)}")
        return cls(int(d["rank"]), tuple(d["combinations"]), ind, dep, K.reshape(len(ind), len(dep)),
                   _array(d["values"]), _array(d["standard_errors"]), _array(d["identified"], bool),
                   Uncertainty.from_json(d), _extra(d, cls.KEYS))

    def to_json(self) -> Json:
        return {"rank": self.rank, "combinations": list(self.combinations), "independent": list(self.independent),
                "dependent": list(self.dependent), "K": self.K.tolist(), "values": self.values.tolist(),
                "standard_errors": self.standard_errors.tolist(), "identified": self.identified.tolist(),
                **self.uncertainty.to_json(), **self.extra}

    def base_values(self, parameters: Mapping[str, float]) -> np.ndarray:
        """β of any full parameter set (CAD, truth) in these combinations."""
        ind = np.array([parameters[n] for n in self.independent], dtype=float)
        dep = np.array([parameters[n] for n in self.dependent], dtype=float)
        return ind + (self.K @ dep if len(dep) else 0.0)

    def standard_error_alone(self) -> dict[str, float]:
        """{parameter: standard error} of the independent parameters that are a base combination on their own (no
        dependent part): their standard error is the parameter's own."""
        out = {}
        for i, (name, s) in enumerate(zip(self.independent, self.standard_errors)):
            if not np.any(self.K[i]) and np.isfinite(s):
                out[name] = float(s)
        return out


@dataclass(frozen=True)
class EstimatorSection:
    """`estimators.<name>`: one estimator's base values and standard errors, its detail and its full Φ by name."""

    values: np.ndarray
    standard_errors: np.ndarray
    detail: Json = field(default_factory=dict)
    parameters: dict[str, float] | None = None
    uncertainty: Uncertainty = field(default_factory=Uncertainty)
    extra: Json = field(default_factory=dict, compare=False)

    KEYS = ("values", "standard_errors", "detail", "parameters", *UNCERTAINTY_KEYS)

    @classmethod
    def from_json(cls, d: Json) -> EstimatorSection:
        params = d.get("parameters")
        return cls(_array(d["values"]), _array(d["standard_errors"]), dict(d.get("detail") or {}),
                   None if params is None else {k: float(v) for k, v in params.items()}, Uncertainty.from_json(d),
                   _extra(d, cls.KEYS))

    def to_json(self) -> Json:
        out: Json = {"values": self.values.tolist(), "standard_errors": self.standard_errors.tolist(),
                     "detail": self.detail}
        if self.parameters is not None:
            out["parameters"] = self.parameters
        return {**out, **self.uncertainty.to_json(), **self.extra}


@dataclass(frozen=True)
class OutputsSection:
    """`outputs`: the monitored channels, their units and noise, and Λ on the identification data."""

    channels: tuple[str, ...]
    residual_variance: np.ndarray
    units: tuple[str, ...] | None = None
    noise_std: np.ndarray | None = None
    extra: Json = field(default_factory=dict, compare=False)

    KEYS = ("channels", "units", "noise_std", "residual_variance")

    @classmethod
    def from_json(cls, d: Json) -> OutputsSection:
        units, noise = d.get("units"), d.get("noise_std")
        return cls(tuple(d["channels"]), _array(d["residual_variance"]), None if units is None else tuple(units),
                   None if noise is None else _array(noise), _extra(d, cls.KEYS))

    def to_json(self) -> Json:
        out = {"channels": list(self.channels), "units": _list(self.units), "noise_std": _list(self.noise_std),
               "residual_variance": self.residual_variance.tolist()}
        return {**_dropped_none(out, ("units", "noise_std")), **self.extra}


@dataclass(frozen=True)
class Quantiles:
    """The calibration T²'s quantiles at `levels` (so that α can change without a refit)."""

    levels: np.ndarray
    values: np.ndarray

    @classmethod
    def from_json(cls, d: Json) -> Quantiles:
        levels, values = _array(d["levels"]), _array(d["values"])
        if levels.ndim != 1 or levels.shape != values.shape or not levels.size:
            raise ValueError("quantiles need as many values as levels")
        return cls(levels, values)

    def to_json(self) -> Json:
        return {"levels": self.levels.tolist(), "values": self.values.tolist()}

    def at(self, alpha: float) -> float | None:
        """The quantile at `alpha`, interpolated; None outside the levels (ascending or, in older files, not)."""
        order = np.argsort(self.levels)
        levels, values = self.levels[order], self.values[order]
        if not levels[0] <= alpha <= levels[-1]:
            return None
        return float(np.interp(alpha, levels, values))


@dataclass(frozen=True)
class T2Calibration:
    """One acceleration-based T² detector as calibrated (dynid.detect.t2.Detector is built from it)."""

    variant: str  # "calibrated" or "paper"
    variance: np.ndarray  # Λ (n_out,)
    threshold: float
    alpha: float
    min_speed: float
    n: int  # the n of the F threshold (paper) or dim(e)

    KEYS = ("variant", "variance", "threshold", "alpha", "min_speed", "n")

    @classmethod
    def from_json(cls, d: Json) -> T2Calibration:
        return cls(str(d["variant"]), _array(d["variance"]), float(d["threshold"]), float(d["alpha"]),
                   float(d["min_speed"]), int(d["n"]))

    def to_json(self) -> Json:
        return {"variant": self.variant, "variance": self.variance.tolist(), "threshold": self.threshold,
                "alpha": self.alpha, "min_speed": self.min_speed, "n": self.n}


@dataclass(frozen=True)
class DetectorSection:
    """`detector`: both acceleration-based variants, the number of calibration samples and the calibrated T²'s
    quantiles."""

    paper: T2Calibration
    calibrated: T2Calibration
    calibration_samples: int
    calibrated_t2_quantiles: Quantiles
    calibration: str = IN_SAMPLE  # CROSS_VALIDATED or IN_SAMPLE (files of an earlier dynid: in-sample)
    # the calibrated variant as the fit's own (in-sample) residuals calibrate it, beside a cross-validated one
    in_sample: T2Calibration | None = None
    extra: Json = field(default_factory=dict, compare=False)

    KEYS = ("paper", "calibrated", "calibration_samples", "calibrated_t2_quantiles", "calibration", "in_sample")

    @classmethod
    def from_json(cls, d: Json) -> DetectorSection:
        calibration = str(d.get("calibration", IN_SAMPLE))
        if calibration not in (CROSS_VALIDATED, IN_SAMPLE):
            raise ValueError(f"detector.calibration is '{calibration}' ({CROSS_VALIDATED} or {IN_SAMPLE})")
        return cls(T2Calibration.from_json(d["paper"]), T2Calibration.from_json(d["calibrated"]),
                   int(d["calibration_samples"]), Quantiles.from_json(d["calibrated_t2_quantiles"]), calibration,
                   T2Calibration.from_json(d["in_sample"]) if d.get("in_sample") else None, _extra(d, cls.KEYS))

    def to_json(self) -> Json:
        out = {"paper": self.paper.to_json(), "calibrated": self.calibrated.to_json(),
               "calibration_samples": self.calibration_samples,
               "calibrated_t2_quantiles": self.calibrated_t2_quantiles.to_json(), "calibration": self.calibration,
               **self.extra}
        if self.in_sample is not None:
            out["in_sample"] = self.in_sample.to_json()
        return out


@dataclass(frozen=True)
class Payload:
    """A known payload a run carried (`--payload MASS[@x,y,z]`)."""

    mass: float
    com: tuple[float, float, float] | None = None

    @classmethod
    def from_json(cls, d: Json) -> Payload:
        com = d.get("com")
        if com is not None and len(com) != 3:
            raise ValueError("a payload's com needs three coordinates")
        return cls(float(d["mass"]), None if com is None else tuple(float(c) for c in com))  # type: ignore[arg-type]

    def to_json(self) -> Json:
        return {"mass": self.mass, "com": None if self.com is None else list(self.com)}


Window = tuple[float | None, float | None]


@dataclass(frozen=True)
class DataRun:
    """`data[i]`: a run the model was fitted on (export and the momentum detector reload it with its window and
    its bad-rows policy, and check its sha256)."""

    path: str
    sha256: str | None = None
    samples: int | None = None
    duration_s: float | None = None
    payload: Payload | None = None
    window: Window | None = None  # the run's --from/--to
    bad_rows: Json | None = None  # what `--bad-rows skip` dropped
    # {joint: [min, max]} in degrees over the run's samples: the postures the fit saw (validate names the joints a
    # validation run takes beyond them, dynid.identify.transfer); None when not recorded (a streamed run, older files)
    joint_range_deg: dict[str, list[float]] | None = None

    KEYS = ("path", "sha256", "samples", "duration_s", "payload", "window", "bad_rows", "joint_range_deg")

    @classmethod
    def from_json(cls, d: Json) -> DataRun:
        window = d.get("window")
        if window is not None:
            if len(window) != 2 or not all(w is None or isinstance(w, (int, float)) and not isinstance(w, bool)
                                           and np.isfinite(w) for w in window):
                raise ValueError("a run's window is [from, to], each a number or null")
            window = tuple(None if w is None else float(w) for w in window)
        payload = d.get("payload")
        ranges = d.get("joint_range_deg")
        if ranges is not None and not all(len(v) == 2 and v[0] <= v[1] for v in ranges.values()):
            raise ValueError("a run's joint_range_deg is {joint: [min, max]}")
        return cls(d["path"], d.get("sha256"), d.get("samples"), d.get("duration_s"),
                   None if payload is None else Payload.from_json(payload), window, d.get("bad_rows"),
                   None if ranges is None else {str(k): [float(v[0]), float(v[1])] for k, v in ranges.items()})

    def to_json(self) -> Json:
        out: Json = {"path": self.path, "sha256": self.sha256, "samples": self.samples, "duration_s": self.duration_s}
        if self.payload is not None:
            out["payload"] = self.payload.to_json()
        if self.window is not None:
            out["window"] = list(self.window)
        if self.bad_rows:
            out["bad_rows"] = self.bad_rows
        if self.joint_range_deg is not None:
            out["joint_range_deg"] = self.joint_range_deg
        return out

    @property
    def reload_window(self) -> Window:
        return self.window or (None, None)

    @property
    def bad_rows_policy(self) -> str:
        """How to reload it: dropping the rows the fit dropped, or refusing bad rows as the fit did."""
        return "skip" if self.bad_rows else DEFAULT_POLICY

    @property
    def payload_dict(self) -> Json | None:
        """The payload as a dataset's `meta["payload"]` holds it."""
        return None if self.payload is None else self.payload.to_json()


@dataclass(frozen=True)
class FoldsSection:
    """`folds`: the fit's time blocks and the Φ fitted without each, so that every block's residual can be taken
    with parameters that never saw it (cross-validated residuals: what a new run would see). The detectors'
    Λ and T²_α are calibrated on those (dynid.detect: `fold_segments`), not on the fit's in-sample residuals."""

    run: np.ndarray  # (B,) index of the run (the model's `data` order) each block belongs to
    samples: np.ndarray  # (B, 2) [start, stop) of the block, in that run's own samples (as fitted: its window)
    parameters: np.ndarray  # (B, p) Φ fitted without the block (the layout's order)
    # blocks whose fold estimate the model does not use (an IV iteration that did not settle, left out of the
    # jackknife too): their samples take the whole fit's Φ, in-sample
    in_sample: tuple[int, ...] = ()

    @classmethod
    def from_json(cls, d: Json) -> FoldsSection:
        run, samples, parameters = _array(d["run"], int), _array(d["samples"], int), _array(d["parameters"])
        B = run.size
        if run.ndim != 1 or samples.shape != (B, 2) or parameters.ndim != 2 or parameters.shape[0] != B:
            raise ValueError("folds need one run, one [start, stop) and one parameter vector per block")
        if np.any(samples[:, 1] <= samples[:, 0]) or np.any(samples < 0) or np.any(run < 0):
            raise ValueError("a fold's samples must be a non-empty [start, stop) of a run")
        return cls(run, samples, parameters, tuple(int(k) for k in d.get("in_sample", ())))

    def to_json(self) -> Json:
        return {"run": self.run.tolist(), "samples": self.samples.tolist(), "parameters": self.parameters.tolist(),
                "in_sample": list(self.in_sample)}

    def segments(self, run: int, n_samples: int, phi: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
        """[start, stop) and the Φ that never saw them, covering samples 0 … n_samples of run `run`: each block's
        fold Φ, the whole fit's `phi` on samples no block holds (none, for a run read as fitted)."""
        out: list[tuple[int, int, np.ndarray]] = []
        at = 0
        for k in np.flatnonzero(self.run == run)[np.argsort(self.samples[self.run == run, 0])]:
            lo, hi = (int(min(v, n_samples)) for v in self.samples[k])
            if lo > at:
                out.append((at, lo, phi))
            if hi > lo:
                out.append((lo, hi, phi if int(k) in self.in_sample else self.parameters[k]))
            at = max(at, hi)
        if at < n_samples:
            out.append((at, n_samples, phi))
        return out


@dataclass(frozen=True)
class ConsistentFit:
    """`consistent`: the physically consistent fit's record (dynid.identify.consistent), solved or failed."""

    status: str  # "solved" or "failed"
    source: str  # the unconstrained estimate it starts from (JSON "from")
    details: Json = field(default_factory=dict)  # λ, the active constraints, CV, solver; or the failure's reason

    @classmethod
    def from_json(cls, d: Json) -> ConsistentFit:
        return cls(str(d["status"]), str(d["from"]), _extra(d, ("status", "from")))

    def to_json(self) -> Json:
        return {"status": self.status, "from": self.source, **self.details}


@dataclass(frozen=True)
class GapsSection:
    """`gaps` (with `effects`): what the refit of `dynid gaps --out` was made on, and its gap."""

    given_model: str | None = None
    gap: Any = None
    thresholds: Any = None
    rank: Any = None
    blocks: Any = None
    in_inertial_parameters: list = field(default_factory=list)  # payloads, already added to their links' Φ
    extra: Json = field(default_factory=dict, compare=False)

    KEYS = ("given_model", "gap", "thresholds", "rank", "blocks", "in_inertial_parameters")

    @classmethod
    def from_json(cls, d: Json) -> GapsSection:
        return cls(d.get("given_model"), d.get("gap"), d.get("thresholds"), d.get("rank"), d.get("blocks"),
                   list(d.get("in_inertial_parameters") or []), _extra(d, cls.KEYS))

    def to_json(self) -> Json:
        return {**{k: getattr(self, k) for k in self.KEYS}, **self.extra}


def section(name: str, build: Any, raw: Any, path: str) -> Any:
    """`build(raw)`, a conversion the schema could not foresee (a length, a shape) refused in one line."""
    try:
        return build(raw)
    except (KeyError, TypeError, ValueError, OverflowError, IndexError) as e:
        raise DataError(f"{path}: not a valid dynid model file: section '{name}': {e}") from None
