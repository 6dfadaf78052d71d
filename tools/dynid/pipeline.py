"""The identified model, built in one place: the fit, the T² calibration and the model file's record.

`identify` is what `dynid fit` and `dynid.DynamicsModel.fit` run: the one regression (dynid.identify.fit), the
detector calibrated on the same contact-free runs (dynid.detect.t2), and the record of docs/formats.md.
`build_model` is its second half, which the gap workflow calls with its own refit Φ and named effects
(dynid.gaps.refit), so both write the same sections the same way.

Layer: above detect; export, gaps, report, api and cli import it.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from .config.robot_config import RobotConfig
from .detect.combined import fit_combined
from .detect.momentum_t2 import CALIBRATION_MAX_S, ObserverCalibrations, observer_record
from .detect.t2 import (Detector, calibrate, calibration_residuals, calibration_stride, detector_record,
                        join_calibration, run_calibration_residuals)
from .identify.fit import CONSISTENT, Estimate, FitResult, FitSettings, fit
from .identify.model_file import IdentifiedModel, data_record, robot_record
from .identify.model_sections import (ALPHA, DEFAULT_N_MODE, BaseSection, ConsistentFit, EstimatorSection,
                                      FoldsSection, OutputsSection, Settings, Uncertainty)
from .identify.plausibility import implausible
from .identify.runs import RunRef, fit_on_cluster, worker_model, worker_run
from .identify.statistics import Statistics
from .identify.supply import SupplyTracking
from .errors import DataError, InputError
from .io.dataset import Dataset
from .io.stream import DatasetFile, Run
from .robot.effects import Effect, augmented_residuals_many
from .robot.model import RobotModel
from .robot.outputs import output_channels, residuals_many


@dataclass(frozen=True)
class DetectorSettings:
    """How the T² detector is calibrated (docs/design.md §3): α, and n of the paper's F threshold."""

    alpha: float = ALPHA
    n_mode: str = DEFAULT_N_MODE  # "dim": n = dim(e), the default; "nu": the paper's n = ν


@dataclass(frozen=True)
class Identification:
    """What `identify` hands on: the model file's content, and the pieces the CLI and the API report from."""

    model: IdentifiedModel
    fit: FitResult
    detectors: dict[str, Detector]
    fit_time_s: float  # the regression alone
    total_time_s: float  # with the calibration
    robot: RobotModel | None = None  # the model fitted: the given one, or with the estimated input noise


@dataclass(frozen=True)
class Built:
    model: IdentifiedModel
    detectors: dict[str, Detector]


def derivatives_record(model: RobotModel) -> dict[str, Any]:
    """The model file's `derivatives` section: the offline estimator of the configuration."""
    cfg = model.config
    return {"method": "savgol", **cfg.derivatives} if cfg.derivatives else {"method": "savgol"}


def joint_ranges(run: Any) -> dict[str, list[float]] | None:
    """{joint: [min, max]} in degrees of a run (a streamed one read again for it, its positions alone)."""
    if isinstance(run, DatasetFile):
        if run.n_samples == 0:
            return None
        lo, hi = run.joint_extrema()
    else:
        q = getattr(run, "q", None)
        if not isinstance(q, np.ndarray) or q.size == 0:
            return None
        lo, hi = q.min(axis=0), q.max(axis=0)
    return {j: [float(np.rad2deg(a)), float(np.rad2deg(b))] for j, a, b in zip(run.joints, lo, hi)}


def cad_ft_offsets(model: RobotModel, stats: Statistics) -> np.ndarray:
    """F/T offsets that fit the CAD inertia best on the identification data (the CAD model has none)."""
    layout, p = model.layout, stats.p
    phi = np.nan_to_num(model.cad_parameters(), nan=0.0)
    G = stats.gram.sum(axis=0)
    out = np.zeros(len(layout))
    for i, s in enumerate(model.config.ft_sensors):
        for k in range(6):
            o = layout.block("ft_offset", s.name).start + k
            g = G[6 * i + k]
            out[o] = (g[o, p] - g[o, :p] @ phi) / g[o, o] if g[o, o] > 0 else 0.0
    return out


