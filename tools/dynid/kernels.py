"""Which implementation runs: the compiled batch kernels (`dynid._kernels`, built from tools/kernels by
scripts/setup) or the Python reference.

The kernels compute over whole arrays of samples (the stacked regressor rows, the momentum observer's products,
the simulated plant's steps); the Python implementations beside their callers stay the definition, and the suite
checks the kernels against them sample by sample (tools/tests/test_kernels.py). Where the extension is missing (a
`pip install` without the CMake build) or `DYNID_KERNELS=0` is set, every caller runs its Python reference.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

try:  # (through importlib: `from . import _kernels` would read to the layer check as importing all of dynid)
    _compiled: ModuleType | None = importlib.import_module("dynid._kernels")
except ModuleNotFoundError:  # not built: the Python reference runs (a broken build raises)
    _compiled = None


def native() -> ModuleType | None:
    """The compiled module, or None where the Python reference runs (not built, or DYNID_KERNELS=0)."""
    if _compiled is None or os.environ.get("DYNID_KERNELS", "1") == "0":
        return None
    return _compiled


def available() -> bool:
    """Whether the compiled kernels are built (whatever DYNID_KERNELS says)."""
    return _compiled is not None
