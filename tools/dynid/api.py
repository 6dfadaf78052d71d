"""dynid's public Python API, in scikit-learn's manner: estimators with `fit`, `predict` and `score`, whose
parameters are checked at fit time, and a few functions for what is not an estimator.

    >>> import dynid
    >>> model = dynid.DynamicsModel(robot="icub_right_arm").fit("out/identification")
    >>> model.validate("out/validation")["table_ii"]
    >>> dynid.ContactDetector(model).evaluate("out/contact")

DATA arguments are a path of what the command line reads (a dataset, CSV or candump file, a `dynid simulate` directory,
a YARP folder, a ROS 2 bag, a logger's folder of files) or a `Dataset` already loaded (`read_data`); a window is a
Dataset's `slice` (the command line's `--from/--to`, `RUN@FROM:TO`, are not paths). The results are the command
line's `--json` results (docs/formats.md).
Layer: above everything but the cli.
"""

from __future__ import annotations

import numbers
import warnings
from collections.abc import Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import Any, Union

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.metrics import r2_score
from sklearn.utils.validation import check_is_fitted

from .config import RobotConfig, load_config
from .config.robot_config import BUNDLED_DIR
from .detect.combined import CombinedDetector, calibrate_combined
from .detect.evaluation import detectors, filter_edges
from .detect.momentum_t2 import MomentumDetector, calibrate_momentum, calibration_runs, friction_band, run_residuals
from .detect.t2 import ALPHA, VARIANTS, Detector, calibrate, calibration_residuals, score_with_delays
from .detect.t2 import score as score_t2
from .errors import InputError
from .export.model_export import Exported, ExportSettings, export_model
from .gaps.find import Gaps as FoundGaps
from .gaps.find import find_gaps as analyse_gaps
from .identify.blocks import fitted_mask, validate_blocks
from .identify.fit import ESTIMATORS, PSEUDO_INERTIA_ONLY, FitSettings
from .identify.model_file import IdentifiedModel
from .identify.model_file import load_model as load_model_file
from .identify.model_sections import DEFAULT_BLOCKS, DEFAULT_ESTIMATOR, DEFAULT_MIN_SPEED, DEFAULT_N_MODE
from .identify.supply import SupplyTracking
from .identify.validation import Evaluated, evaluate, load_run, validation
from .io.dataset import Dataset
from .io.load import load_data
from .pipeline import DetectorSettings, IdentifySettings, identify
from .robot.effects import augmented_residuals_many
from .robot.model import RobotModel
from .robot.outputs import measured_outputs

Data = Union[str, Path, Dataset]


def load_robot(robot: str | Path | RobotConfig = "icub_right_arm") -> RobotModel:
    """The robot model of a configuration: a bundled name, a YAML file, or a loaded `RobotConfig`."""
    return RobotModel(robot if isinstance(robot, RobotConfig) else load_config(robot))


def read_data(data: Data, robot: str | Path | RobotConfig | RobotModel = "icub_right_arm") -> Dataset:
    """A run of data as a `Dataset`, checked against the robot (what `dynid import` reads); its meta["read_from"] is
    the path, which a model fitted on it (or on a slice of it) records as its data."""
    if isinstance(data, Dataset):
        return data
    if not isinstance(data, (str, Path)):
        raise InputError(f"data must be a path or a Dataset, not {type(data).__name__}")
    model = robot if isinstance(robot, RobotModel) else load_robot(robot)
    ds = load_data(Path(data), model.config, joint_limits=model.joint_limits)
    ds.meta["read_from"] = str(data)
    return ds


def _runs(data: Data | Sequence[Data], model: RobotModel) -> tuple[list[Dataset], list[str]]:
    items = _items(data)
    runs = [_windowed(d) if isinstance(d, Dataset) else load_run(str(d), model) for d in items]
    labels = [_path_of(d) or "dataset" if isinstance(d, Dataset) else str(d) for d in items]
    return runs, labels


