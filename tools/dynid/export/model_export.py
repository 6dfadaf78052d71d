"""An identified model → the coefficient file: calibrate T² through the monitor's own filter, build, write.

`export_model` is what `dynid export --model` and `dynid.export_coefficients` run; `export_cad` writes the CAD
model uncalibrated (for tests and benchmarks that need a coefficient file without a fit).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..config.robot_config import RobotConfig
from ..detect.momentum import (DEFAULT_BANDWIDTH_HZ, VELOCITY_WINDOW_S, friction_band, measured_velocity,
                               velocity_window_samples)
from ..detect.momentum_t2 import MomentumDetector, calibrate_momentum, stored_detector
from ..detect.online import (FixedLagSavitzkyGolay, OnlineCalibration, PieceFolds, calibrate_online, estimator_for,
                             uniform_pieces)
from ..detect.combined import calibrate_combined
from ..detect.t2 import Detector, chi2_quantile, f_threshold
from ..errors import DataError
from ..identify.model_file import IdentifiedModel, data_digest, file_digest
from ..identify.model_sections import ALPHA
from ..identify.supply import SupplyTracking
from ..identify.transfer import fit_ranges
from ..identify.validation import load_run
from ..io.bad_rows import DEFAULT_POLICY
from ..io.dataset import Dataset
from ..robot.effects import Effect
from ..robot.model import RobotModel
from ..robot.outputs import divisors, output_channels
from ..robot.regressors.stack import DEFAULT_MIN_SPEED, group_row_maps, group_rows
from . import known_answers
from .plausible import Implausible, check_plausible
from .coefficients import (
    EventSettings,
    MonitorDetector,
    MonitorObserver,
    Provenance,
    build_coefficients,
    check_monitor_supports,
    external_torque_map,
    check_window,
    exportable_effects,
    write_coefficients,
)

CAD_SAMPLES = 100_000  # the N of the F threshold of an uncalibrated (CAD) export
# The observer's events: on the live mission of the default arm, 3 samples gave 40 false onsets in 120 s, 10 gave one
# and found every visible episode (docs/detection.md#the-monitor).
MOMENTUM_EVENTS = EventSettings(hysteresis=0.5)  # the default times: 10 ms on, 100 ms off


@dataclass(frozen=True)
class ExportSettings:
    """The monitor's filter and event logic, and what Λ and T²_α are calibrated on."""

    data: Sequence[str] = ()  # contact-free runs; default: the model's identification data (checked by sha256)
    data_windows: Sequence[tuple[float | None, float | None] | None] = ()  # each run's --data RUN@FROM:TO window
    lag: int | None = None  # filter lag in samples, 0 = causal; default window // 4
    window: int | None = None  # filter window in samples; default the configuration's offline window
    alpha: float | None = None  # default: the model's
    events: EventSettings = field(default_factory=EventSettings)
    # The residual the monitor runs: "combined" (default where the observer and κ can be calibrated: both residuals in
    # one statistic, docs/detection.md#no-blind-side), "acceleration" (the default otherwise) or "momentum" (the
    # observer, no q̈; not for an augmented model, whose effects have no momentum form yet). The file carries each it
    # can calibrate (rt_monitor --residual switches).
    residual: str | None = None
    bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ  # the observer's
    observer_events: EventSettings = field(default_factory=lambda: MOMENTUM_EVENTS)
    cad_rate_hz: float = 1000.0  # the boards' sample rate of a CAD export (a calibrated one takes its data's)
    data_payloads: Sequence[dict | None] = ()  # each --data run's known payload (--payload), None: none

    def events_for(self, residual: str) -> EventSettings:
        """The event settings the file carries: those of the residual the monitor runs (the combined detector's are
        the acceleration residuals')."""
        return self.observer_events if residual == "momentum" else self.events


@dataclass(frozen=True)
class Exported:
    path: str
    size: int  # bytes
    alpha: float
    filter: FixedLagSavitzkyGolay
    calibration: OnlineCalibration
    channels: list[str]
    effects: list[Effect]
    tracking: SupplyTracking | None
    residual: str
    observer: MonitorObserver | None
    events: EventSettings  # those of the residual the monitor runs
    observer_note: str = ""  # why the file carries no observer
    combined_scale: float = 0.0  # κ of the combined detector (0: not carried)
    combined_note: str = ""  # why the file carries no combined detector


