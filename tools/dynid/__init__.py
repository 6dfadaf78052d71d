"""dynid: robot dynamics identification and real-time contact monitoring.

From one recorded experiment, dynid identifies in one regression the inertial parameters of every body, the F/T
sensor offsets, the friction of every joint and motor and the motor gains (Traversaro et al., Humanoids 2013),
calibrates a Hotelling T² contact detector, and exports the coefficient file the C++ monitor loads.

The API (scikit-learn's manner; the command line `dynid` runs the same code):

    import dynid
    model = dynid.DynamicsModel(robot="icub_right_arm").fit("out/identification")
    model.validate("out/validation")["table_ii"]          # the paper's Table II
    dynid.ContactDetector(model).evaluate("out/contact")  # TPR, FPR, AUC, episodes
    model.save("out/model.json")
    dynid.export_coefficients(model, "out/model.dcoef")

- `load_robot`, `read_data`: a robot configuration's model; a run of data (CSV, candump, dataset, simulation).
- `DynamicsModel`: fit / predict / score / validate / save / load.
- `ContactDetector`: fit (recalibrate) / decision_function (T²) / predict / score / evaluate.
- `export_coefficients`: the monitor's coefficient file. `export_urdf`: the identified robot as a URDF.
  `find_gaps`: the model-gap workflow.

The package's layers follow the data's path (tools/README.md): config → io → robot (and simulation) → identify
→ detect → pipeline → export → gaps → report → api → cli.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .version import __version__

# name -> the module that defines it. Loaded on first use (PEP 562, as SciPy and scikit-image do): `import dynid.cli`
# and `dynid --help` need not load scikit-learn and Pinocchio for the API's sake.
_EXPORTS = {
    "ContactDetector": "api", "DynamicsModel": "api", "ExportSettings": "api", "Gaps": "api",
    "export_coefficients": "api", "export_urdf": "api", "find_gaps": "api", "load_model": "api", "load_robot": "api", "read_data": "api",
    "RobotConfig": "config", "bundled_configs": "config",
    "ConfigError": "errors", "DataError": "errors", "InputError": "errors",
    "Dataset": "io", "RobotModel": "robot",
}
__all__ = [
    "ConfigError",
    "ContactDetector",
    "DataError",
    "Dataset",
    "DynamicsModel",
    "ExportSettings",
    "Gaps",
    "InputError",
    "RobotConfig",
    "RobotModel",
    "__version__",
    "bundled_configs",
    "export_coefficients",
    "export_urdf",
    "find_gaps",
    "load_model",
    "load_robot",
    "read_data",
]

if TYPE_CHECKING:  # what the names are, for type checkers and IDEs
    from .api import (
        ContactDetector,
        DynamicsModel,
        ExportSettings,
        Gaps,
        export_coefficients,
        find_gaps,
        load_model,
        load_robot,
        read_data,
    )
    from .config import RobotConfig, bundled_configs
    from .errors import ConfigError, DataError, InputError
    from .io import Dataset
    from .robot import RobotModel


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'dynid' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