def _no_y(y: object) -> None:
    """The model's outputs are in the data: a `y` given is refused, not ignored (scikit-learn passes None)."""
    if y is not None:
        raise InputError("y is not used: the measured outputs are in the data (give X alone)")


def _path_of(ds: Dataset) -> str | None:
    """The file a run in memory was read from (`read_data`), else its recorded source."""
    return ds.meta.get("read_from") or ds.meta.get("source")


def _items(data: Data | Sequence[Data]) -> list[Data]:
    """One run or a sequence of runs, as a list; what is neither is refused in one line."""
    if isinstance(data, (str, Path, Dataset)):
        return [data]
    if isinstance(data, np.ndarray) or not isinstance(data, Sequence):
        raise InputError(f"data must be a path, a Dataset (dynid.read_data) or a list of them, not {type(data).__name__}")
    if not data:
        raise InputError("no data given")
    odd = next((d for d in data if not isinstance(d, (str, Path, Dataset))), None)
    if odd is not None:  # an array in a list was read as a file's name
        raise InputError(f"data must be paths or Datasets (dynid.read_data), not {type(odd).__name__}")
    return list(data)


def _windowed(ds: Dataset) -> Dataset:
    """A run in memory, its window (its first and last stamps, the data's own seconds) recorded where it names no
    window of its file: the model file then says which samples it was fitted on (as `--from/--to` do), so that
    `validate` and `detect` know a later window of the same file for what it is, and export reloads the same samples."""
    if ds.meta.get("window") is not None or not _path_of(ds) or ds.n_samples == 0:
        return ds
    return replace(ds, meta={**ds.meta, "window": [float(ds.t[0]), float(ds.t[-1])]})