def calibration_data(identified: IdentifiedModel, model: RobotModel, data: Sequence[str],
                     windows: Sequence[tuple[float | None, float | None] | None] = (),
                     data_payloads: Sequence[dict | None] = ()) -> tuple[list[Dataset], str]:
    """The contact-free data Λ and T²_α come from: `data` (each in its window and with its known payload, if given),
    else what the model was fitted on (checked by sha256), each run with the payload the fit was told it carried."""
    options: list[tuple[tuple[float | None, float | None], str]] = []
    payloads: list[dict | None] = []  # the known payload each fitted run carried (a loaded run of a pair)
    if data:
        paths = list(data)
        digests = [data_digest(p) for p in paths]
        missing = next((p for p, d in zip(paths, digests) if d is None), None)
        if missing is not None:
            raise DataError(f"{missing}: no such data (a file, a `dynid simulate` directory, a yarpdatadumper folder, "
                            "a ROS 2 bag or a folder of files)")
        own = list(windows) + [None] * (len(paths) - len(windows))
        options = [(w or (None, None), DEFAULT_POLICY) for w in own]
        payloads = list(data_payloads) + [None] * (len(paths) - len(data_payloads))
    else:
        if not identified.data:
            raise DataError(f"{identified.path} names no identification data; pass --data")
        paths, digests = [], []
        for entry in identified.data:
            digest = data_digest(entry.path)
            if digest is None:
                raise DataError(f"the identification data {entry.path} are gone; pass the contact-free data with --data")
            if entry.sha256 is None:
                raise DataError(f"{identified.path} holds no sha256 of its identification data {entry.path} (a "
                                "model fitted in Python, or by an older dynid); pass the contact-free data with --data")
            if digest != entry.sha256:
                raise DataError(f"the identification data {entry.path} changed since the fit (sha256); pass --data")
            paths.append(entry.path)
            digests.append(digest)
            # the fit's --from/--to and --bad-rows skip, if it had them
            options.append((entry.reload_window, entry.bad_rows_policy))
            payloads.append(entry.payload_dict)
    runs = [load_run(p, model, window, payload, bad_rows=policy)
            for p, (window, policy), payload in zip(paths, options, payloads)]
    return runs, ",".join(str(d) for d in digests)


WRONG_WAY = ("gravity", "distal_mass")  # dynid.identify.plausibility: what gravity given the wrong way gives


