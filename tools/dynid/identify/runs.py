"""Many runs, and the statistics of each mapped on a Dask cluster (dynid.cluster): `dynid fit --workers/--scheduler`.

A run travels to a worker as a `RunRef` (its path, `--from/--to` window and known payload), never as data: the
worker opens it itself (`stream_run`: a dataset file read a window at a time, anything else read whole), builds
the robot model once per configuration, and returns the statistics of one time block (`accumulate_blocks`). The
client assembles each run's blocks in order and merges the runs in the order given (`Statistics.__add__`), so the
fit solves from the very sums the serial fit would: the same model, to rounding (docs/benchmarks.md measures it).
"""

from __future__ import annotations

import hashlib
import os
import pickle
from collections import OrderedDict
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from ..config.robot_config import RobotConfig
from ..errors import DataError, InputError
from ..io.bad_rows import DEFAULT_POLICY
from ..io.dataset import SIMULATION_DATASET
from ..io.load import INPUT_CHECK_S, quiet_inputs
from ..io.stream import DatasetFile, Run, is_dataset_file, open_run
from ..robot.model import RobotModel
from .fit import FitResult, FitSettings, SignalSource, fit_statistics, run_units
from .statistics import Statistics, accumulate_blocks, assemble, block_edges
from .validation import check_robot, load_run

Window = tuple[float | None, float | None]


@dataclass(frozen=True)
class RunRef:
    """A run as the command line names it: a path any worker can read, its window, its known payload."""

    path: str
    window: Window = (None, None)
    payload: dict[str, Any] | None = None
    bad_rows: str = DEFAULT_POLICY  # a log's bad rows (dynid.io.bad_rows); a dataset file has none

    def key(self) -> tuple:
        return (self.path, self.window, repr(self.payload), self.bad_rows)


def stream_run(ref: RunRef, model: RobotModel) -> Run:
    """`load_run`'s run, streamed where it is a dataset file (dynid.io.stream): checked the same way, the window
    found by bisection, the payload marked, a run of another robot refused."""
    p = Path(ref.path)
    file = p / SIMULATION_DATASET if (p / SIMULATION_DATASET).is_file() else p
    run = open_run(file, model.config, model.joint_limits) if is_dataset_file(file) else None
    if not isinstance(run, DatasetFile):  # a CSV, a candump log, a YARP folder, a compressed archive: read whole
        return load_run(ref.path, model, ref.window, ref.payload, ref.bad_rows)
    run = run.window(*ref.window, source=ref.path)
    if ref.payload is not None:
        model.payload_parameters(float(ref.payload["mass"]), ref.payload.get("com"))  # the frame exists
        run.meta = {**run.meta, "payload": ref.payload}
    check_robot(ref.path, run.meta.get("robot"), model)
    return run


# A worker's caches: one model per configuration (Pinocchio's build takes a second), the last few runs opened.
_MODELS: dict[str, RobotModel] = {}
_RUNS: OrderedDict[tuple, Run] = OrderedDict()
_KEEP_RUNS = 4


def for_workers(config: RobotConfig, refs: list[RunRef]) -> tuple[RobotConfig, list[RunRef]]:
    """The configuration and runs with absolute paths: a Dask worker opens them in its own working directory (a
    walkthrough's `--data 'npz/*.npz' --scheduler ...` was "data file not found" there, and a relative --urdf "lost
    the connection to the cluster"). Symlinks are kept: they are what the workers share."""
    urdf = Path(os.path.abspath(config.urdf)) if config.urdf != Path() else config.urdf
    return replace(config, urdf=urdf), [replace(r, path=os.path.abspath(r.path)) for r in refs]


def worker_model(config: RobotConfig) -> RobotModel:
    key = hashlib.sha256(pickle.dumps(config)).hexdigest()
    if key not in _MODELS:
        _MODELS[key] = RobotModel(config)
    return _MODELS[key]


