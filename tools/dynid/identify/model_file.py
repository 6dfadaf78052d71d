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
from ..errors import DataError, InputError
from ..io.dataset import SIMULATION_DATASET, atomic_write
from ..robot.effects import finite_number, parse_effects
from ..robot.model import RobotModel
from .model_schema import check_sections
from .supply import SupplyTracking

FORMAT_NAME = "dynid-model"
FORMAT_VERSION = 2  # 2: an `effects` section; files without one are still written as 1


@dataclass
class IdentifiedModel:
    robot: dict[str, Any]
    parameters: dict[str, float]
    record: dict[str, Any] = field(default_factory=dict)  # every other section, as in the file
    path: str | None = None
    _config: RobotConfig | None = None
    _model: RobotModel | None = None

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
            raise DataError(f"model file lacks parameter '{missing[0]}' of {self.robot['name']}")
        return np.array([self.parameters[n] for n in names], dtype=float)

    @property
    def effects(self) -> list:  # list[dynid.robot.effects.Effect]

        return parse_effects(self.record.get("effects"), self.robot_model, self.path or "model file")

    @property
    def supply_tracking(self):  # dynid.identify.supply.SupplyTracking | None
        """The input channels' supply tracking, None for a model fitted without it (or by an earlier dynid)."""
        d = self.record.get("supply_tracking")
        if d is None:
            return None
        try:
            return SupplyTracking.from_dict(d)
        except (KeyError, TypeError, ValueError, OverflowError, InputError) as e:  # OverflowError: a huge integer
            raise DataError(f"{self.path or 'model file'}: bad supply_tracking section: {e}") from None

    @property
    def min_speed(self) -> float:
        return float(self.record.get("settings", {}).get("min_speed", 0.01))

    @property
    def output_channels(self) -> list[str]:
        return list(self.record["outputs"]["channels"])

    @property
    def residual_variance(self) -> np.ndarray:
        return np.asarray(self.record["outputs"]["residual_variance"], dtype=float)

    def base_values(self, parameters: dict[str, float]) -> np.ndarray:
        """β of any full parameter set (CAD, truth) in this fit's base combinations."""
        b = self.record["base"]
        ind = np.array([parameters[n] for n in b["independent"]], dtype=float)
        dep = np.array([parameters[n] for n in b["dependent"]], dtype=float)
        return ind + (np.asarray(b["K"], dtype=float).reshape(len(ind), len(dep)) @ dep if len(dep) else 0.0)

    def to_json(self) -> dict[str, Any]:
        version = FORMAT_VERSION if self.record.get("effects") else 1
        return {"format": FORMAT_NAME, "format_version": version, "robot": self.robot,
                "parameters": self.parameters, **self.record}

    def save(self, path: str | Path) -> None:
        """Write the model file atomically; one that every command would refuse (check_values) is never written."""
        data = self.to_json()
        check_values(data, str(path))
        text = json.dumps(data, indent=1, allow_nan=False) + "\n"
        atomic_write(Path(path), lambda f: f.write(text.encode()))
        self.path = str(path)


def _config_from(robot: dict[str, Any]) -> RobotConfig:
    """The configuration the model was fitted for (its source if unchanged, else the embedded text), which must be
    the robot the file names: an edited name used to pass, and export wrote another robot's monitor file."""
    config = _config_of(robot)
    if config.name != robot["name"]:
        raise DataError(f"the model file names robot '{robot['name']}', but the configuration it embeds is "
                        f"{config.name}'s")
    return config


def _config_of(robot: dict[str, Any]) -> RobotConfig:
    source = robot.get("config_source", "")
    urdf = robot.get("urdf")  # the URDF it was fitted with (a supplied one is not found again without it)
    urdf = urdf if urdf and Path(urdf).is_file() else None
    try:
        config = load_config(source, urdf)
        if config.digest == robot["config_digest"]:
            return _with_noise(config, robot)
    except Exception:  # noqa: BLE001 - a moved or edited source falls back to the embedded copy below
        pass
    text = robot.get("config_text")
    if not text or hashlib.sha256(text.encode()).hexdigest() != robot["config_digest"]:
        raise DataError(f"the model's robot configuration '{source}' changed or is gone, and no intact copy is embedded")
    directory = Path(source).parent if Path(source).is_file() else None
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", dir=directory, delete=False, encoding="utf-8") as f:
        f.write(text)
    try:
        return _with_noise(load_config(f.name, urdf), robot)
    finally:
        Path(f.name).unlink(missing_ok=True)


