"""Where a robot configuration's URDF is: a path beside it, a model of icub-models, a file inside an installed pip
distribution, or one the user supplies (found in DYNID_URDF_PATH)."""

from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path

from ..errors import ConfigError
from .fields import Fields


URDF_PATH_ENV = "DYNID_URDF_PATH"  # directories searched for a `urdf: {supplied: FILE}` (os.pathsep-separated)


def _supplied_urdf(spec: Fields, name: str) -> Path:
    """A URDF dynid does not ship (its licence, or the robot's owner, keeps it out): found in DYNID_URDF_PATH."""
    for folder in os.environ.get(URDF_PATH_ENV, "").split(os.pathsep):
        if folder and (Path(folder) / name).is_file():
            return Path(folder) / name
    raise spec.fail(
        "supplied",
        f"names '{name}', a URDF you supply: give it with --urdf PATH, or put its folder in {URDF_PATH_ENV}",
    )


def resolve_urdf(f: Fields, config_dir: Path, override: str | Path | None = None) -> Path:
    forms = ("path", "icub_models", "package", "file", "supplied")
    if f.has("urdf") and not isinstance(f.data["urdf"], dict):  # a bare path, the first thing a user writes
        raise f.fail("urdf", f"must be a mapping: {{path: FILE}} (relative to the configuration), or one of "
                             f"{', '.join(forms[1:])} (robots/README.md); got {f.data['urdf']!r}")
    spec = f.sub("urdf").only(*forms)
    if override is not None:
        path = Path(override)
        if not path.is_file():
            raise ConfigError(f"{f.robot}: the URDF given with --urdf is not a file: {path}")
        return path
    if spec.has("supplied"):
        path = _supplied_urdf(spec, spec.string("supplied"))
    elif spec.has("path"):
        path = Path(spec.string("path"))
        path = path if path.is_absolute() else config_dir / path
    elif spec.has("icub_models"):
        name = spec.string("icub_models")
        try:
            import icub_models
        except ImportError:
            raise spec.fail("icub_models", "needs the icub-models package, which is not installed") from None
        try:
            path = Path(icub_models.get_model_file(name))
        except FileNotFoundError:
            known = ", ".join(sorted(icub_models.get_robot_names()))
            raise spec.fail("icub_models", f"names no model of icub-models: '{name}' (known: {known})") from None
    elif spec.has("package"):
        # A URDF shipped as data inside a pip distribution (e.g. example-robot-data).
        dist, suffix = spec.string("package"), spec.string("file")
        try:
            files = importlib.metadata.files(dist) or []
        except importlib.metadata.PackageNotFoundError:
            raise spec.fail("package", f"names a distribution that is not installed: '{dist}'") from None
        hits = [p for p in files if str(p).replace("\\", "/").endswith(suffix)]
        if not hits:
            raise spec.fail("file", f"matches no file of the distribution '{dist}': '{suffix}'")
        path = Path(str(hits[0].locate()))
    else:
        raise f.fail("urdf", "must give one of 'path', 'icub_models', 'package' or 'supplied'")
    if not path.is_file():
        raise f.fail("urdf", f"points to a missing file: {path}")
    return path


def urdf_if_found(f: Fields, config_dir: Path, override: str | Path | None) -> Path:
    """The URDF if it can be found, else an empty path: for what reads the configuration alone (the bus)."""
    try:
        return resolve_urdf(f, config_dir, override)
    except ConfigError:
        return Path()
