"""Settings for every test of the repository (tools/tests, tests/): loaded by pytest before any test module."""

from __future__ import annotations

import os

from threadpoolctl import threadpool_limits

# One BLAS and OpenMP thread per test process, unless the caller chose otherwise. The suite already runs a process
# per core (two pytest-xdist workers, and tests that run two `dynid` processes at once); OpenBLAS's threads on top
# spin-wait against each other: four `dynid gaps` at once on this 2-core machine took 25-33 s with OpenBLAS's default
# two threads each, 8.6-9.0 s with one (docs/benchmarks.md#the-suites-time). The `dynid`
# processes the tests start inherit the variables; this process's libraries, loaded already, are limited here.
if "OPENBLAS_NUM_THREADS" not in os.environ and "OMP_NUM_THREADS" not in os.environ:
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
    threadpool_limits(limits=1)