def build_model(model: RobotModel, phi: np.ndarray, datasets: Sequence[Dataset], data_paths: Sequence[str | Path],
                sections: IdentifiedModel, settings: FitSettings, *, detector: DetectorSettings = DetectorSettings(),
                tracking: SupplyTracking | None = None, effects: Sequence[Effect] = (), nu: int | None = None,
                residual_variance: np.ndarray | None = None,
                cluster: Any = None, refs: Sequence[RunRef] | None = None,
                folds: FoldsSection | None = None) -> Built:
    """Calibrate T² for Φ (and the effects) on the contact-free `datasets` (read with `settings`' derivatives and
    min_speed), and fill the sections every model file has: outputs (Λ: `residual_variance`, else the calibrated
    detector's), detector, supply_tracking, derivatives (where `sections` has none), data. `sections` brings the
    robot and the rest (the fit's sections, or the gap workflow's); the model returned carries Φ as `parameters`.
    With a `cluster` (dynid.cluster) and the runs' `refs`, each run's calibration residuals are a task on it.
    With `folds` (the fit's), Λ and T²_α are calibrated on cross-validated residuals: each time block's through the Φ
    fitted without it (docs/detection.md#out-of-sample); the in-sample calibration is kept beside, for comparison."""
    effects = list(effects)

    def residuals_of(sig, t, phis):  # noqa: ANN001, ANN202 - dynid.detect.t2.ResidualsOf
        return augmented_residuals_many(model, phis, effects, sig, t)

    segments = None if folds is None else [folds.segments(i, ds.n_samples, phi) for i, ds in enumerate(datasets)]
    if cluster is not None and refs is not None and not effects:  # each run's residuals a task of its own
        stride = calibration_stride(sum(ds.n_samples for ds in datasets))
        parts = cluster.map(calibration_task, [(model.config, ref, settings, phi, tracking, stride,
                                                None if segments is None else segments[i])
                                               for i, ref in enumerate(refs)],
                            "calibrating T²", runs=list(range(len(refs))))
        e, dq, e_constant, e_in = join_calibration(parts)
    else:
        e, dq, e_constant, e_in = calibration_residuals(model, datasets, settings, residuals_of, tracking, phi,
                                                        segments)
    detectors = calibrate(model, phi, e, dq, detector.alpha, settings.min_speed, detector.n_mode, nu, e_constant=e_constant)
    in_sample = None if folds is None else calibrate(model, phi, e_in, dq, detector.alpha, settings.min_speed,
                                                      variants=("calibrated",))["calibrated"]
    outs = output_channels(model)
    variance = detectors["calibrated"].variance if residual_variance is None else residual_variance
    identified = replace(
        sections, parameters=dict(zip(model.layout.names, phi.tolist())),
        outputs=OutputsSection(tuple(o.name for o in outs), np.asarray(variance, float), tuple(o.unit for o in outs),
                               np.array([o.sigma for o in outs])),
        detector=detector_record(model, detectors, e, dq, in_sample),
        supply_tracking=tracking, derivatives=sections.derivatives or derivatives_record(model),
        data=tuple(data_record(p, ds.n_samples, ds.duration, ds.meta.get("payload"), ds.meta.get("window"),
                               ds.meta.get("bad_rows"), joint_ranges(ds)) for p, ds in zip(data_paths, datasets)),
        path=None)
    return Built(identified, detectors)


def fit_record(model: RobotModel, config: RobotConfig, result: FitResult, settings: FitSettings,
               detector: DetectorSettings, n_components: int | None) -> IdentifiedModel:
    """The model file's sections that describe the regression: estimator, settings, ν, base parameters, every
    estimator's values (the robot's section of `config`; Φ, the outputs and the calibration follow in
    `build_model`)."""
    base = result.base
    names = model.layout.names
    chosen = result.estimates[result.chosen]
    consistent = result.consistent
    return IdentifiedModel(
        robot_record(config), {},
        # the regression; with `consistent` solved, `parameters` are its physically consistent projection
        estimator=settings.estimator if result.chosen == CONSISTENT else result.chosen,
        settings=Settings(settings.estimator, settings.consistent, settings.consistent_sphere, settings.cad_pull,
                          n_components, settings.min_speed, result.statistics.n_blocks, settings.instrument_window_s,
                          detector.alpha, detector.n_mode),
        n_components=result.cv["n_components"], cv=result.cv, jackknife=result.jackknife,
        consistent=None if consistent is None else ConsistentFit.from_json(consistent),
        base=BaseSection(base.rank, tuple(base.combinations()), tuple(names[i] for i in base.independent),
                         tuple(names[i] for i in base.dependent), np.asarray(base.K, float), chosen.beta, chosen.se,
                         np.asarray(result.identified, bool), uncertainty_record(chosen)),
        estimators={k: EstimatorSection(v.beta, v.se, v.detail, dict(zip(names, v.phi.tolist())),
                                        uncertainty_record(v)) for k, v in result.estimates.items()})


def uncertainty_record(estimate: Estimate) -> Uncertainty:
    """An estimate's two standard errors (time blocks within runs; runs or pairs left out) and each unit's own
    estimate with their spread (the sample standard deviation across units), where runs were jackknifed."""
    return Uncertainty(estimate.se_blocks, estimate.se_runs, estimate.units,
                       None if estimate.units is None else estimate.units.std(axis=0, ddof=1))


