"""The model file that `dynid fit` writes and validate, detect, export and gaps read.

JSON (``format: dynid-model``, ``format_version: 1``), written atomically:

    robot             {name, config_digest, config_source, config_text}: the configuration it was fitted for,
                      embedded, so the file stands alone
    parameters        {name: value}: a full Φ (layout order) that reproduces the identified base parameters;
                      combinations the data do not determine take the CAD value (inertia), the nominal motor
                      gain, or 0
    base              {rank, combinations, independent, dependent, K, values, standard_errors, identified}: the
                      base parameters β = Φ[independent] + K Φ[dependent] of the run, with jackknife standard
                      errors; `identified` is false where the run cannot determine the combination
    estimators        {ols|pls|iv: {base values, standard errors, detail}}: all three, side by side
    estimator         the regression `parameters` comes from; `settings` the fit's settings
    consistent        null (--consistent off), or the physically consistent fit's record: status, λ, the active
                      constraints, CV, solver (dynid.identify.consistent); when solved, `parameters` are its
                      projection of the estimator's, also under estimators.consistent
    n_components      PLS ν (cross-validated unless given); `cv` the held-out error for every ν
    jackknife         {folds, rank_deficient: [{block, samples [start, end), unseen}]}: the folds (one time block
                      left out) whose data miss base directions the whole run sees, and the combinations
                      involved (all reported not `identified`); empty on a run long enough
    outputs           {channels, units, noise_std, residual_variance}: Λ, per output channel, on the
                      identification data (rows at rest left out)
    derivatives       the offline derivative estimator (the configuration's)
    data              [{path, sha256, samples, duration_s, payload?, window?, bad_rows?}]: what it was fitted on
    detector          calibration for T² (added by the fit; see dynid.detect.t2)
    folds             {run, samples, parameters, in_sample}: the fit's time blocks and the Φ fitted without each;
                      the detectors are calibrated on each block's residual through its own fold's Φ
    effects           (format_version 2, written by `dynid gaps --out`) the named missing effects, refitted with
                      the standard parts (dynid.robot.effects); `gaps` what the refit was made on and its gap
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import RobotConfig, load_config
from ..errors import DataError, InputError, PathError
from ..io.dataset import SIMULATION_DATASET, atomic_write
from ..robot.effects import Effect, check_effect_targets, finite_number, parse_effects
from ..robot.model import RobotModel
from .model_schema import check_sections
from .model_sections import (BaseSection, ConsistentFit, DataRun, DetectorSection, EstimatorSection, FoldsSection,
                             GapsSection, OutputsSection, Payload, RobotSection, Settings, T2Calibration, section)
from .observer_sections import ObserverSection
from .supply import SupplyTracking

FORMAT_NAME = "dynid-model"
FORMAT_VERSION = 2  # 2: an `effects` section; files without one are still written as 1


@dataclass
class IdentifiedModel:
    """A model file in memory: one typed section per part of the file (dynid.identify.model_sections), read by
    attribute. `load_model` builds it from the JSON once; `to_json` writes it back as `dynid fit` writes it."""

    robot: RobotSection
    parameters: dict[str, float]
    outputs: OutputsSection | None = None  # None only while dynid.pipeline.build_model has not calibrated it yet
    settings: Settings = field(default_factory=Settings)
    estimator: str | None = None  # the regression `parameters` come from ("gaps" for an augmented model)
    n_components: int | None = None  # PLS ν (cross-validated unless given)
    cv: dict[str, Any] | None = None  # the held-out error for every ν
    jackknife: dict[str, Any] | None = None  # the folds of the block jackknife and those that miss a direction
    consistent: ConsistentFit | None = None  # None: `--consistent off`
    base: BaseSection | None = None
    estimators: dict[str, EstimatorSection] = field(default_factory=dict)
    cad_ft_offsets: np.ndarray | None = None  # the F/T offsets fitted beside the CAD inertias (Table II's CAD column)
    supply_tracking: SupplyTracking | None = None  # None: constant motor gains (or a model of an earlier dynid)
    detector: DetectorSection | None = None
    derivatives: dict[str, Any] | None = None  # the offline derivative estimator (the configuration's)
    data: tuple[DataRun, ...] = ()
    observer: ObserverSection | None = None
    folds: FoldsSection | None = None  # the Φ fitted without each time block (None: an older file, or gaps' refit)
    fit_time_s: float | None = None
    plausibility: list[dict[str, Any]] | None = None
    named_effects: tuple[Effect, ...] | None = None  # `effects` as written (format_version 2); `effects` checks them
    gaps: GapsSection | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # sections this dynid does not know, written back unchanged
    path: str | None = None
    _config: RobotConfig | None = field(default=None, repr=False)
    _model: RobotModel | None = field(default=None, repr=False)

    @property
    def config(self) -> RobotConfig:
        if self._config is None:
            try:
                self._config = _config_from(self.robot)
            except DataError as e:
                raise DataError(f"{self.path}: {e}" if self.path else str(e)) from None
        return self._config

    @property
    def robot_model(self) -> RobotModel:
        if self._model is None:
            self._model = RobotModel(self.config)
        return self._model

    @property
    def phi(self) -> np.ndarray:
        names = self.robot_model.layout.names
        missing = [n for n in names if n not in self.parameters]
        if missing:
            raise DataError(f"model file lacks parameter '{missing[0]}' of {self.robot.name}")
        return np.array([self.parameters[n] for n in names], dtype=float)

    @property
    def effects(self) -> list[Effect]:
        """The named effects of an augmented model (`dynid gaps --out`), each checked to act on this robot."""
        return check_effect_targets(list(self.named_effects or ()), self.robot_model, self.path or "model file")

    @property
    def min_speed(self) -> float:
        return self.settings.min_speed

    @property
    def output_channels(self) -> list[str]:
        return list(self._outputs.channels)

    @property
    def residual_variance(self) -> np.ndarray:
        return self._outputs.residual_variance

    @property
    def _outputs(self) -> OutputsSection:
        if self.outputs is None:
            raise DataError(f"{self.path or 'model'}: model file lacks its 'outputs' section")
        return self.outputs

    @property
    def calibrated(self) -> T2Calibration | None:
        """The calibrated T² detector of the fit; None in a file without a `detector` section."""
        return None if self.detector is None else self.detector.calibrated

    @property
    def alpha(self) -> float:
        """The confidence level the model's detectors were calibrated at (its settings' without a detector)."""
        return self.settings.alpha if self.calibrated is None else self.calibrated.alpha

    @property
    def calibration_min_speed(self) -> float:
        """The min speed the model's detectors were calibrated with (its settings' without a detector)."""
        return self.settings.min_speed if self.calibrated is None else self.calibrated.min_speed

    @property
    def data_paths(self) -> list[str]:
        return [run.path for run in self.data]

    def base_values(self, parameters: dict[str, float]) -> np.ndarray:
        """β of any full parameter set (CAD, truth) in this fit's base combinations."""
        if self.base is None:
            raise DataError(f"{self.path or 'model'}: model file lacks its 'base' section")
        return self.base.base_values(parameters)

    def to_json(self) -> dict[str, Any]:
        version = FORMAT_VERSION if self.named_effects else 1
        sections: list[tuple[str, Any]] = [
            ("estimator", self.estimator), ("settings", self.settings.to_json()), ("n_components", self.n_components),
            ("cv", self.cv), ("jackknife", self.jackknife),
            ("base", None if self.base is None else self.base.to_json()),
            ("estimators", {k: v.to_json() for k, v in self.estimators.items()} or None),
            ("cad_ft_offsets", _plain(self.cad_ft_offsets)),
            ("outputs", None if self.outputs is None else self.outputs.to_json()),
            ("detector", None if self.detector is None else self.detector.to_json()),
            ("derivatives", self.derivatives), ("data", [run.to_json() for run in self.data] or None),
            ("observer", None if self.observer is None else self.observer.to_json()),
            ("folds", None if self.folds is None else self.folds.to_json()),
            ("fit_time_s", self.fit_time_s), ("plausibility", self.plausibility),
            ("effects", None if self.named_effects is None else [e.as_dict() for e in self.named_effects]),
            ("gaps", None if self.gaps is None else self.gaps.to_json())]
        out = {"format": FORMAT_NAME, "format_version": version, "robot": self.robot.to_json(),
               "parameters": self.parameters, **{k: v for k, v in sections if v is not None}}
        # null is what these say when off (`--consistent off`, `--supply-time-constant 0`)
        out["consistent"] = None if self.consistent is None else self.consistent.to_json()
        out["supply_tracking"] = None if self.supply_tracking is None else self.supply_tracking.as_dict()
        return {**out, **self.extra}

    def save(self, path: str | Path) -> None:
        """Write the model file atomically; one that every command would refuse (check_values) is never written."""
        data = self.to_json()
        check_values(data, str(path), fitted=True)
        text = json.dumps(data, indent=1, allow_nan=False) + "\n"
        atomic_write(Path(path), lambda f: f.write(text.encode()))
        self.path = str(path)


