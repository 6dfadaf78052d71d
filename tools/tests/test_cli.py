"""The `dynid` command line as users and outside tests drive it: real processes, exit codes, one-line errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import dynid, dynid_executable

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel

ICUB = load_config("icub_right_arm")
LIMITS = RobotModel(ICUB).joint_limits


run = dynid_executable  # real processes, as a user's shell runs them


def icub_columns(n: int = 400, seed: int = 0) -> dict[str, np.ndarray]:
    """A short, smooth, exciting motion of the iCub arm with plausible PWMs and wrenches."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    cols: dict[str, np.ndarray] = {"t": t}
    for i, j in enumerate(ICUB.joints):
        lo, hi = LIMITS[j]
        cols[f"q.{j}"] = (lo + hi) / 2 + 0.3 * (hi - lo) * np.sin(2 * np.pi * (0.5 + 0.2 * i) * t + i)
    for m in ICUB.motor_names:
        cols[f"pwm.{m}"] = rng.uniform(-0.2, 0.2, n)
    for c in ("fx", "fy", "fz", "tx", "ty", "tz"):
        cols[f"ft.r_arm_ft.{c}"] = rng.normal(0, 1, n)
    return cols


def write_csv(path: Path, cols: dict[str, np.ndarray]) -> Path:
    names = list(cols)
    data = np.column_stack([cols[k] for k in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return path


def assert_one_line_error(p: subprocess.CompletedProcess, *words: str) -> None:
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert "Traceback" not in p.stderr
    for w in words:
        assert w in lines[0], lines[0]


def test_help_means_something() -> None:
    p = run("--help")
    assert p.returncode == 0
    for command in ("import", "structure"):
        assert command in p.stdout
    p = run("import", "--help")
    assert "--robot" in p.stdout and "--data" in p.stdout and "--out" in p.stdout


def test_import_then_structure(tmp_path: Path) -> None:
    csv = write_csv(tmp_path / "run.csv", icub_columns())
    out = tmp_path / "run.npz"
    p = run("import", "--data", str(csv), "--out", str(out), "--json", str(tmp_path / "import.json"))
    assert p.returncode == 0, p.stderr
    assert "imported 400 samples" in p.stdout and out.is_file()
    result = json.loads((tmp_path / "import.json").read_text())
    assert result["samples"] == 400 and result["robot"] == "icub_right_arm"
    p = run("structure", "--data", str(out), "--json", "-")
    assert p.returncode == 0, p.stderr
    result = json.loads(p.stdout)  # stdout holds the JSON alone; the report went to stderr
    assert "numerical rank" in p.stderr
    # 400 samples of a smooth motion excite less than random states do, but far more than standing still.
    assert len(result["parameters"]) == 118 and result["rank"] == 81


def test_an_import_whose_reader_closes_stdout_says_what_it_did_not_write(tmp_path: Path) -> None:
    """Outputs are put in place when a command succeeds; one whose standard output is closed first (`| head -0`)
    writes none, and says so in one line (a reader of stdout alone, as spy's, ends quietly: test_lcm_deploy)."""
    csv = write_csv(tmp_path / "run.csv", icub_columns())
    out = tmp_path / "run.npz"
    p = subprocess.Popen([sys.executable, "-m", "dynid.cli", "import", "--data", str(csv), "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    p.stdout.close()  # the reader is gone before the command prints its report
    err = p.stderr.read()
    assert p.wait(timeout=120) == 141 and not out.exists()
    assert err.strip().splitlines() == ["dynid import: standard output closed before the command ended: its outputs "
                                        "(--out) were not written"], err
    # `2>&1 | head`: standard error is that closed pipe too; the exit is still SIGPIPE's, not 1 from a second error
    p = subprocess.Popen([sys.executable, "-m", "dynid.cli", "import", "--data", str(csv), "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    p.stdout.close()
    assert p.wait(timeout=120) == 141 and not out.exists()


def test_structure_reports_the_rank() -> None:
    p = run("structure", "--combinations")
    assert p.returncode == 0, p.stderr
    assert "numerical rank 87 of 118" in p.stdout
    assert "m0.phi_m" in p.stdout


def _drop(col):
    return lambda c: c.pop(col)


def _rename(old, new):
    return lambda c: c.__setitem__(new, c.pop(old))


def _set_row(col, row, value):
    def edit(c):
        c[col] = c[col].copy()
        c[col][row] = value
    return edit


BAD_CSV = [
    ("missing column", _drop("q.r_elbow"), ["q.r_elbow"]),
    ("missing pwm", _drop("pwm.m2"), ["pwm.m2"]),
    ("unknown joint", _rename("q.r_elbow", "q.r_elbw"), ["r_elbw"]),
    ("non-increasing time", _set_row("t", 200, 0.1), ["not strictly increasing"]),
    ("NaN", _set_row("ft.r_arm_ft.fz", 17, np.nan), ["ft.r_arm_ft.fz"]),
    ("PWM in board counts", _set_row("pwm.m0", 5, 1333.0), ["pwm.m0", "1333"]),
    ("degrees for radians", lambda c: c.__setitem__("q.r_elbow", np.degrees(c["q.r_elbow"]) + 90), ["q.r_elbow"]),
]


@pytest.mark.parametrize("label,edit,words", BAD_CSV, ids=[b[0] for b in BAD_CSV])
def test_import_refuses_bad_csv(tmp_path: Path, label, edit, words) -> None:
    cols = icub_columns()
    edit(cols)
    csv = write_csv(tmp_path / "bad.csv", cols)
    out = tmp_path / "out.npz"
    p = run("import", "--data", str(csv), "--out", str(out))
    assert_one_line_error(p, *words)
    assert not out.exists()  # nothing half-written


def test_data_that_does_not_fit_the_default_robot_says_it_was_read_as_that(tmp_path: Path) -> None:
    """A user of another robot who forgot --robot reads the data error against the default arm's configuration, and
    is told so; with --robot given, nothing is added."""
    csv = tmp_path / "mine.csv"
    csv.write_text("t,q.joint_a\n0,0\n0.001,0\n")
    done = dynid("import", "--data", str(csv), "--out", str(tmp_path / "x.npz"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.rstrip().endswith("(read as icub_right_arm's, the default robot: --robot names yours)")
    done = dynid("import", "--robot", "icub_right_arm", "--data", str(csv), "--out", str(tmp_path / "x.npz"))
    assert done.returncode == 2 and "the default robot" not in done.stderr, done.stderr
    for command in ("import", "fit"):  # a file that is not there was read as nothing: no robot to name
        done = dynid(command, "--data", str(tmp_path / "gone.csv"), "--out", str(tmp_path / "x.npz"))
        assert done.returncode == 2 and "not found" in done.stderr and "the default robot" not in done.stderr


def test_import_missing_file(tmp_path: Path) -> None:
    assert_one_line_error(run("import", "--data", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "o.npz")), "nope.csv")


@pytest.mark.parametrize("spec", ["@{list}", "{folder}/*.csv"])
def test_import_of_many_runs_says_it_reads_one(tmp_path: Path, spec: str) -> None:
    """`import --data @list.txt` said "data file not found" of a list that exists."""
    listing = tmp_path / "runs.txt"
    listing.write_text(f"{tmp_path / 'a.csv'}\n")
    done = run("import", "--data", spec.format(list=listing, folder=tmp_path), "--out", str(tmp_path / "o.npz"))
    assert_one_line_error(done, "import reads one run")
    assert not (tmp_path / "o.npz").exists()


def test_import_unknown_robot(tmp_path: Path) -> None:
    assert_one_line_error(run("import", "--robot", "icub_left_leg", "--data", "x.csv", "--out", "o.npz"), "icub_left_leg")


def test_bad_flag() -> None:
    assert_one_line_error(run("import", "--data", "x.csv", "--out", "o.npz", "--bogus"), "--bogus")


def test_corrupt_dataset_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"PK\x03\x04 not really a zip")
    assert_one_line_error(run("structure", "--data", str(bad)), "bad.npz")


@pytest.mark.parametrize("target", ["dir", "missing_dir/out.npz", "/proc/dynid.npz"])
def test_unwritable_out(tmp_path: Path, target: str) -> None:
    csv = write_csv(tmp_path / "run.csv", icub_columns())
    out = tmp_path if target == "dir" else (tmp_path / target if not target.startswith("/") else Path(target))
    assert_one_line_error(run("import", "--data", str(csv), "--out", str(out)), "cannot write")
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary file left behind


def test_unwritable_json(tmp_path: Path) -> None:
    p = run("structure", "--samples", "50", "--json", str(tmp_path))
    assert_one_line_error(p, "cannot write")


@pytest.mark.parametrize("samples", ["0", "-5", "many"])
def test_samples_must_be_positive(samples: str) -> None:
    assert_one_line_error(run("structure", "--samples", samples), "--samples")


def test_an_unwritable_output_directory_is_refused_before_any_work(tmp_path: Path, monkeypatch) -> None:
    """A read-only file system (or a directory without write permission) is found before a fit runs, not after
    it wrote its model and failed on --json. (os.access is what the check asks; root ignores permission bits, so
    the read-only directory is simulated here.)"""
    import argparse
    import os

    from dynid.cli.common import check_outputs
    from dynid.errors import InputError

    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == ro else real(p, mode))
    args = argparse.Namespace(command="fit", out=str(tmp_path / "m.json"), json=str(ro / "r.json"))
    with pytest.raises(InputError, match=r"cannot write '.*/ro/r\.json' \(--json\): the directory .*/ro is not writable"):
        check_outputs(args)
    check_outputs(argparse.Namespace(command="fit", out=str(tmp_path / "m.json"), json=str(tmp_path / "r.json")))


# Every command that writes, with --json where nothing can be created (/proc: os.access says yes for root) and inputs
# that do not exist: the output is refused first, before any work, and named by its option.
WRITERS = {
    "fit": ["--data", "missing.csv", "--out", "m.json"],
    "validate": ["--model", "missing.json", "--data", "missing.csv"],
    "detect": ["--model", "missing.json", "--data", "missing.csv"],
    "export": ["--model", "missing.json", "--out", "x.dcoef"],
    "simulate": ["--out", "sim"],
    "excite": ["--duration", "10", "--out", "t.csv"],
    "play": ["--data", "missing.csv", "--sink", "candump:p.log"],
    "gaps": ["--data", "missing.csv", "--out", "g.json", "--figures", "figs"],
    "fleet": ["--data", "missing", "--out", "fleet"],
    "report": ["--model", "missing.json", "--validation", "missing.csv", "--out", "r.html"],
    "import": ["--data", "missing.csv", "--out", "d.npz"],
    "structure": [],
}


def test_an_output_directory_under_a_file_is_refused_before_any_work(tmp_path: Path) -> None:
    """`simulate --out afile/sub` passed the check (its nearest existing path was a file, not probed), simulated, and
    failed making the directory (a review found it)."""
    (tmp_path / "afile").write_text("x")
    p = run("simulate", "--duration", "2", "--out", str(tmp_path / "afile" / "sub" / "deeper"))
    assert_one_line_error(p, f"cannot write to '{tmp_path / 'afile' / 'sub' / 'deeper'}' (--out): "
                             f"{tmp_path / 'afile'} is not a directory")


@pytest.mark.parametrize("command", WRITERS)
def test_an_output_nothing_can_be_created_at_is_refused_before_any_work(command: str, tmp_path: Path) -> None:
    """`fit --out f.json --json /proc/r.json` passed the check (os.access), ran, wrote f.json and then failed on the
    --json without saying it was the --json. The check creates (and removes) a file where each output will go."""
    if os.geteuid() != 0:  # permission bits refuse /proc to anyone else first, with their own message
        pytest.skip("as root only: for root os.access says yes in /proc, and the created file is the check")
    done = dynid(command, *WRITERS[command], "--json", "/proc/dynid-result.json", cwd=tmp_path)
    assert_one_line_error(done, "cannot write '/proc/dynid-result.json' (--json): no file can be created in /proc")
    assert list(tmp_path.iterdir()) == []
    if command in ("fit", "simulate", "import"):
        out = "/proc/dynid-out" + ("" if command == "simulate" else ".x")
        done = dynid(command, *[out if a == WRITERS[command][-1] else a for a in WRITERS[command]], cwd=tmp_path)
        assert_one_line_error(done, f"'{out}' (--out)", "can be created in /proc")


def test_an_output_that_fails_late_leaves_none_behind(tmp_path: Path, monkeypatch) -> None:
    """A write that fails after the check all the same (a full disk): the command's other outputs, written before it,
    are not left behind, nor any temporary file, and the message names the output by its option."""
    import errno

    import dynid.cli.common
    from dynid.cli import main

    real = dynid.cli.common.atomic_write

    def full_disk(path, write):  # noqa: ANN001 - atomic_write's arguments
        def fail(f) -> None:  # noqa: ANN001
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path, fail)

    monkeypatch.setattr(dynid.cli.common, "atomic_write", full_disk)  # write_json's
    csv = write_csv(tmp_path / "run.csv", icub_columns())
    out, result = tmp_path / "run.npz", tmp_path / "import.json"
    (tmp_path / "run.npz").write_bytes(b"an earlier import")
    code = main(["import", "--data", str(csv), "--out", str(out), "--json", str(result)])
    assert code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.npz"]
    assert out.read_bytes() == b"an earlier import"  # the file the import would have replaced is left as it was


def test_validate_on_the_fits_own_data_says_it_is_in_sample(default_model: Path, default_experiments: dict,
                                                           tmp_path: Path) -> None:
    """A validation window inside the fit's data printed in-sample figures as a validation (a walkthrough); the model
    file knows its runs and windows."""
    import json

    done = run("validate", "--model", str(default_model), "--data", str(default_experiments["identification"]),
               "--to", "20", "--json", str(tmp_path / "v.json"))
    assert done.returncode == 0, done.stderr
    assert "note: 100 % of these samples are the fit's own" in done.stdout
    result = json.loads((tmp_path / "v.json").read_text())
    assert result["fit_overlap"] == 1.0 and result["window"] == [None, 20.0]
    done = run("validate", "--model", str(default_model), "--data", str(default_experiments["validation"]), "--to", "20")
    assert done.returncode == 0 and "the fit's own" not in done.stdout


def test_a_headerless_log_of_another_robot_names_the_configuration(tmp_path: Path) -> None:
    """The UR10e's headerless log read with the Panda's configuration said only "no header: name the columns" (a
    walkthrough): the likelier mistake, another robot's data, is named with what this configuration reads."""
    log = tmp_path / "ur.csv"
    log.write_text("".join(f"{k * 0.002:.3f}," + ",".join(["0.1"] * 30) + "\n" for k in range(50)))
    done = run("import", "--robot", "panda", "--data", str(log), "--out", str(tmp_path / "o.npz"))
    assert_one_line_error(done, "no header: the first line is data (31 values), and the configuration panda reads its "
                                "runs as folders of files")
    assert "another robot's data (give its --robot)" in done.stderr