class DynamicsModel(BaseEstimator):
    """The identified dynamics of a robot: inertia, F/T offsets, friction and motor gains in one regression, with
    the T² detector calibrated on the same data (`dynid fit`).

    Parameters
    ----------
    robot : str or Path
        A bundled configuration's name or a configuration file.
    estimator : {"iv", "pls", "ols"}
        Whose parameters the model keeps; all three are fitted and reported.
    n_components : int or None
        PLS latent variables; None chooses them by block cross-validation.
    blocks : int
        Time blocks for cross-validation and the jackknife.
    min_speed : float
        Rows whose joint or motor is slower than this (rad/s) are left out: static friction holds them.
    alpha : float
        Confidence level of the T² threshold, in [0.5, 1).
    n_mode : {"dim", "nu"}
        n of the paper's F threshold: dim(e), or ν as the paper writes.
    supply_time_constant : float
        Time constant (s) of each motor's supply tracking; 0 keeps the gains constant.
    consistent : bool or "pseudo-inertia"
        Physically consistent estimation (docs/consistency.md): the estimator's parameters projected onto physical
        ones (every pseudo-inertia positive semidefinite, each body's mass inside a sphere about its frame,
        friction ≥ 0, gains of their sign), kept as the estimator "consistent". None (the default): the robot
        configuration's `fit.consistent`, off where it gives none (on for the iCub leg: docs/consistency.md#default
        says why). "pseudo-inertia": the same without the sphere (a body may carry mass beyond its reach).
    cad_pull : bool
        With `consistent`: a pull of the inertial parameters towards CAD, its weight cross-validated (default off).

    Attributes
    ----------
    model_ : IdentifiedModel
        The model file's content (`save` writes it).
    parameters_ : dict[str, float]
        The full parameter vector Φ by name.
    rank_ : int
        The number of base parameters the data excite.
    undetermined_ : list[str]
        Base combinations whose standard error is above 10 %: the run does not determine them.
    """

    def __init__(self, robot: str | Path = "icub_right_arm", estimator: str = DEFAULT_ESTIMATOR,
                 n_components: int | None = None, blocks: int = DEFAULT_BLOCKS, min_speed: float = DEFAULT_MIN_SPEED,
                 alpha: float = ALPHA, n_mode: str = DEFAULT_N_MODE,
                 supply_time_constant: float = SupplyTracking.time_constant_s, consistent: bool | str | None = None,
                 cad_pull: bool = False) -> None:
        self.robot = robot
        self.estimator = estimator
        self.n_components = n_components
        self.blocks = blocks
        self.min_speed = min_speed
        self.alpha = alpha
        self.n_mode = n_mode
        self.supply_time_constant = supply_time_constant
        self.consistent = consistent
        self.cad_pull = cad_pull

    def _check_params(self) -> None:
        if self.estimator not in ESTIMATORS:
            raise InputError(f"estimator must be one of {', '.join(ESTIMATORS)}, got {self.estimator!r}")
        integer = lambda v: isinstance(v, numbers.Integral) and not isinstance(v, bool)  # noqa: E731 - np.int64 too
        real = lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool) and np.isfinite(v)  # noqa: E731
        if self.n_components is not None and not (integer(self.n_components) and self.n_components > 0):
            raise InputError(f"n_components must be a positive integer or None, got {self.n_components!r}")
        if not (integer(self.blocks) and self.blocks > 1):
            raise InputError(f"blocks must be an integer of 2 or more, got {self.blocks!r}")
        if not (real(self.min_speed) and self.min_speed >= 0):
            raise InputError(f"min_speed must be 0 or more, got {self.min_speed!r}")
        if not (real(self.alpha) and 0.5 <= self.alpha < 1):
            raise InputError(f"alpha must be in [0.5, 1), got {self.alpha!r}")
        if self.n_mode not in ("dim", "nu"):
            raise InputError(f"n_mode must be 'dim' or 'nu', got {self.n_mode!r}")
        if not (real(self.supply_time_constant) and self.supply_time_constant >= 0):
            raise InputError(f"supply_time_constant must be 0 or more, got {self.supply_time_constant!r}")
        if not (self.consistent is None or isinstance(self.consistent, (bool, np.bool_))
                or self.consistent == PSEUDO_INERTIA_ONLY):
            raise InputError(f"consistent must be None, True, False or {PSEUDO_INERTIA_ONLY!r}, got "
                             f"{self.consistent!r}")
        if not isinstance(self.cad_pull, (bool, np.bool_)):
            raise InputError(f"cad_pull must be True or False, got {self.cad_pull!r}")
        if self.cad_pull and self.consistent is False:
            raise InputError("cad_pull weighs the CAD prior of the physically consistent fit: set consistent too")

    def fit(self, X: Data | Sequence[Data], y: None = None) -> DynamicsModel:
        """Identify the model on one or more contact-free runs (stacked into one regression).

        Parameters
        ----------
        X : DATA or a list of DATA
            The identification run(s).
        y : None
            Unused: the outputs are in the data.
        """
        _no_y(y)
        self._check_params()
        robot = load_robot(self.robot)
        consistent = self.consistent
        if consistent is None:  # the robot's default, as `dynid fit` without --consistent
            consistent = {"off": False, "on": True}.get(robot.config.fit_consistent, robot.config.fit_consistent)
        if self.cad_pull and consistent is False:
            raise InputError("cad_pull weighs the CAD prior of the physically consistent fit: set consistent too")
        runs, labels = _runs(X, robot)
        fit = FitSettings(estimator=self.estimator, n_components=None if self.n_components is None else
                          int(self.n_components), min_speed=float(self.min_speed), blocks=int(self.blocks),
                          consistent=bool(consistent),
                          cad_pull=bool(self.cad_pull), consistent_sphere=consistent != PSEUDO_INERTIA_ONLY)
        done = identify(robot, runs, labels, IdentifySettings(fit, DetectorSettings(self.alpha, self.n_mode),
                                                              self.supply_time_constant))
        self._set_fitted(done.model)
        return self

    def _set_fitted(self, identified: IdentifiedModel) -> None:
        self.model_ = identified
        self.parameters_ = dict(identified.parameters)
        base = identified.base
        self.rank_ = None if base is None else base.rank
        self.undetermined_ = [] if base is None else [c for c, ok in zip(base.combinations, base.identified) if not ok]

    def _evaluated(self, X: Data) -> Evaluated:
        check_is_fitted(self, "model_")
        items = _items(X)
        if len(items) != 1:
            raise InputError(f"one run here, not {len(items)}")
        X = items[0]
        robot = self.model_.robot_model
        ds = X if isinstance(X, Dataset) else load_run(str(X), robot)
        label = str(X) if not isinstance(X, Dataset) else _path_of(X) or "dataset"
        return evaluate(self.model_.path or "model", label, self.model_, ds)

    def _each(self, X: Data | Sequence[Data]) -> list[Evaluated]:
        """Every run of X evaluated (one, or a list: scikit-learn's cross-validation passes a subset of a list)."""
        check_is_fitted(self, "model_")
        return [self._evaluated(x) for x in _items(X)]

    @property
    def output_channels_(self) -> list[str]:
        """The output channels y: each F/T sensor's six, then the motor inputs (or the measured torques)."""
        check_is_fitted(self, "model_")
        return self.model_.output_channels

    def predict(self, X: Data | Sequence[Data]) -> np.ndarray:
        """ŷ (N, n_outputs): the F/T wrenches through the regressor and the inputs from the motor equations, on the
        run's filtered signals, with the offline supply estimate where the model tracks it (runs one after another)."""
        return np.vstack([measured_outputs(ev.model, ev.signals) - ev.e for ev in self._each(X)])

    def residuals(self, X: Data | Sequence[Data]) -> np.ndarray:
        """e = y − ŷ (N, n_outputs) on the run (runs one after another)."""
        return np.vstack([ev.e for ev in self._each(X)])

    def score(self, X: Data | Sequence[Data], y: None = None) -> float:
        """R² of the predicted outputs on the run (or the runs together), averaged over the channels (scikit-learn's
        `r2_score`): `cross_val_score` over a list of runs scores each held-out part."""
        _no_y(y)
        evs = self._each(X)
        y_true = np.vstack([measured_outputs(ev.model, ev.signals) for ev in evs])
        return float(r2_score(y_true, y_true - np.vstack([ev.e for ev in evs]), multioutput="uniform_average"))

    def validate(self, X: Data, blocks: int | None = None) -> dict[str, Any]:
        """The paper's Table II (F/T error norms, identified against CAD) and the per-channel RMS against the noise:
        `dynid validate --json`. `blocks` = K also validates each of K equal time blocks of X alone, with whether
        the model was fitted on it, the worst block and the spread (`validate --blocks K`: result["blocks"])."""
        ev = self._evaluated(X)
        source = str(X) if not isinstance(X, Dataset) else _path_of(X)
        label = source or "dataset"
        fitted = fitted_mask(self.model_, source, ev.dataset.t) if source else None  # the fit's own samples
        result = validation(ev, self.model_.path or "model", label,
                            window=(float(ev.dataset.t[0]), float(ev.dataset.t[-1])) if isinstance(X, Dataset)
                            else (None, None), fit_overlap=None if fitted is None else float(fitted.mean()))
        if blocks is not None:
            # the fit's own samples from the mask above (its data's sha256 read once, a run in memory's too)
            result["blocks"] = validate_blocks(self.model_, ev.dataset, blocks, self.model_.path or "model", label,
                                               source, fitted)
        return result

    def save(self, path: str | Path) -> DynamicsModel:
        """Write the model file (JSON, atomically); `dynid validate`, `detect`, `export` and `gaps` read it."""
        check_is_fitted(self, "model_")
        self.model_.save(path)
        return self

    @classmethod
    def load(cls, path: str | Path) -> DynamicsModel:
        """A fitted model from a model file of `dynid fit` (or `dynid gaps --out`)."""
        return cls._from_identified(load_model_file(path))

    @classmethod
    def _from_identified(cls, identified: IdentifiedModel) -> DynamicsModel:
        """The fitted estimator of an identified model, with the settings it was fitted with."""
        settings = identified.settings
        tracking = identified.supply_tracking
        consistent = (False if not settings.consistent else True if settings.consistent_sphere
                      else PSEUDO_INERTIA_ONLY)  # as fitted: a clone refits with the same settings
        # a bundled robot by its name (as it was given), a user's by its file; a gaps model's estimator ("gaps") refits
        # as the standard model's default: its effects are find_gaps' to name again
        source = Path(identified.config.source)
        bundled = source.resolve().parent == BUNDLED_DIR.resolve() and source.stem == identified.config.name
        robot = identified.config.name if bundled else str(source)
        estimator = settings.estimator if settings.estimator in ESTIMATORS else DEFAULT_ESTIMATOR
        est = cls(robot=robot, estimator=estimator, n_components=settings.n_components,
                  blocks=settings.blocks, min_speed=settings.min_speed, alpha=settings.alpha, n_mode=settings.n_mode,
                  supply_time_constant=tracking.time_constant_s if tracking is not None else 0.0,
                  consistent=consistent, cad_pull=settings.cad_pull)
        est._set_fitted(identified)
        return est


