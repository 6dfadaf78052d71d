"""Many runs (issue 33): runs streamed from disk, statistics that merge exactly, `--data` globs/folders/lists, the
jackknife over runs, and the fit on a Dask LocalCluster equal to the serial one."""

from __future__ import annotations

import json
import os
import re
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from conftest import dynid
from dynid.config.robot_config import load_config
from dynid.errors import DataError, DataNote
from dynid.identify.fit import FitSettings, SignalSource, fit, run_units
from dynid.identify.runs import RunRef, stream_run
from dynid.identify.statistics import accumulate
from dynid.io.load import apply_window, load_data
from dynid.io.run_paths import expand_all, expand_named
from dynid.io.stream import DatasetFile, DatasetWriter, open_run
from dynid.robot.model import RobotModel
from dynid.simulation import SimulationSettings, simulate
from dynid.simulation.output import write_simulation

SECONDS = 20.0


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel(load_config("icub_right_arm"))


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory, model: RobotModel) -> list[Path]:
    """Three short identification runs of the default arm (robot seed 0), each its own trajectory."""
    root = tmp_path_factory.mktemp("runs")
    out = []
    for seed in range(3):
        sim = simulate(model.config, SimulationSettings(duration=SECONDS, seed=seed))
        write_simulation(sim, root / f"run{seed}")
        out.append(root / f"run{seed}")
    return out


def columns_equal(a, b) -> None:  # noqa: ANN001 - two Datasets
    assert [n for n, _ in a.columns()] == [n for n, _ in b.columns()]
    for (name, x), (_, y) in zip(a.columns(), b.columns()):
        assert np.array_equal(x, y), name


def test_a_dataset_file_streams_what_load_data_reads(runs: list[Path], model: RobotModel, tmp_path: Path) -> None:
    whole = load_data(runs[0], model.config, model.joint_limits)
    run = open_run(runs[0], model.config, model.joint_limits)
    assert isinstance(run, DatasetFile) and run.n_samples == whole.n_samples
    assert run.duration == whole.duration and run.median_step() == pytest.approx(whole.median_step(), rel=1e-9)
    part = run.slice(4321, 9876)
    columns_equal(part, whole.slice(4321, 9876))
    assert part.meta["rows"] == [4321, 9876]
    window = run.window(3.25, 11.5)
    expected = apply_window(whole, 3.25, 11.5)
    assert window.n_samples == expected.n_samples
    columns_equal(window.slice(0, window.n_samples), expected.slice(0, expected.n_samples))
    with pytest.raises(DataError, match="holds only"):
        run.window(5.0, 5.01)

    # Written a chunk at a time, read back whole: the same file content.
    copy = tmp_path / "copy.npz"
    with DatasetWriter(copy, run.n_samples, run.meta) as out:
        for lo in range(0, run.n_samples, 7000):
            out.write(run.slice(lo, lo + 7000))
    columns_equal(load_data(copy, model.config, model.joint_limits), whole)
    # An unfinished writer leaves nothing behind.
    with pytest.raises(DataError, match="rows written"), DatasetWriter(tmp_path / "short.npz", 10**6) as out:
        out.write(run.slice(0, 100))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.npz"]


def test_a_dataset_file_with_column_major_members_streams_too(runs: list[Path], model: RobotModel,
                                                              tmp_path: Path) -> None:
    """A lab's own writer may store q column-major (numpy keeps a transposed array's order): such a file was read
    whole, silently (a walkthrough's 8 h log: 1.9 GB). It streams, column by column, to the same samples."""
    whole = load_data(runs[0], model.config, model.joint_limits)
    with zipfile.ZipFile(runs[0] / "dataset.npz") as archive:
        members = {i.filename.removesuffix(".npy"): np.load(archive.open(i), allow_pickle=False)
                   for i in archive.infolist()}
    members["q"] = np.asfortranarray(members["q"])
    members["ft/r_arm_ft"] = np.asfortranarray(members["ft/r_arm_ft"])
    column_major = tmp_path / "column_major.npz"
    np.savez(column_major, **members)
    run = open_run(column_major, model.config, model.joint_limits)
    assert isinstance(run, DatasetFile)
    columns_equal(run.slice(4321, 9876), whole.slice(4321, 9876))
    window = run.window(3.25, 11.5)
    columns_equal(window.slice(0, window.n_samples), apply_window(whole, 3.25, 11.5).slice(0, window.n_samples))