def _plain(array: np.ndarray | None) -> list | None:
    return None if array is None else np.asarray(array).tolist()


def _config_from(robot: RobotSection) -> RobotConfig:
    """The configuration the model was fitted for (its source if unchanged, else the embedded text), which must be
    the robot the file names: an edited name used to pass, and export wrote another robot's monitor file."""
    config = _config_of(robot)
    if config.name != robot.name:
        raise DataError(f"the model file names robot '{robot.name}', but the configuration it embeds is "
                        f"{config.name}'s")
    return _check_urdf(config, robot)


def _config_of(robot: RobotSection) -> RobotConfig:
    source = robot.config_source
    urdf = robot.urdf if robot.urdf and Path(robot.urdf).is_file() else None  # a supplied one is found through it
    try:
        config = load_config(source, urdf)
        if config.digest == robot.config_digest:
            return _with_noise(config, robot)
    except Exception:  # noqa: BLE001 - a moved or edited source falls back to the embedded copy below
        pass
    text = robot.config_text
    if not text or hashlib.sha256(text.encode()).hexdigest() != robot.config_digest:
        raise DataError(f"the model's robot configuration '{source}' changed or is gone, and no intact copy is embedded")
    directory = Path(source).parent if Path(source).is_file() else None
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", dir=directory, delete=False, encoding="utf-8") as f:
        f.write(text)
    try:
        return _with_noise(load_config(f.name, urdf), robot)
    finally:
        Path(f.name).unlink(missing_ok=True)