class ContactDetector(BaseEstimator):
    """Hotelling T² contact detection on a fitted model's residuals (`dynid detect`).

    Unfitted, it uses the calibration the model was fitted with; `fit` recalibrates Λ and T²_α on other
    contact-free runs.

    Parameters
    ----------
    model : DynamicsModel
        A fitted model.
    variant : {"combined", "calibrated", "paper", "momentum"}
        "combined" (the default, as `dynid detect`'s and the monitor's: both residuals' T²/T²_α summed over κ, no
        blind side of a sensor; its decision function is that sum over κ: docs/detection.md#no-blind-side),
        "calibrated" (the acceleration residuals, Λ and T²_α from contact-free data, so α keeps its promise), "paper"
        (diagonal Λ and the F threshold, as published) or "momentum" (T² on the generalized-momentum observer's
        residuals, no q̈, calibrated like "calibrated": docs/detection.md; its decision function is T²/T²_α).
    bandwidth_hz : float
        The momentum observer's bandwidth (variants "momentum" and "combined").
    alpha : float or None
        Confidence level; None takes the model's.
    """

    def __init__(self, model: DynamicsModel, variant: str = "combined", alpha: float | None = None,
                 bandwidth_hz: float = 15.0) -> None:
        self.model = model
        self.variant = variant
        self.alpha = alpha
        self.bandwidth_hz = bandwidth_hz

    def set_params(self, **params: Any) -> ContactDetector:
        """As scikit-learn's, and what was calibrated with the old settings is dropped (a stale one gave the old α's
        alarms silently): the lazy calibrations (the momentum observer's, κ), which the next use redoes with the new
        ones, and `fit`'s own on the runs it was given, which it does not keep: fit again (a warning says so; until
        then the model's own calibration is used)."""
        refitted = "detector_" in self.__dict__ or getattr(self, "_fitted_on_runs", False)
        super().set_params(**params)
        for cached in ("detector_", "_momentum", "_combined", "_fitted_on_runs"):
            self.__dict__.pop(cached, None)
        if refitted:
            warnings.warn("set_params dropped the calibration fit() made on its runs: call fit() again to recalibrate "
                          "on them with the new parameters (until then the model's own calibration is used)",
                          UserWarning, stacklevel=2)
        return self

    def __sklearn_clone__(self) -> ContactDetector:
        """A clone with the same fitted model (scikit-learn's would clone the model unfitted: the detector is of that
        model, as a frozen estimator is), unfitted itself."""
        return type(self)(**{**self.get_params(deep=False), "model": self.model})

    def __sklearn_is_fitted__(self) -> bool:
        """Usable once its model is fitted: unfitted, it takes the calibration the model was fitted with."""
        return hasattr(self.model, "model_")

    def _check(self) -> None:
        check_is_fitted(self.model, "model_")
        if self.variant not in (*VARIANTS, "momentum", "combined"):
            raise InputError(f"variant must be one of {', '.join(VARIANTS)}, momentum, combined, got {self.variant!r}")
        real = lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool) and np.isfinite(v)  # noqa: E731
        if self.alpha is not None and not (real(self.alpha) and 0.5 <= self.alpha < 1):
            raise InputError(f"alpha must be None or in [0.5, 1), got {self.alpha!r}")
        if not (real(self.bandwidth_hz) and self.bandwidth_hz > 0):
            raise InputError(f"bandwidth_hz must be a positive number, got {self.bandwidth_hz!r}")

    def _alpha(self) -> float:
        calibrated = self.model.model_.calibrated
        stored = ALPHA if calibrated is None else calibrated.alpha
        return float(stored if self.alpha is None else self.alpha)

    def _detector(self) -> Detector:
        self._check()
        if hasattr(self, "detector_"):
            return self.detector_
        variant = "calibrated" if self.variant == "combined" else self.variant  # the combined one's acceleration part
        return detectors(self.model.model_, self._alpha(), self.model.model_.settings.n_mode)[variant]

    def _combined_detector(self, runs: list | None = None) -> CombinedDetector:
        if runs is None and hasattr(self, "_combined"):
            return self._combined
        identified = self.model.model_
        momentum = self._momentum_detector(runs)  # on the given runs, or (cached) on the fit's, cross-validated
        folds = None
        if runs is None:  # the runs it was fitted on, cross-validated, as the momentum detector's
            runs, _ = calibration_runs(identified, None)
            folds = identified.folds
        self._combined = calibrate_combined(identified, momentum, self._detector(), runs, folds)
        return self._combined

    def _momentum_detector(self, runs: list | None = None) -> MomentumDetector:
        if runs is None and hasattr(self, "_momentum"):
            return self._momentum
        identified = self.model.model_
        folds = None
        if runs is None:  # the runs it was fitted on: each time block through the Φ fitted without it
            runs, _ = calibration_runs(identified, None)
            folds = identified.folds
        det = calibrate_momentum(identified.robot_model, identified.phi, identified.base, runs, self._alpha(),
                                 identified.min_speed, self.bandwidth_hz, tracking=identified.supply_tracking,
                                 folds=folds)
        self._momentum = det
        return det

    def _combined_statistic(self, X: Data) -> tuple[Dataset, np.ndarray]:
        det = self._combined_detector()
        ds, momentum, all_rest = self._momentum_statistic_and_rest(X)
        ev = self.model._evaluated(X)
        acceleration = self._detector()
        t2 = np.where(filter_edges(ev), np.nan, acceleration.t2(ev.model, ev.e, ev.signals.dq))
        return ds, det.statistic(momentum, t2 / acceleration.threshold, all_rest)

    def _momentum_statistic(self, X: Data) -> tuple[Dataset, np.ndarray]:
        return self._momentum_statistic_and_rest(X)[:2]

    def _momentum_statistic_and_rest(self, X: Data) -> tuple[Dataset, np.ndarray, np.ndarray]:
        """The run, the momentum detector's statistic and where every row rests."""
        identified = self.model.model_
        robot = identified.robot_model
        det = self._momentum_detector()
        ds = _runs(X, robot)[0][0]
        band = friction_band(robot, identified.phi, identified.base, det.band_sigmas)
        res = run_residuals(robot, identified.phi, ds, det.bandwidth_hz, det.min_speed, band,
                            identified.supply_tracking, det.velocity_window_s)
        return ds, det.statistic(res.e, res.at_rest), res.at_rest.all(axis=1)

    def fit(self, X: Data | Sequence[Data], y: None = None) -> ContactDetector:
        """Recalibrate Λ and T²_α on contact-free runs, with the offline derivatives and supply estimate (the
        momentum variant: through its observer). Every part of the variant is recalibrated: the combined one's
        acceleration residuals too, where `dynid detect --calibration` recalibrates the observer and κ alone (so the
        two differ there; the momentum variant's are the same)."""
        self._check()
        identified = self.model.model_
        robot = identified.robot_model
        runs, _ = _runs(X, robot)
        self._fitted_on_runs = True
        if self.variant == "momentum":
            self._momentum_detector(runs)
            return self
        variant = "calibrated" if self.variant == "combined" else self.variant
        phi, effects = identified.phi, identified.effects
        settings = FitSettings(min_speed=identified.min_speed)

        def residuals_of(sig, t, phis):  # noqa: ANN001, ANN202 - dynid.detect.t2.ResidualsOf
            return augmented_residuals_many(robot, phis, effects, sig, t)

        # runs given to calibrate on: out of sample by the caller's choice, through the model's Φ
        e, dq, e_constant, _ = calibration_residuals(robot, runs, settings, residuals_of, identified.supply_tracking,
                                                     phi)
        found = calibrate(robot, phi, e, dq, self._alpha(), identified.min_speed, variants=(variant,),
                          e_constant=e_constant)
        self.detector_ = found[variant]
        if self.variant == "combined":  # both parts on the given runs, then κ on them
            self._combined_detector(runs)
        return self

    def decision_function(self, X: Data) -> np.ndarray:
        """T² per sample (NaN where the detector is gated off, and within half the derivative filter's window of
        the run's ends: `dynid.detect.evaluation.filter_edges`); T²/T²_α for the momentum variant, s for the combined
        one."""
        self._check()
        if self.variant == "momentum":
            return self._momentum_statistic(X)[1]
        if self.variant == "combined":
            return self._combined_statistic(X)[1]
        ev = self.model._evaluated(X)
        e = ev.e_constant if self.variant == "paper" else ev.e  # the paper's model has constant gains
        return np.where(filter_edges(ev), np.nan, self._detector().t2(ev.model, e, ev.signals.dq, ev.identified.phi))

    def predict(self, X: Data) -> np.ndarray:
        """Contact (True) where T² exceeds T²_α."""
        threshold = 1.0 if self.variant in ("momentum", "combined") else self._detector().threshold
        return np.nan_to_num(self.decision_function(X), nan=0.0) > threshold

    def score(self, X: Data, y: np.ndarray | None = None) -> float:
        """Balanced accuracy against `y` or the run's own contact ground truth: the mean of the recalls of the classes
        present, (TPR + 1 − FPR) / 2, or 1 − FPR on a contact-free run (scikit-learn's `balanced_accuracy_score`)."""
        truth = np.asarray(y if y is not None else self._contact(X), bool)
        hit = self.predict(X)
        if truth.shape != hit.shape:
            raise InputError(f"y has {truth.size} samples, the run {hit.size}")
        recalls = [hit[truth].mean()] if truth.any() else []
        recalls += [1.0 - hit[~truth].mean()] if (~truth).any() else []
        return float(np.mean(recalls))

    def _contact(self, X: Data) -> np.ndarray:
        ds = X if isinstance(X, Dataset) else load_run(str(X), self.model.model_.robot_model)
        if ds.contact is None:
            raise InputError("the run has no 'contact' ground truth: pass y")
        return ds.contact != 0

    def evaluate(self, X: Data) -> dict[str, Any]:
        """TPR, FPR, ROC/AUC, episodes found and onset delays against the run's ground truth: this variant's
        part of `dynid detect --json`."""
        self._check()
        if self.variant in ("momentum", "combined"):
            ds, stat = (self._momentum_statistic if self.variant == "momentum" else self._combined_statistic)(X)
            found = score_with_delays(ds.t, stat, 1.0, ds.contact, ds.extra.get("skin.side"))
        else:
            ev = self.model._evaluated(X)
            e = ev.e_constant if self.variant == "paper" else ev.e
            det = self._detector()
            t2 = np.where(filter_edges(ev), np.nan, det.t2(ev.model, e, ev.signals.dq, ev.identified.phi))
            found = score_t2(ev.dataset.t, t2, det.threshold, ev.dataset.contact, ev.dataset.extra.get("skin.side"))
        # Without contact labels every alarm counts as a false positive: said by a TPR of None, not a missing key
        return {"tpr": None, **found}