def worker_run(ref: RunRef, model: RobotModel) -> Run:
    key = (ref.key(), model.config.digest)
    if key in _RUNS:
        _RUNS.move_to_end(key)
    else:
        _RUNS[key] = stream_run(ref, model)
        while len(_RUNS) > _KEEP_RUNS:
            _RUNS.popitem(last=False)
    return _RUNS[key]


def block_task(config: RobotConfig, ref: RunRef, settings: FitSettings, first: int, last: int) -> tuple:
    """A worker's task: the statistics of time blocks [first, last) of one run (one BLAS thread: the workers
    already fill the cores)."""
    model = worker_model(config)
    run = worker_run(ref, model)
    source = SignalSource(model, run, settings, instruments=not run.meta.get("payload"))
    with threadpool_limits(limits=1, user_api="blas"):
        return accumulate_blocks(model, source, block_edges(run.n_samples, settings.blocks), first, last)


def fit_on_cluster(model: RobotModel, refs: list[RunRef], runs: list[Run], settings: FitSettings,
                   cluster: Any) -> FitResult:
    """`fit` with each run's time blocks computed as tasks on `cluster` (a dynid.cluster.DaskCluster); `runs` are
    the runs as opened here (for their sample counts and payloads; a streamed run holds no data)."""
    tasks, owner = [], []
    edges_of = []
    for i, (ref, run) in enumerate(zip(refs, runs)):
        edges = block_edges(run.n_samples, settings.blocks)
        edges_of.append(edges)
        for k in range(len(edges) - 1):
            tasks.append((model.config, ref, settings, k, k + 1))
            owner.append(i)
    parts = cluster.map(block_task, tasks, "building regressors", runs=owner)
    total: Statistics | None = None
    for i, edges in enumerate(edges_of):
        stats = assemble(model, edges, [p for p, o in zip(parts, owner) if o == i])
        total = stats if total is None else total + stats
    assert total is not None
    payloads = [r.meta.get("payload") for r in runs]
    return fit_statistics(model, total, settings, sum(r.n_samples for r in runs), run_units(payloads),
                          [bool(p) for p in payloads])


def check_distinct_runs(paths: list[str], runs: list) -> None:
    """Refuse one recording given twice under two names (a folder and its `dynid import`, a copy): it would count
    twice, and its blocks would pose as independent runs. Two runs are the same where their first and last samples'
    q and measured outputs (F/T, inputs: their noise tells two recordings of one trajectory apart, however still the
    robot was at both ends) are, bit for bit, and their lengths: not their stamps, which a bag written from the same
    log may shift to the epoch (a walkthrough's CSV and its MCAP: block errors 0.56 times the run's own, the runs'
    error zero)."""
    seen: dict[bytes, str] = {}
    for path, run in zip(paths, runs):
        n = run.n_samples
        ends = [run.slice(0, min(n, 64)), run.slice(max(0, n - 64), n)]
        arrays = [a for d in ends for a in (d.q, *(v for family in (d.ft, d.pwm, d.current, d.tau)
                                                   for _, v in sorted(family.items())))]
        key = hashlib.sha256(np.int64(n).tobytes() + b"".join(np.ascontiguousarray(a, float).tobytes()
                                                               for a in arrays)).digest()
        if key in seen:
            raise InputError(f"--data {seen[key]} and {path} hold the same samples (one recording under two names?): "
                             "it would count twice; give it once")
        seen[key] = path


def input_notes(config: RobotConfig, paths: list[str], runs: list) -> list[tuple[str, str]]:
    """(path, note) for each run's motor inputs or joint torques that stay within their noise while their joints move
    (dynid.io.load.quiet_inputs), judged on a run's first INPUT_CHECK_S seconds (a dataset file's read alone)."""
    out = []
    for path, run in zip(paths, runs):
        head = run.slice(0, min(run.n_samples, int(INPUT_CHECK_S / run.median_step()) + 2)) \
            if isinstance(run, DatasetFile) else run
        out += [(path, note) for note in quiet_inputs(config, head)]
    return out