def test_a_bad_window_is_refused_with_its_rows(runs: list[Path], model: RobotModel, tmp_path: Path) -> None:
    """A corrupt value deep in a streamed file is found when its window is read: one line naming the file's row."""
    whole = load_data(runs[0], model.config, model.joint_limits)
    bad = whole.slice(0, whole.n_samples)
    bad.ft["r_arm_ft"][15_000, 2] = 3e7  # beyond ±1e6: a corrupt cell
    bad.save(tmp_path / "bad.npz")
    run = open_run(tmp_path / "bad.npz", model.config, model.joint_limits)  # its first rows are fine
    with pytest.raises(DataError, match=r"bad\.npz, rows .*row 15001: beyond"):
        run.slice(14_000, 16_000)
    done = dynid("fit", "--data", str(tmp_path / "bad.npz"), "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and "row 15001" in done.stderr and "Traceback" not in done.stderr
    assert done.stderr.count("\n") == 1 and not (tmp_path / "m.json").exists()
    # A compressed archive cannot be read in place: it is read whole, as before.
    with zipfile.ZipFile(tmp_path / "bad.npz") as src, zipfile.ZipFile(tmp_path / "z.npz", "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            dst.writestr(info.filename, src.read(info.filename))
    with pytest.raises(DataError, match="row 15001"):
        open_run(tmp_path / "z.npz", model.config, model.joint_limits)


@pytest.fixture(scope="module")
def three(runs: list[Path], model: RobotModel):  # noqa: ANN201 - a FitResult
    """The fit of the three runs together, in-process (4 time blocks a run)."""
    return fit(model, [stream_run(RunRef(str(p)), model) for p in runs], FitSettings(blocks=4))


def test_statistics_merge_exactly_and_associatively(runs: list[Path], model: RobotModel, three) -> None:  # noqa: ANN001
    settings = FitSettings(blocks=4)
    a, b, c = (accumulate(model, SignalSource(model, stream_run(RunRef(str(p)), model), settings, True), 4, 1)
               for p in runs)
    left, right = (a + b) + c, a + (b + c)
    for name in ("gram", "rows", "cross", "cross_b", "block_samples", "block_run"):
        assert np.array_equal(getattr(left, name), getattr(right, name)), name
        # … and they are the statistics the fit of the three runs solved from (its forked workers' sums)
        np.testing.assert_allclose(getattr(left, name), getattr(three.statistics, name), rtol=1e-12, atol=1e-9)
    assert left.n_runs == 3 and list(left.block_run) == [0] * 4 + [1] * 4 + [2] * 4
    # A pair of runs out of the merged statistics: its blocks, its runs renumbered
    pair = left.of_blocks(left.block_run != 1)
    assert pair.n_runs == 2 and np.array_equal(pair.gram, np.concatenate([a.gram, c.gram]))


def test_a_jackknife_over_runs_beside_the_one_over_blocks(three) -> None:  # noqa: ANN001
    est = three.estimates[three.chosen]
    assert est.se_runs is not None and est.units.shape == (3, three.base.rank)
    np.testing.assert_array_equal(est.se, np.maximum(est.se_blocks, est.se_runs))
    # "Determined" needs both: a combination the runs disagree on beyond 10 % is not determined.
    loose = est.se_runs > 0.1 * np.abs(est.beta)
    assert loose.any() and not (three.identified & loose).any()
    assert three.jackknife["units"] == 3 and three.jackknife["runs"] == 3
    # A loaded run joins the unloaded one before it: pairs are the units.
    assert run_units([None, {"mass": 2.8}, None, {"mass": 2.8}]) == [0, 0, 1, 1]
    assert run_units([{"mass": 1.0}, None, None]) == [0, 0, 1]


def test_data_takes_globs_folders_and_lists(runs: list[Path], tmp_path: Path) -> None:
    root = runs[0].parent
    assert expand_all([str(root / "run*")]) == [str(p) for p in runs]
    assert expand_all([str(root)]) == [str(p) for p in runs]
    listing = tmp_path / "runs.txt"
    listing.write_text(f"# two runs\n{runs[2]}\n\n{runs[0]}  # the first\n")
    assert expand_all([f"@{listing}"]) == [str(runs[2]), str(runs[0])]
    with pytest.raises(DataError, match="named twice"):
        expand_all([str(runs[0]), str(root)])
    with pytest.raises(DataError, match="matches no run"):
        expand_all([str(root / "nothing*")])
    assert [r.name for r in expand_named([f"arm7={runs[0]}", str(runs[1])])] == ["arm7", root.name]
    done = dynid("fit", "--data", str(tmp_path / "none*"), "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and "matches no run" in done.stderr
    # a folder's README_cpp.txt or LICENSE.txt is no run (the Panda's shared folder has both beside its logs), nor a
    # run's episode labels (the UR10e's contact folder: read as a run, "column t is missing")
    beside = tmp_path / "beside"
    beside.mkdir()
    for name in ("README_cpp.txt", "LICENSE.TXT", "run.csv", "run.episodes.csv"):
        (beside / name).write_text("x\n")
    assert expand_all([str(beside)]) == [str(beside / "run.csv")]


def test_a_local_cluster_of_two_workers_gives_the_serial_model(runs: list[Path], model: RobotModel,
                                                               tmp_path: Path) -> None:
    """`dynid fit --workers 2` (a Dask LocalCluster) against the in-process fit: the same model to 1e-10."""
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("two workers need two CPUs: a local cluster has at most one worker a CPU (dynid.cluster.executor)")
    data = [arg for p in runs[:2] for arg in ("--data", str(p))] + ["--blocks", "4"]
    serial = dynid("fit", *data, "--out", str(tmp_path / "serial.json"))
    assert serial.returncode == 0, serial.stderr
    done = dynid("fit", *data, "--workers", "2", "--out", str(tmp_path / "dask.json"))
    assert done.returncode == 0, done.stderr
    assert "local Dask cluster of 2 worker processes" in done.stdout
    a, b = (json.loads((tmp_path / f"{k}.json").read_text()) for k in ("serial", "dask"))
    pa, pb = np.array(list(a["parameters"].values())), np.array(list(b["parameters"].values()))
    scale = np.maximum(np.abs(pa), 1e-12)
    assert np.max(np.abs(pa - pb) / scale) <= 1e-10
    for variant in ("calibrated", "paper"):
        assert b["detector"][variant]["threshold"] == pytest.approx(a["detector"][variant]["threshold"], rel=1e-10)
    assert b["base"]["standard_errors_runs"] == pytest.approx(a["base"]["standard_errors_runs"], rel=1e-10)

    # A corrupt window found by a worker: the same one line and exit 2 as in-process, nothing written.
    whole = load_data(runs[0], model.config, model.joint_limits)
    whole.ft["r_arm_ft"][15_000, 2] = 3e7
    whole.save(tmp_path / "bad.npz")
    done = dynid("fit", "--data", str(tmp_path / "bad.npz"), "--workers", "2", "--out", str(tmp_path / "bad.json"))
    assert done.returncode == 2 and "row 15001" in done.stderr and done.stderr.count("\n") == 1, done.stderr
    assert not (tmp_path / "bad.json").exists()


def test_more_workers_than_cpus_start_one_a_cpu_with_a_note(monkeypatch) -> None:
    """`--workers N` past this process's CPUs: one worker a CPU, and a note that says so (64 processes on 2 CPUs, each
    importing dynid and holding its blocks, only shared the CPUs and multiplied the memory)."""
    import dynid.cluster

    started: list[int | None] = []
    monkeypatch.setattr(dynid.cluster, "DaskCluster", lambda workers, scheduler: started.append(workers))
    cpus = len(os.sched_getaffinity(0))
    with pytest.warns(DataNote, match=f"--workers {cpus + 1}: this process may run on {cpus} CPU"):
        dynid.cluster.executor(cpus + 1, None)
    assert started == [cpus]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # within the CPUs, or a running cluster's own workers: as asked, no note
        dynid.cluster.executor(cpus, None)
        dynid.cluster.executor(None, "tcp://127.0.0.1:1")
    assert started == [cpus, cpus, None]


def test_a_scheduler_that_is_not_there_is_one_line(runs: list[Path], tmp_path: Path, monkeypatch) -> None:
    import dynid.cluster

    monkeypatch.setattr(dynid.cluster, "CONNECT_TIMEOUT_S", 1.0)
    from dynid.cli import main

    code = main(["fit", "--data", str(runs[0]), "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path / "m.json")])
    assert code == 3 and not (tmp_path / "m.json").exists()


@pytest.mark.parametrize(("address", "says"), [
    ("127.0.0.1", "not a Dask scheduler.s address: give \\[tcp://\\]HOST:PORT"),
    ("", "not a Dask scheduler's address"),
    ("http://127.0.0.1:8787", "not a Dask scheduler's address"),
    ("tcp://127.0.0.1:99999", "not a Dask scheduler's address"),
    ("tls://127.0.0.1:8786", "a TLS scheduler needs a security context")])
def test_an_address_no_scheduler_has_is_refused_before_connecting(address: str, says: str) -> None:
    """A walkthrough's mistyped addresses waited 40 s and left a traceback (tls://: exit 1): refused at once."""
    from dynid.cluster import scheduler_problem

    assert re.match(says, scheduler_problem(address)), scheduler_problem(address)
    for good in ("tcp://127.0.0.1:8786", "127.0.0.1:8786", "tcp://[::1]:8786", "scheduler.lab:8786"):
        assert scheduler_problem(good) == ""
    done = dynid("fit", "--data", "nowhere.csv", "--scheduler", address, "--out", "m.json")  # refused by the parser
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1 and "argument --scheduler" in done.stderr


def test_runs_and_urdf_go_to_a_scheduler_s_workers_as_absolute_paths(tmp_path: Path, monkeypatch) -> None:
    """A Dask worker opens the files in its own working directory: relative paths were "data file not found" there
    (and a relative --urdf "lost the connection to the cluster"). Symlinks stay: they are what the workers share."""
    from dynid.config.robot_config import load_config
    from dynid.identify.runs import RunRef, for_workers

    monkeypatch.chdir(tmp_path)
    (tmp_path / "store").mkdir()
    (tmp_path / "store" / "a.csv").write_text("t\n")
    (tmp_path / "linked.csv").symlink_to(tmp_path / "store" / "a.csv")
    urdf = Path(load_config("icub_right_arm").urdf)
    (tmp_path / "arm.urdf").write_bytes(urdf.read_bytes())
    config = load_config("icub_right_arm", "arm.urdf")
    assert not Path(config.urdf).is_absolute()
    config, refs = for_workers(config, [RunRef("linked.csv", (1.0, None))])
    assert config.urdf == tmp_path / "arm.urdf" and refs == [RunRef(str(tmp_path / "linked.csv"), (1.0, None))]


def test_two_recordings_of_one_trajectory_at_rest_at_both_ends_are_two_runs(runs: list[Path], model: RobotModel) -> None:
    """The same q at both ends and the same length (a fleet runs one trajectory, parked at home) is not one recording:
    the measured outputs' noise differs. The same samples under shifted stamps are one."""
    from dataclasses import replace

    from dynid.errors import InputError
    from dynid.identify.runs import check_distinct_runs

    a = load_data(runs[0], model.config, model.joint_limits)
    b = replace(a, ft={s: w + np.random.default_rng(0).normal(0, 0.1, w.shape) for s, w in a.ft.items()})
    check_distinct_runs(["a", "b"], [a, b])
    with pytest.raises(InputError, match="--data a and c hold the same samples"):
        check_distinct_runs(["a", "c"], [a, replace(a, t=a.t + 1.7e9)])