@dataclass(frozen=True)
class IdentifySettings:
    """Everything `identify` takes besides the robot and the data."""

    fit: FitSettings = field(default_factory=FitSettings)
    detector: DetectorSettings = field(default_factory=DetectorSettings)
    supply_time_constant_s: float = SupplyTracking.time_constant_s  # 0: constant motor gains
    # Estimate each input channel's noise from the first fit's residuals (moving rows) and refit with it: the
    # weighting, the model file's noise, validation's ratios and the detector's prior then use the estimate.
    estimate_noise: bool = False
    # Calibrate the momentum observer now, for `detect` and `export`, and keep it in the model file (its `observer`
    # section): on the runs as fitted (window, bad rows), which is what those commands calibrate on.
    observer: bool = True

    @property
    def tracking(self) -> SupplyTracking | None:
        return SupplyTracking(self.supply_time_constant_s) if self.supply_time_constant_s > 0 else None


def check_scale(model: RobotModel, datasets: Sequence[Dataset], payload_possible: bool = True,
                without_payload: str = "this command refits on one run without a payload") -> None:
    """Refuse a set-up whose overall scale no data can fix (docs/design.md §3, Table I): every row is then
    homogeneous (b = 0), and Φ = 0 fits as well as any Φ. Something measured in physical units must enter: an
    F/T sensor, a joint torque sensor, a known motor gain, or a run carrying a known payload."""
    cfg = model.config
    unknown = [b.owner for b in model.layout.blocks if b.kind == "motor_gain"]
    if not unknown or cfg.ft_sensors or cfg.joints_with_input("torque"):
        return
    if any(cfg.motor(m).known_gain is not None for g in cfg.actuation for m in g.motors):
        return
    if any(ds.meta.get("payload") for ds in datasets):
        return
    kinds = sorted({g.input for g in cfg.actuation if g.input != "torque"})
    raise InputError(
        f"{cfg.name}: the scale cannot be identified: the {'/'.join(kinds)} gains of {', '.join(unknown)} are unknown "
        "and there is no F/T sensor; give the gains (motors.<m>.known_gain in the configuration)"
        + (", or add a run carrying a known payload (--data RUN --payload MASS[@x,y,z], one --payload per --data)"
           if payload_possible else f" ({without_payload})")
    )


def calibration_task(config: RobotConfig, ref: RunRef, settings: FitSettings, phi: np.ndarray,
                     tracking: SupplyTracking | None, stride: int,
                     segments: list | None = None) -> tuple[np.ndarray, ...]:
    """A worker's task: one run's T² calibration residuals for Φ, or for each fold's Φ on its block
    (dynid.detect.t2.run_calibration_residuals)."""
    model = worker_model(config)
    run = worker_run(ref, model)
    with threadpool_limits(limits=1, user_api="blas"):
        return run_calibration_residuals(model, run, settings, lambda sig, t, phis: residuals_many(model, phis, sig),
                                         tracking, stride, phi, segments)


def identify(model: RobotModel, datasets: Sequence[Run], data_paths: Sequence[str | Path],
             settings: IdentifySettings = IdentifySettings(), cluster: Any = None,
             refs: Sequence[RunRef] | None = None) -> Identification:
    """Fit the model of docs/design.md §3 to the stacked runs, calibrate T² on them, and build the model file.

    With a `cluster` (dynid.cluster.DaskCluster) and each run's `refs`, the runs' statistics and calibration
    residuals are tasks on it; the model is the in-process one's (the same sums, in the same order)."""
    # One BLAS thread: the products here are small (p × p Grams) or long and thin ((N, 3) @ (3, 3)), where OpenBLAS's
    # threads cost more than they give on a shared 2-core machine (docs/benchmarks.md#compiled-kernels); the
    # statistics' workers fill the cores.
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify(model, datasets, data_paths, settings, cluster, refs)