def robot_record(config: RobotConfig) -> RobotSection:
    return RobotSection(config.name, config.digest, config.source, Path(config.source).read_text(encoding="utf-8"),
                        str(config.urdf.resolve()), dict(config.noise.per_channel),
                        urdf_sha256=hashlib.sha256(config.urdf.read_bytes()).hexdigest())


def _check_urdf(config: RobotConfig, robot: RobotSection) -> RobotConfig:
    """`config` if its URDF is the one the model was fitted with (its bytes' sha256), else DataError: Φ is of that
    URDF's bodies, and another one (edited, or the configuration's own where the fitted one is gone) would
    silently change every prediction. A file written before the digest was kept is taken as it is."""
    if robot.urdf_sha256 is None or robot.urdf is None:  # what a file does not record is not checked
        return config
    found = hashlib.sha256(config.urdf.read_bytes()).hexdigest() if config.urdf.is_file() else None
    if found != robot.urdf_sha256:
        now = f"{config.urdf} is another file (sha256 {found[:12]}…)" if found else f"{config.urdf} is not found"
        raise DataError(f"the model was fitted with the URDF {robot.urdf} (sha256 {robot.urdf_sha256[:12]}…), and "
                        f"{now}: put the fitted one back (at that path, or in DYNID_URDF_PATH for a supplied URDF), or "
                        "fit again on this one")
    return config


def _with_noise(config: RobotConfig, robot: RobotSection) -> RobotConfig:
    """The configuration with the per-channel noise the model was fitted with (estimated by `fit --noise
    estimate`, or the configuration's own)."""
    per = robot.noise_per_channel
    if not per:
        return config
    return replace(config, noise=replace(config.noise, per_channel=dict(per)))


