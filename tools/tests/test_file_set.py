"""A run written as a folder of files, read through the configuration's `files:` field (dynid.io.file_set): both
layouts against the values written, every bad folder, file and configuration refused in one line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError, DataError
from dynid.identify.model_file import data_digest
from dynid.io.file_set import holds_file_set
from dynid.io.load import load_data
from dynid.io.run_paths import expand

N = 300  # samples


def config_with(tmp_path: Path, files: str, name: str = "arm_files") -> Path:
    """The bundled iCub arm without its F/T sensor, on joint torques, with a `files:` field."""
    base = load_config()
    text = open(base.source).read().split("\nft_sensors:")[0].replace("name: icub_right_arm", f"name: {name}")
    joints = ", ".join(base.joints)
    path = tmp_path / f"{name}.yaml"
    path.write_text(text + f"\nactuation:\n  - {{name: arm, input: torque, joints: [{joints}]}}\n" + files)
    return path


def stacked_setup(tmp_path: Path) -> tuple[Path, Path, dict[str, np.ndarray]]:
    """The Panda's layout: t in ms alone, then q (deg) and τ with one value a line, a sample's on consecutive lines."""
    joints = load_config().joints
    files = ("files:\n  \"*_time.txt\": [t ms]\n"
             f"  \"*_positions.txt\": [{', '.join(f'q.{j} deg' for j in joints)}]\n"
             f"  \"*_torques.txt\": [{', '.join(f'tau.{j} Nm' for j in joints)}]\n")
    cfg = config_with(tmp_path, files)
    rng = np.random.default_rng(0)
    values = {"t": np.arange(N) * 2.0 + rng.uniform(-0.3, 0.3, N), "q": rng.uniform(-20, 20, (N, len(joints))),
              "tau": rng.normal(0, 3, (N, len(joints)))}
    run = tmp_path / "run_01"
    run.mkdir()
    np.savetxt(run / "run_01_time.txt", values["t"], fmt="%.17g")
    np.savetxt(run / "run_01_positions.txt", values["q"].reshape(-1), fmt="%.17g")
    np.savetxt(run / "run_01_torques.txt", values["tau"].reshape(-1), fmt="%.17g")
    return cfg, run, values


def rows_setup(tmp_path: Path) -> tuple[Path, Path, dict[str, np.ndarray]]:
    """PAL's layout: a header line, a sample a line, each file with its own copy of t; an extra column kept."""
    joints = load_config().joints
    files = ("files:\n"
             f"  position.csv: [t s, {', '.join(f'q.{j} rad' for j in joints)}]\n"
             f"  effort.csv: [t s, {', '.join(f'tau.{j} Nm' for j in joints)}, _, effort.raw raw]\n")
    cfg = config_with(tmp_path, files)
    rng = np.random.default_rng(1)
    t = np.arange(N) * 0.01
    values = {"t": t, "q": rng.uniform(-1, 1, (N, len(joints))), "tau": rng.normal(0, 3, (N, len(joints))),
              "skipped": rng.normal(size=N), "raw": rng.normal(size=N)}
    run = tmp_path / "pal"
    run.mkdir()
    header = "t," + ",".join(f"- {j}_position" for j in joints)
    np.savetxt(run / "position.csv", np.column_stack([t, values["q"]]), delimiter=",", fmt="%.17g", header=header,
               comments="")
    header = "t," + ",".join(f"- {j}_effort" for j in joints) + ",skipped,raw"
    np.savetxt(run / "effort.csv", np.column_stack([t, values["tau"], values["skipped"], values["raw"]]),
               delimiter=",", fmt="%.17g", header=header, comments="")
    return cfg, run, values


def test_one_value_a_line_is_read_a_sample_per_n_lines(tmp_path: Path) -> None:
    cfg, run, values = stacked_setup(tmp_path)
    config = load_config(cfg)
    ds = load_data(run, config)
    assert ds.meta["source_format"] == "file set" and ds.n_samples == N
    np.testing.assert_allclose(ds.t, values["t"] * 1e-3, rtol=1e-15)
    np.testing.assert_allclose(ds.q, np.radians(values["q"]), rtol=1e-15)
    for i, j in enumerate(config.joints):
        assert np.array_equal(ds.tau[j], values["tau"][:, i])