def export_coefficients(model: DynamicsModel, path: str | Path, settings: ExportSettings = ExportSettings()) -> Exported:
    """Write the coefficient file rt_monitor loads, T² calibrated through the monitor's own filter on the model's
    identification data (or `settings.data`): `dynid export`."""
    check_is_fitted(model, "model_")
    return export_model(model.model_, path, settings)


def export_urdf(model: DynamicsModel, path: str | Path, nearest_physical: bool = False):  # -> export.urdf.UrdfExport
    """The identified robot as a URDF, and its side file `<path without .urdf>.dynamics.yaml` (`dynid export
    --urdf`, docs/formats.md): the physical full set nearest CAD that reproduces the identified base parameters in
    every link; `nearest_physical` writes the nearest physical set where none reproduces them (else InputError)."""
    from .export.urdf import export_urdf as write

    check_is_fitted(model, "model_")
    return write(model.model_, path, nearest_physical)


class Gaps(FoundGaps):
    """`find_gaps`' result: `.result` (`dynid gaps --json`), `.effects`, and `augmented_model()`, the fitted
    `DynamicsModel` with the named effects (predict, validate, detect and export it as any other)."""

    def augmented_model(self) -> DynamicsModel:  # type: ignore[override]
        return DynamicsModel._from_identified(super().augmented_model())