def load_model(path: str | Path) -> IdentifiedModel:
    """Read and check a model file; any problem is a `DataError` naming it."""
    path = Path(path)
    if not path.is_file():
        raise PathError(f"model file not found: {path}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    # ValueError covers JSONDecodeError, UnicodeDecodeError and an integer of more than 4300 digits; RecursionError
    # arrays nested thousands deep.
    except (ValueError, RecursionError) as e:
        with open(path, "rb") as f:
            if f.read(8) == b"DYNIDCOF":  # dynid.export.coefficients.MAGIC (that layer is above this one)
                raise DataError(f"{path}: a coefficient file (dynid export's, for rt_monitor), not a model file: give "
                                "the model.json it was exported from") from None
        raise DataError(f"{path}: not a dynid model file (not JSON: {e.__class__.__name__})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        raise DataError(f"{path}: not a dynid model file (no 'format: {FORMAT_NAME}')")
    version = data.get("format_version")
    if isinstance(version, int) and not isinstance(version, bool) and version > FORMAT_VERSION:
        raise DataError(f"{path}: model format version {version!r} is newer than this dynid reads ({FORMAT_VERSION})")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise DataError(f"{path}: model format version {version!r} is not a version (1..{FORMAT_VERSION})")
    for key in ("robot", "parameters", "outputs"):
        if key not in data:
            raise DataError(f"{path}: model file lacks its '{key}' section")
    params = data["parameters"]
    if not isinstance(params, dict) or not all(finite_number(v) for v in params.values()):
        raise DataError(f"{path}: every parameter must be a finite number")
    _check_sections(data, path)
    check_sections(data, str(path))
    check_values(data, str(path))
    return model_from_json(data, str(path))


# The top-level sections and how each is built; the JSON's types are checked before (model_schema.check_sections)
_BUILDERS: dict[str, Any] = {
    "settings": Settings.from_json, "estimator": str, "n_components": int, "cv": dict, "jackknife": dict,
    "consistent": ConsistentFit.from_json, "base": BaseSection.from_json,
    "estimators": lambda d: {k: EstimatorSection.from_json(v) for k, v in d.items()},
    "cad_ft_offsets": lambda v: np.asarray(v, float), "supply_tracking": SupplyTracking.from_dict,
    "outputs": OutputsSection.from_json, "detector": DetectorSection.from_json, "derivatives": dict,
    "data": lambda runs: tuple(DataRun.from_json(r) for r in runs), "observer": ObserverSection.from_json,
    "folds": FoldsSection.from_json,
    "fit_time_s": float, "plausibility": list, "effects": parse_effects, "gaps": GapsSection.from_json,
}


def model_from_json(data: dict[str, Any], path: str = "model file") -> IdentifiedModel:
    """The typed model of a checked model-file document; a value no section can hold is one line (DataError)."""
    kwargs: dict[str, Any] = {}
    for key, build in _BUILDERS.items():
        if data.get(key) is None:
            continue
        if key == "effects":
            kwargs["named_effects"] = tuple(parse_effects(data[key], path))
            continue
        if key == "supply_tracking":  # its own checks raise InputError: the model file is the bad input here
            try:
                kwargs[key] = SupplyTracking.from_dict(data[key])
            except (KeyError, TypeError, ValueError, OverflowError, InputError) as e:
                raise DataError(f"{path}: bad supply_tracking section: {e}") from None
            continue
        kwargs[key] = section(key, build, data[key], path)
    known = {"format", "format_version", "robot", "parameters", *_BUILDERS}
    extra = {k: v for k, v in data.items() if k not in known}
    return IdentifiedModel(section("robot", RobotSection.from_json, data["robot"], path),
                           {k: float(v) for k, v in data["parameters"].items()}, **kwargs, extra=extra, path=path)


MAX_BODY_MASS = 1000.0  # kg: rt_monitor/include/rt_monitor/plausibility.hpp's kMaxMass (no robot link weighs more)


def check_values(data: dict[str, Any], path: str, fitted: bool = False) -> None:
    """Values no model can hold, refused by every command in one line (issue 31): a motor gain that is not positive
    (the PWM or current would have to be infinite, or of the wrong sign, to move the motor), a body mass beyond any
    robot link's, a detector's Λ or threshold that is not positive (T² would be NaN, or above it on every sample).
    `fitted`: the model a fit is about to write, whose values come from the data, not from an edit."""
    for name, v in data["parameters"].items():
        if name.endswith(".phi_m") and not v > 0:
            raise DataError(f"{path}: motor {name[: -len('.phi_m')]}'s gain is {v:g}: a motor gain must be positive "
                            "(refit on a run that moves that motor, or give its known gain in the configuration)")
        if name.endswith(".m") and not abs(v) <= MAX_BODY_MASS:
            why = ("the fit gives it from these data, so they do not fit the configuration as declared (F/T sensors' "
                   "ports swapped, gravity's direction, a unit?): nothing is written" if fitted else
                   "an edited or damaged model file")
            raise DataError(f"{path}: {name} is {v:g} kg, beyond any robot link's ({MAX_BODY_MASS:g} kg): {why}")
    detectors = data.get("detector")
    for variant, d in (detectors.items() if isinstance(detectors, dict) else ()):
        if not isinstance(d, dict):
            continue
        variance = d.get("variance")
        if isinstance(variance, list) and not all(finite_number(x) and x > 0 for x in variance):
            raise DataError(f"{path}: detector.{variant}.variance must be positive on every channel (Λ of T²)")
        threshold = d.get("threshold")
        if threshold is not None and not (finite_number(threshold) and threshold > 0):
            raise DataError(f"{path}: detector.{variant}.threshold is {threshold}: T²_α must be a positive number")


def _check_sections(data: dict[str, Any], path: Path) -> None:
    """The types of what `IdentifiedModel`'s properties read, checked once at load: an edited or damaged section is
    one line naming it here, not a KeyError or AttributeError in the middle of a command."""
    robot = data["robot"]
    if not isinstance(robot, dict) or not all(isinstance(robot.get(k), str) for k in ("name", "config_digest",
                                                                                      "config_source")):
        raise DataError(f"{path}: section 'robot' needs its name, config_digest and config_source as text")
    for key in ("config_text", "urdf"):
        if robot.get(key) is not None and not isinstance(robot[key], str):
            raise DataError(f"{path}: robot.{key} must be text")
    noise = robot.get("noise_per_channel")
    if noise is not None and not (isinstance(noise, dict) and all(finite_number(v) for v in noise.values())):
        raise DataError(f"{path}: robot.noise_per_channel must map channels to numbers")
    outputs = data["outputs"]
    channels = outputs.get("channels") if isinstance(outputs, dict) else None
    variance = outputs.get("residual_variance") if isinstance(outputs, dict) else None
    if not (isinstance(channels, list) and channels and all(isinstance(c, str) and c for c in channels)):
        raise DataError(f"{path}: outputs.channels must be a list of channel names")
    if not (isinstance(variance, list) and len(variance) == len(channels) and all(finite_number(v) for v in variance)):
        raise DataError(f"{path}: outputs.residual_variance must hold one finite number per channel "
                        f"({len(channels)})")
    settings = data.get("settings", {})
    if not isinstance(settings, dict) or not finite_number(settings.get("min_speed", 0.0)):
        raise DataError(f"{path}: section 'settings' must be a mapping, its min_speed a number")


def data_digest(path: str | Path) -> str | None:
    """sha256 of the data behind a DATA argument: a file's bytes, a `dynid simulate` directory's dataset, a ROS 2
    bag folder's files (dynid.io.rosbag.bag_digest), a yarpdatadumper folder's `data.log` files (each with its
    path in the folder, in sorted order), or any other folder's own files (by name, sorted: a logger's folder of
    files); None where there are no such data."""
    from ..io.rosbag import bag_digest, is_bag
    from ..io.yarp import is_dumper_folder

    p = Path(path)
    if p.is_file():
        return file_digest(p)
    if is_bag(p):
        return bag_digest(p)
    if (p / SIMULATION_DATASET).is_file():
        return file_digest(p / SIMULATION_DATASET)
    if is_dumper_folder(p):
        h = hashlib.sha256()
        for log in sorted(p.glob("**/data.log")):
            h.update(log.relative_to(p).as_posix().encode() + b"\0" + file_digest(log).encode())
        return h.hexdigest()
    files = sorted(f for f in p.iterdir() if f.is_file()) if p.is_dir() else []
    if files:  # a logger's folder of files (the configuration's `files:`, dynid.io.file_set): each, by name
        h = hashlib.sha256()
        for f in files:
            h.update(f.name.encode() + b"\0" + file_digest(f).encode())
        return h.hexdigest()
    return None


def data_record(path: str | Path, samples: int, duration_s: float,
                payload: dict[str, Any] | None = None, window: list[float | None] | None = None,
                bad_rows: dict[str, Any] | None = None, joint_range_deg: dict[str, list[float]] | None = None) -> DataRun:
    """What a model file says of the data it was fitted on (export checks the sha256 before reusing them), with the
    known payload the run carried, its --from/--to window and the bad rows `--bad-rows skip` dropped (so a reload
    takes the same samples), and each joint's range over it (degrees). Data that never was a file (a `Dataset` built in Python) has no path to resolve and
    no sha256."""
    digest = data_digest(path)
    has_window = window is not None and any(w is not None for w in window)
    return DataRun(str(path) if digest is None else str(Path(path).resolve()), digest, samples, duration_s,
                   Payload(float(payload["mass"]), None if payload.get("com") is None else
                           tuple(float(c) for c in payload["com"])) if payload else None,  # type: ignore[arg-type]
                   tuple(None if w is None else float(w) for w in window) if has_window else None,  # type: ignore[union-attr,arg-type]
                   bad_rows or None, joint_range_deg)


def file_digest(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