def test_a_sample_a_line_with_headers_and_one_clock(tmp_path: Path) -> None:
    cfg, run, values = rows_setup(tmp_path)
    ds = load_data(run, load_config(cfg))
    assert np.array_equal(ds.t, values["t"]) and np.array_equal(ds.q, values["q"])
    assert np.array_equal(ds.extra["effort.raw"], values["raw"]) and "skipped" not in ds.extra
    assert data_digest(run) == data_digest(run)  # the fit's record of the run, checked again by export
    before = data_digest(run)
    (run / "effort.csv").write_text((run / "effort.csv").read_text().replace("\n0,", "\n0.0,", 1))
    assert data_digest(run) != before


def test_a_folder_of_files_is_one_run_where_runs_are_listed(tmp_path: Path) -> None:
    cfg, run, _ = stacked_setup(tmp_path)
    config = load_config(cfg)
    assert holds_file_set(run, config) and not holds_file_set(tmp_path, config)
    assert expand(str(tmp_path), run_folder=lambda p: holds_file_set(p, config)) == [run]
    # `dynid fit --data PARENT` reads the folder as one run, not as three .txt files: here it is refused for its
    # random positions, which are outside the arm's limits, and the refusal names the folder
    done = dynid("fit", "--robot", str(cfg), "--data", str(tmp_path),
                           "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and done.stderr.strip().startswith(f"dynid fit: error: {run}: q.")


def _bad(tmp_path: Path, setup, change, message: str) -> None:
    cfg, run, _ = setup(tmp_path)
    change(run)
    with pytest.raises(DataError, match=message):
        load_data(run, load_config(cfg))


def _rewrite(path: Path, edit) -> None:
    path.write_text(edit(path.read_text()))


@pytest.mark.parametrize("change, message", [
    (lambda run: (run / "run_01_time.txt").unlink(), r"'\*_time.txt' of the configuration's files: field matches no "
                                                     r"file; the folder holds run_01_positions.txt"),
    (lambda run: (run / "run_02_time.txt").write_text("0\n"), r"'\*_time.txt' .* matches 2 files \(run_01_time.txt, "
                                                              r"run_02_time.txt\)"),
    # A file with a sample more than the others: the others' last sample is cut short, a bad row (below: skipped).
    (lambda run: _rewrite(run / "run_01_torques.txt", lambda s: s + "1\n" * 7),
     r"run_01_time.txt ends after sample 300, run_01_torques.txt holds 301: sample 301 is cut short \(1 bad row of "
     r"301;"),
    (lambda run: _rewrite(run / "run_01_torques.txt", lambda s: s + "1\n"),
     r"sample 301 is cut short \(1 bad row of 301;"),
    (lambda run: (run / "run_01_time.txt").write_text("1,2\n" * N), r"its lines hold 2 values, but the configuration "
                                                                    r"describes 1 columns"),
    (lambda run: (run / "run_01_time.txt").write_text(""), r"run_01_time.txt: the file is empty"),
])
def test_a_bad_folder_is_refused_in_one_line(tmp_path: Path, change, message: str) -> None:
    _bad(tmp_path, stacked_setup, change, message)


@pytest.mark.parametrize("change, message", [
    (lambda run: _rewrite(run / "effort.csv", lambda s: s.replace("\n0.01,", "\n0.010002,", 1)),
     r"sample 2's t is 0.01 s in position.csv and 0.010002 s in effort.csv \(they differ on 1 samples\): the files "
     r"must share one clock"),
    (lambda run: _rewrite(run / "effort.csv", lambda s: s.replace(",skipped,raw", ",raw", 1)),
     r"effort.csv: the header line has 9 fields, but the configuration's files.'effort.csv' describes 10 columns"),
    (lambda run: _rewrite(run / "position.csv", lambda s: s.split("\n", 1)[0] + "\n"), r"a header but no data lines"),
])
def test_a_bad_table_of_the_folder_is_refused_in_one_line(tmp_path: Path, change, message: str) -> None:
    _bad(tmp_path, rows_setup, change, message)


def test_a_file_that_ends_early_leaves_its_missing_samples_cut_short(tmp_path: Path) -> None:
    # The logger stopped: the torques end 40 samples early, 3 lines into the last one they have.
    cfg, run, _ = stacked_setup(tmp_path)
    _rewrite(run / "run_01_torques.txt", lambda s: "".join(s.splitlines(keepends=True)[: 7 * 259 + 3]))
    with pytest.raises(DataError, match=r"41 bad rows of 300: 41 cut short; at sample 260, .*the first: "
                                        r"run_01_torques.txt ends 3 of 7 lines into sample 260: the last sample, cut "
                                        r"short"):
        load_data(run, load_config(cfg))
    ds = load_data(run, load_config(cfg), bad_rows="skip")
    assert ds.n_samples == 259 and ds.meta["bad_rows"]["count"] == 41 and ds.meta["bad_rows"]["kinds"] == {"cut_short": 41}


def _smooth(run: Path, values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The stacked layout's positions and torques as signals move (each joint its own slow sine about its own level),
    rewritten in place: a line lost inside shows against them, as against a real log."""
    t = np.arange(N)[:, None] * 2e-3
    k = np.arange(values["q"].shape[1])[None, :]
    q = 10.0 * (k - 3) + 5.0 * np.sin(2 * np.pi * (0.3 + 0.1 * k) * t + k)
    tau = 2.0 * (k - 3) + np.cos(2 * np.pi * (0.2 + 0.15 * k) * t)
    np.savetxt(run / "run_01_positions.txt", q.reshape(-1), fmt="%.17g")
    np.savetxt(run / "run_01_torques.txt", tau.reshape(-1), fmt="%.17g")
    return {**values, "q": q, "tau": tau}


def test_a_line_lost_or_added_inside_a_file_is_named_not_taken_for_a_cut_last_sample(tmp_path: Path) -> None:
    # A walkthrough's Panda log with line 70000 of its torques deleted read as "ends 6 of 7 lines into sample 20544:
    # the last sample, cut short", and --bad-rows skip then fitted every later torque in the next joint's place.
    cfg, run, values = stacked_setup(tmp_path)
    values = _smooth(run, values)
    config = load_config(cfg)
    ds = load_data(run, config)  # the clean run reads as written
    np.testing.assert_allclose(ds.q, np.radians(values["q"]), rtol=1e-15)
    lines = (run / "run_01_torques.txt").read_text().splitlines(keepends=True)
    for at in (7 * 120 + 3, 7 * 200):  # inside a sample, and at one's first line
        (run / "run_01_torques.txt").write_text("".join(lines[:at] + lines[at + 1:]))
        for policy in ("refuse", "skip"):
            with pytest.raises(DataError, match=rf"run_01_torques.txt: a line is missing just before line {at + 1} "
                                                r"\(from there on every value sits in the next signal's place"):
                load_data(run, config, bad_rows=policy)
        (run / "run_01_torques.txt").write_text("".join(lines[:at] + [lines[at]] + lines[at:]))
        with pytest.raises(DataError, match=rf"run_01_torques.txt: line {at + 1} is one too many"):
            load_data(run, config, bad_rows="skip")
    # the logger stopping mid-sample is what it was: its last sample cut short, skipped on request
    (run / "run_01_torques.txt").write_text("".join(lines[:-3]))
    with pytest.raises(DataError, match=r"run_01_torques.txt ends 4 of 7 lines into sample 300: the last sample, cut "
                                        r"short"):
        load_data(run, config)
    assert load_data(run, config, bad_rows="skip").n_samples == N - 1
    # a column too many in the configuration: the file's lines are the run's samples of 7, not of 8
    (run / "run_01_torques.txt").write_text("".join(lines))
    wide = Path(str(cfg).replace(".yaml", "_wide.yaml"))
    wide.write_text(cfg.read_text().replace('"*_torques.txt": [', '"*_torques.txt": [_, ', 1).replace(
        "name: arm_files", "name: arm_files_wide"))
    with pytest.raises(DataError, match=r"run_01_torques.txt: its 2100 lines are 300 samples of 7 values, as many "
                                        r"samples as run_01_time.txt holds, but the configuration's "
                                        r"files.'\*_torques.txt' names 8 columns for it"):
        load_data(run, load_config(wide))


def test_a_bad_line_is_its_samples_bad_row_refused_or_skipped(tmp_path: Path) -> None:
    cfg, run, values = stacked_setup(tmp_path)
    lines = (run / "run_01_positions.txt").read_text().split("\n")
    lines[7 * 5 + 3] = "nope"  # sample 6's fourth joint
    (run / "run_01_positions.txt").write_text("\n".join(lines))
    config = load_config(cfg)
    with pytest.raises(DataError, match=r"run_01: run_01_positions.txt line 39, column q.r_elbow: 'nope' is not a number \(1 bad row of 300; "
                                        r"--bad-rows skip"):
        load_data(run, config)
    ds = load_data(run, config, bad_rows="skip")
    assert ds.n_samples == N - 1 and ds.meta["bad_rows"]["count"] == 1 and ds.meta["bad_rows"]["first"] == ["sample 6"]
    keep = np.arange(N) != 5
    np.testing.assert_allclose(ds.t, values["t"][keep] * 1e-3, rtol=1e-15)  # every file's rows stay together
    np.testing.assert_allclose(ds.q, np.radians(values["q"][keep]), rtol=1e-15)


def test_the_command_line_says_it_in_one_line_with_exit_2(tmp_path: Path) -> None:
    cfg, run, _ = stacked_setup(tmp_path)
    (run / "run_01_torques.txt").unlink()
    out = tmp_path / "run.npz"
    done = dynid("import", "--robot", str(cfg), "--data", str(run),
                           "--out", str(out))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert "'*_torques.txt' of the configuration's files: field matches no file" in done.stderr and not out.exists()


def test_fit_on_a_folder_the_files_field_does_not_match_says_how_it_read_it(tmp_path: Path) -> None:
    """Another robot's logger folder (TIAGo's names under a configuration whose `files:` are the Panda's): read as a
    folder of runs, its first file fails; the error says why the folder was not one run of the configuration."""
    cfg, run, _ = stacked_setup(tmp_path)
    for name in list(run.iterdir()):  # another logger's names: run_01_time.csv, ...
        name.rename(name.with_suffix(".csv"))
    done = dynid("fit", "--robot", str(cfg), "--data", str(run),
                           "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    # The folder's mismatch first, as validate says it; then what reading it as a folder of runs ran into.
    assert done.stderr.startswith(f"dynid fit: error: {run}: '"), done.stderr
    assert "of the configuration's files: field matches no file; the folder holds run_01_positions.csv" in done.stderr
    assert "(read instead as a folder of runs, one a file, it failed: " in done.stderr
    assert not (tmp_path / "m.json").exists()


@pytest.mark.parametrize("files, message", [
    ("files: [a.txt]\n", r"field 'files' must be a mapping of file name \(or glob\) to its columns"),
    ("files: {}\n", r"field 'files' must be a mapping"),
    ("files:\n  sub/t.txt: [t s]\n", r"the key 'sub/t.txt': a key must be a file name in the run's folder"),
    ("files:\n  a.txt: [q.r_shoulder_pitch rad]\n", r"field 'files' must name the time column 't' in one of its files"),
    ("files:\n  a.txt: [t s, q.r_shoulder_pitch rad]\n  b.txt: [t s, q.r_shoulder_pitch deg]\n",
     r"field 'files.b.txt' names the column 'q.r_shoulder_pitch', which 'files.a.txt' names too"),
    ("files:\n  a.txt: [t s]\n  b.txt: [_, _]\n", r"field 'files.b.txt' skips every column"),
    ("files:\n  a.txt: [t s, q.r_shoulder_pitch A]\n", r"field 'files.a.txt\[1\]': 'q.r_shoulder_pitch' must give its "
                                                       r"unit, one of rad, deg"),
])
def test_a_bad_files_field_is_refused_naming_the_entry(tmp_path: Path, files: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_config(config_with(tmp_path, files))


def test_units_are_converted_as_columns_converts_them(tmp_path: Path) -> None:
    cfg, run, values = stacked_setup(tmp_path)
    ds = load_data(run, load_config(cfg))
    assert ds.q[3, 2] == pytest.approx(values["q"][3, 2] * math.pi / 180.0, rel=1e-15)