def find_gaps(X: Data, robot: str | Path = "icub_right_arm", model: DynamicsModel | None = None,
              supply_tracking: bool = True, verbose: bool = False, keep_tentative: bool = False,
              steps: Sequence[float] | None = None) -> Gaps:
    """Where the model and the run disagree, the missing effects that explain it and the gap after the fix
    (`dynid gaps`): `.result` is its `--json`, `.augmented_model()` the model with the named effects (and the
    tentative ones with `keep_tentative`). With `model`, its inertias are held (a payload, a changed gain or friction
    is then named against it). `steps`: known change points of the F/T offsets (the data's own seconds), as
    `--steps`; None: the configuration's `ft_steps`, else searched."""
    given = None
    if model is not None:
        check_is_fitted(model, "model_")
        given = model.model_
    robot_model = given.robot_model if given is not None else load_robot(robot)
    ds = X if isinstance(X, Dataset) else load_run(str(X), robot_model)
    label = str(X) if not isinstance(X, Dataset) else _path_of(X) or "dataset"
    found = analyse_gaps(robot_model, ds, label, given, supply_tracking, log=print if verbose else (lambda _: None),
                         keep_tentative=keep_tentative, steps=steps)
    found.result["robot"] = robot_model.config.name  # as `dynid gaps --json` has it
    return Gaps(**{f.name: getattr(found, f.name) for f in fields(found)})


load_model = DynamicsModel.load

__all__ = [
    "ContactDetector",
    "Data",
    "DynamicsModel",
    "ExportSettings",
    "Gaps",
    "export_coefficients",
    "export_urdf",
    "find_gaps",
    "load_model",
    "load_robot",
    "read_data",
]