def _identify(model: RobotModel, datasets: Sequence[Run], data_paths: Sequence[str | Path],
              settings: IdentifySettings, cluster: Any, refs: Sequence[RunRef] | None) -> Identification:
    check_scale(model, datasets)
    fit_settings = settings.fit
    if fit_settings.estimator == "iv" and any(ds.meta.get("payload") for ds in datasets):
        # The instruments' predicted inputs leave out a payload's known torques, which would bias IV: with a
        # payload run the fit keeps OLS (all estimators but IV are still reported).
        fit_settings = replace(fit_settings, estimator="ols")
        settings = replace(settings, fit=fit_settings)
    started = time.perf_counter()

    def fitted(model: RobotModel) -> FitResult:
        if cluster is None or refs is None:
            return fit(model, list(datasets), settings.fit)
        return fit_on_cluster(model, list(refs), list(datasets), settings.fit, cluster)

    result = fitted(model)
    if settings.estimate_noise:
        model = with_estimated_noise(model, result)
        result = fitted(model)
    fit_time = time.perf_counter() - started
    folds = folds_record(model, result)
    sections = replace(fit_record(model, model.config, result, settings.fit, settings.detector,
                                  settings.fit.n_components),
                       cad_ft_offsets=cad_ft_offsets(model, result.statistics), folds=folds)
    # only a PWM input drifts with its supply (dynid.identify.supply)
    tracking = settings.tracking if model.config.motors_with_input("pwm") else None
    # The observer's cross-validated calibration samples need Φ, the folds and the settings only: a thread runs them
    # while this one calibrates T² (the kernels and numpy's loops release the GIL). The two whole-run passes after
    # them (the in-sample observer, the combined detector's acceleration residuals) stay one at a time: overlapped
    # too they took a second less and 60-110 MB more (docs/benchmarks.md#compiled-kernels). A DataError of the
    # observer's (e.g. too few contact-free samples) leaves the section out: `detect` calibrates then, and says why.
    observer, heads = None, []
    with ThreadPoolExecutor(1, thread_name_prefix="dynid-observer") as pool:
        if settings.observer:
            try:
                heads = [_head(run) for run in datasets]
                draft = replace(sections, parameters=dict(zip(model.layout.names, result.phi.tolist())),
                                supply_tracking=tracking)
                draft.robot_model  # built once, before two threads read it  # noqa: B018
                observer = ObserverCalibrations(draft, heads, pool.submit)
            except DataError:
                observer = None
        built = build_model(model, result.phi, datasets, data_paths, sections, settings.fit,
                            detector=settings.detector, nu=result.cv["n_components"], tracking=tracking,
                            residual_variance=result.residual_variance[result.chosen], cluster=cluster, refs=refs,
                            folds=folds)
        identified = built.model
        if observer is not None:
            try:
                identified.observer = observer_record(identified, heads, settings.detector.alpha,
                                                      combine=fit_combined(identified, heads),
                                                      calibrations=observer)
            except DataError:
                pass
    total = time.perf_counter() - started
    identified.fit_time_s = total
    # With --consistent off nothing keeps each body physical: say where the estimate is not (identify/plausibility.py)
    identified.plausibility = implausible(model, result.phi)
    return Identification(identified, result, built.detectors, fit_time, total, model)


def folds_record(model: RobotModel, result: FitResult) -> FoldsSection | None:
    """The model file's `folds`: each time block of the fit (its run, its samples in that run) and the chosen
    estimate's Φ fitted without it. A fold the jackknife left out, or whose Φ no model could hold (not finite, a
    motor gain that is not positive: a short run's fold), is marked in-sample: its block takes the whole fit's Φ."""
    chosen = result.estimates[result.chosen]
    if chosen.folds is None:
        return None
    stats = result.statistics
    edges = np.asarray(stats.block_samples)
    runs = np.asarray(stats.block_run)
    first = {int(r): int(edges[np.flatnonzero(runs == r)[0]]) for r in np.unique(runs)}
    samples = np.array([[edges[k] - first[int(runs[k])], edges[k + 1] - first[int(runs[k])]]
                        for k in range(stats.n_blocks)], dtype=int)
    gains = [b.start for b in model.layout.blocks_of("motor_gain")]
    kept = chosen.folds_kept if chosen.folds_kept is not None else np.ones(stats.n_blocks, dtype=bool)
    usable = kept & np.all(np.isfinite(chosen.folds), axis=1) & np.all(chosen.folds[:, gains] > 0, axis=1)
    parameters = np.where(usable[:, None], chosen.folds, result.phi[None, :])
    return FoldsSection(runs.astype(int), samples, parameters, tuple(int(k) for k in np.flatnonzero(~usable)))


def _head(run: Run) -> Dataset:
    """A run in memory as it is (each calibration cuts its own copy of the seconds it reads, for as long as it runs:
    kept here for every run at once, a fleet's would add up), a streamed one read as far as they read (150 s)."""
    if isinstance(run, Dataset):
        return run
    return run.slice(0, min(run.n_samples, int(CALIBRATION_MAX_S / run.median_step()) + 2))


def with_estimated_noise(model: RobotModel, result: FitResult) -> RobotModel:
    """The model with each channel's noise set to the fit's residual RMS on the rows that move (the configuration's
    noise is a prior; a UR's current noise differs fivefold from base to wrist, an iCub leg sensor's axes
    differ too)."""
    rms = np.sqrt(result.residual_variance[result.chosen])
    per = {o.name: float(r) for o, r in zip(output_channels(model), rms) if np.isfinite(r) and r > 0}
    cfg = model.config
    noise = replace(cfg.noise, per_channel={**cfg.noise.per_channel, **per})
    return RobotModel(replace(cfg, noise=noise))