def robot_record(config: RobotConfig) -> dict[str, Any]:
    return {"name": config.name, "config_digest": config.digest, "config_source": config.source,
            "config_text": Path(config.source).read_text(encoding="utf-8"), "urdf": str(config.urdf.resolve()),
            "noise_per_channel": dict(config.noise.per_channel)}


def _with_noise(config: RobotConfig, robot: dict[str, Any]) -> RobotConfig:
    """The configuration with the per-channel noise the model was fitted with (estimated by `fit --noise
    estimate`, or the configuration's own)."""
    per = robot.get("noise_per_channel")
    if not per:
        return config
    return replace(config, noise=replace(config.noise, per_channel={k: float(v) for k, v in per.items()}))


def load_model(path: str | Path) -> IdentifiedModel:
    """Read and check a model file; any problem is a `DataError` naming it."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"model file not found: {path}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    # ValueError covers JSONDecodeError, UnicodeDecodeError and an integer of more than 4300 digits; RecursionError
    # arrays nested thousands deep.
    except (ValueError, RecursionError) as e:
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
    record = {k: v for k, v in data.items() if k not in ("format", "format_version", "robot", "parameters")}
    return IdentifiedModel(data["robot"], {k: float(v) for k, v in params.items()}, record, str(path))


MAX_BODY_MASS = 1000.0  # kg: rt_monitor/include/rt_monitor/plausibility.hpp's kMaxMass (no robot link weighs more)


def check_values(data: dict[str, Any], path: str) -> None:
    """Values no model can hold, refused by every command in one line (issue 31): a motor gain that is not positive
    (the PWM or current would have to be infinite, or of the wrong sign, to move the motor), a body mass beyond any
    robot link's, a detector's Λ or threshold that is not positive (T² would be NaN, or above it on every sample)."""
    for name, v in data["parameters"].items():
        if name.endswith(".phi_m") and not v > 0:
            raise DataError(f"{path}: motor {name[: -len('.phi_m')]}'s gain is {v:g}: a motor gain must be positive "
                            "(refit on a run that moves that motor, or give its known gain in the configuration)")
        if name.endswith(".m") and not abs(v) <= MAX_BODY_MASS:
            raise DataError(f"{path}: {name} is {v:g} kg, beyond any robot link's ({MAX_BODY_MASS:g} kg): an edited or "
                            "damaged model file")
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
    bag folder's files (dynid.io.rosbag.bag_digest), or a yarpdatadumper folder's `data.log` files (each with its
    path in the folder, in sorted order); None where there are no such data."""
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
    return None


def data_record(path: str | Path, samples: int, duration_s: float,
                payload: dict[str, Any] | None = None, window: list[float | None] | None = None,
                bad_rows: dict[str, Any] | None = None) -> dict[str, Any]:
    """What a model file says of the data it was fitted on (export checks the sha256 before reusing them), with the
    known payload the run carried, its --from/--to window and the bad rows `--bad-rows skip` dropped (so a reload
    takes the same samples). Data that never was a file (a `Dataset` built in Python) has no path to resolve and
    no sha256."""
    digest = data_digest(path)
    out = {"path": str(path) if digest is None else str(Path(path).resolve()), "sha256": digest, "samples": samples,
           "duration_s": duration_s}
    if payload:
        out["payload"] = {"mass": float(payload["mass"]), "com": payload.get("com")}
    if window is not None and any(w is not None for w in window):
        out["window"] = [None if w is None else float(w) for w in window]
    if bad_rows:
        out["bad_rows"] = bad_rows
    return out


def run_options(entry: dict[str, Any]) -> tuple[tuple[float | None, float | None], str]:
    """The window and the bad-rows policy to reload a recorded run with (`data_record`'s window and bad_rows)."""
    window = entry.get("window") or [None, None]
    return (window[0], window[1]), "skip" if entry.get("bad_rows") else "refuse"


def file_digest(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