def export_model(identified: IdentifiedModel, out: str | Path, settings: ExportSettings = ExportSettings()) -> Exported:
    """Calibrate the monitor's T² on contact-free data through its fixed-lag filter and write the coefficient file
    atomically."""
    model = identified.robot_model
    if model.config.gravity_imu:  # the coefficient file and the monitor's core hold one gravity vector
        raise DataError(f"{model.config.name} takes gravity per sample from the accelerometer at "
                        f"{model.config.gravity_imu}; the monitor takes it constant: export a configuration with a "
                        "constant 'gravity' (the base held still) instead")
    # A fit under gravity given the wrong way (or the inputs' sign turned) predicts with the right magnitudes and the
    # wrong signs: its Λ comes out 3-50 times too wide and the monitor needs about three times the force to see a
    # contact (a walkthrough on the Panda), with no fault. `fit` warns of it; the monitor's file is refused.
    wrong_way = [p for p in identified.plausibility or () if p.get("problem") in WRONG_WAY]
    if wrong_way:
        raise DataError(f"{identified.path or 'the model'}: {wrong_way[0]['text']}; a monitor on this model would see "
                        "contacts only far above its noise: fit again with gravity's direction and the inputs' sign "
                        "checked in the configuration")
    effects = identified.effects
    check_monitor_supports(model, effects)  # before any data is read: a robot the core cannot run is refused at once
    exportable_effects(effects)  # before the (slow) calibration: an effect the monitor lacks is refused at once
    originals, calibration_digest = calibration_data(identified, model, settings.data, settings.data_windows,
                                                     settings.data_payloads)
    # A log that misses samples (the Panda's: 54 times in 21 s) as the monitor takes it: short gaps bridged, the run
    # cut at longer ones (its filter restarts there)
    # The period is the bus's where the runs' median step agrees with its rate: the monitor's samples come at it
    pieces = [(piece, origin, run) for run, ds in enumerate(originals)
              for piece, origin in uniform_pieces(ds, sample_period(model, ds))]
    longest = max(pieces, key=lambda p: p[0].n_samples)
    est = estimator_for(model, longest[0].t, settings.lag, settings.window,
                        sample_period(model, originals[longest[2]]))
    kept = [p for p in pieces if p[0].n_samples >= est.window + 1]
    if not kept:
        raise DataError(f"no stretch of the calibration data without a gap is longer than the filter's window "
                        f"({est.window} samples)")
    datasets, origins, runs = [p[0] for p in kept], [p[1] for p in kept], [p[2] for p in kept]
    check_window(est)  # before the calibration: a window the monitor cannot hold is refused at once
    for ds in originals[1:]:
        if abs(ds.median_step() - originals[0].median_step()) > 1e-3 * originals[0].median_step():
            raise DataError("the calibration data have different sample rates")
    alpha = identified.alpha if settings.alpha is None else settings.alpha
    min_speed = identified.calibration_min_speed
    tracking = identified.supply_tracking
    residual = settings.residual or ("acceleration" if effects else "combined")
    if residual != "acceleration" and effects:
        raise DataError(f"{identified.path}: an augmented model (named effects) has no momentum residual yet; export "
                        "it with --residual acceleration")
    events = settings.events_for(residual).at(est.sample_period)  # (the combined detector: the acceleration's)
    # On the runs it was fitted on, each time block's residual through the Φ fitted without it (docs/detection.md)
    folds = None if settings.data or effects else identified.folds
    cal = calibrate_online(model, identified.phi, datasets, est, alpha, min_speed, effects=effects, tracking=tracking,
                           tau_map=external_torque_map(model), folds=folds, origins=origins, runs=runs)
    detector = MonitorDetector(cal.variance, cal.threshold, cal.ft_thresholds, alpha, min_speed, cal.samples, events,
                               cal.tau_variance)
    observer, note = None, "an augmented model's effects have no momentum form yet" if effects else ""
    if not effects:
        try:
            observer = monitor_observer(identified, originals, alpha, min_speed, settings)  # the observer takes stamps
        except DataError as e:  # the acceleration residuals the monitor runs do not need it: said, not fatal
            if settings.residual in ("momentum", "combined") or settings.bandwidth_hz != DEFAULT_BANDWIDTH_HZ:
                raise  # asked for (a residual, or a bandwidth of the user's): its failure is the command's
            note = str(e)
    scale, combined_note = 0.0, note or "no observer"
    if observer is not None:
        try:
            scale = monitor_combined_scale(identified, kept, observer, detector, est, settings)
            combined_note = ""
        except DataError as e:
            if settings.residual == "combined":
                raise
            combined_note = str(e)
    if residual == "combined" and not scale:
        residual = "acceleration"  # the default, where the combined detector cannot be calibrated: said
    provenance = Provenance(file_digest(identified.path) if identified.path else "", calibration_digest,
                            identified.estimator or "")
    fit_range = fit_ranges(identified, model.config.joints)
    c = build_coefficients(model, identified.phi, detector, est, provenance, effects, tracking, observer, residual,
                           scale, fit_range)
    if observer is not None and settings.residual in (None, "acceleration"):
        try:
            check_plausible(c)
        except Implausible as e:  # an observer calibrated on too little: dropped, said; the file is checked again
            residual = "acceleration"  # (the same event settings as the combined detector's)
            without = build_coefficients(model, identified.phi, detector, est, provenance, effects, tracking, None,
                                         residual, fit_range=fit_range)
            check_plausible(without)
            c, observer, note = without, None, f"its calibration is implausible ({e})"
            scale, combined_note = 0.0, note
    known_answers.attach(c, identified, datasets, effects)  # what the monitor checks its core against at load
    size = write_coefficients(c, out)
    return Exported(str(out), size, alpha, est, cal, list(c.channel_names), effects, tracking, residual, observer,
                    events, note, scale, combined_note)


def sample_period(model: RobotModel, ds: Dataset) -> float:
    """The monitor's sample period for a run: the robot's bus's nominal one where its rate agrees with the run's
    median step (dynid.config.bus.BusDescription.nominal_period), else that median."""
    bus = model.config.bus
    return ds.median_step() if bus is None else bus.nominal_period(ds.median_step())


def monitor_combined_scale(identified: IdentifiedModel, pieces: Sequence, observer: MonitorObserver,
                           detector: MonitorDetector, est: FixedLagSavitzkyGolay, settings: ExportSettings) -> float:
    """κ of the combined detector as the monitor runs it (dynid.detect.combined): both normalised statistics on the
    observer's calibration samples, the acceleration residuals' through the monitor's filter and causal supply
    tracker at the same tick, cross-validated on the runs the model was fitted on. On the runs as the monitor takes
    them (`pieces`: (piece, its rows' original indices, its run) of uniform_pieces, short gaps bridged, a run cut at
    a long one, where both residuals start over), each piece's samples through the fold Φ of their original ones."""
    model = identified.robot_model
    det_c = Detector("calibrated", np.asarray(detector.variance, float), float(detector.threshold), detector.alpha,
                     detector.min_speed, len(detector.variance))
    folds = None if settings.data or identified.folds is None else PieceFolds(
        identified.folds, [p[1] for p in pieces], [p[2] for p in pieces])
    return calibrate_combined(identified, observer.detector, det_c, [p[0] for p in pieces], folds,
                              measured=observer.measured, est=est).scale


def monitor_observer(identified: IdentifiedModel, datasets: Sequence[Dataset], alpha: float, min_speed: float,
                     settings: ExportSettings) -> MonitorObserver:
    """The momentum detector calibrated as the monitor will run it, on the runs `dynid detect` would calibrate on: q̇
    the robot's own where its bus carries every joint's (dq.J) and the runs hold it, as `dynid detect` takes it; else
    estimated causally from q, as the monitor then does."""
    model, phi = identified.robot_model, identified.phi
    measured = bus_carries_velocity(model) and all(measured_velocity(model, ds) is not None for ds in datasets)
    # the fit's own calibration where it matches (the model file's `observer` section), else calibrate now
    det = None if settings.data else stored_detector(identified, "detect" if measured else "monitor", alpha,
                                                     settings.bandwidth_hz, VELOCITY_WINDOW_S, min_speed=min_speed)
    if det is None:
        det = calibrate_momentum(model, phi, identified.base, datasets, alpha, min_speed, settings.bandwidth_hz,
                                 tracking=identified.supply_tracking, measured=measured,
                                 folds=None if settings.data else identified.folds)
    band = friction_band(model, phi, identified.base, det.band_sigmas)
    return MonitorObserver(det, velocity_window_samples(datasets[0].t, det.velocity_window_s), band, measured)


def bus_carries_velocity(model: RobotModel) -> bool:
    """The robot's bus description carries every joint's measured q̇ (a dq.J signal each)."""
    bus = model.config.bus
    return bus is not None and all(f"dq.{j}" in bus.targets() for j in model.config.joints)


def export_cad(config: RobotConfig, out: str | Path, settings: ExportSettings = ExportSettings()) -> int:
    """The CAD model with nominal gains and no friction or offsets, Λ = the channels' noise σ², the F threshold,
    sampled at `settings.cad_rate_hz`; returns the file's size."""
    model = RobotModel(config)
    phi = np.nan_to_num(model.cad_parameters(), nan=0.0)
    for m in model.layout.owners("motor_gain"):
        phi[model.layout.block("motor_gain", m).start] = config.motor(m).nominal_gain
    outs = output_channels(model)
    variance = np.array([o.sigma for o in outs]) ** 2
    alpha = ALPHA if settings.alpha is None else settings.alpha
    t = np.arange(3) / settings.cad_rate_hz
    est = estimator_for(model, t, settings.lag, settings.window)
    residual = settings.residual or "acceleration"
    detector = MonitorDetector(variance, f_threshold(len(outs), CAD_SAMPLES, alpha),
                               {s.name: f_threshold(6, CAD_SAMPLES, alpha) for s in config.ft_sensors}, alpha, DEFAULT_MIN_SPEED,
                               CAD_SAMPLES, settings.events_for(residual).at(est.sample_period), cad_tau_variance(model, variance * divisors(model, phi) ** 2))
    observer = cad_observer(model, phi, variance, alpha, t, settings.bandwidth_hz)
    check_monitor_supports(model)
    c = build_coefficients(model, phi, detector, est, Provenance(estimator="cad"), observer=observer, residual=residual)
    return write_coefficients(c, out)


def cad_tau_variance(model: RobotModel, row_variance: np.ndarray) -> np.ndarray:
    """τ_ext = −L⁻¹ r per actuation group: its variance from the rows' (in row units), for an uncalibrated export."""
    tau_variance = np.ones(len(model.config.joints))
    for g, gj, r in group_rows(model):
        Li = np.linalg.inv(group_row_maps(g)[0])
        tau_variance[gj] = Li**2 @ row_variance[r]
    return tau_variance


def cad_observer(model: RobotModel, phi: np.ndarray, variance: np.ndarray, alpha: float, t: np.ndarray,
                 bandwidth_hz: float) -> MonitorObserver:
    """An uncalibrated observer for the CAD export: Λ the channels' noise in row units (σ·gain on a motor row),
    χ² thresholds, no friction band."""
    row_variance = variance * divisors(model, phi) ** 2
    tau_variance = cad_tau_variance(model, row_variance)
    det = MomentumDetector(bandwidth_hz, row_variance, tau_variance,
                           chi2_quantile(alpha, row_variance.size), alpha, DEFAULT_MIN_SPEED, 0.0,
                           {s.name: chi2_quantile(alpha, 6) for s in model.config.ft_sensors}, CAD_SAMPLES)
    return MonitorObserver(det, velocity_window_samples(t), friction_band(model, phi, None, 0.0))
