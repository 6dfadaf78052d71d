"""Real logs' bad rows (dynid.io.bad_rows) and a window per run (`--data RUN@FROM:TO`).

The end-to-end case is the one real UR10e controller logs have: garbage rows at the start (t = −0.12 s, values
near 1e150) and a last row cut short. By default the run is refused with one line naming how many rows, which
kinds and where; with `--bad-rows skip` it fits, and the fit is the fit of the clean rows, the count reported in
the output, the `--json` and the model file. The simulated run is a 6 s Panda (joint torques), fitted in a
few seconds.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from dynid.cli import main
from dynid.config.robot_config import load_config
from dynid.errors import DataError
from dynid.identify.model_file import load_model
from dynid.io.align import keep_increasing
from dynid.io.csv_format import read_csv
from dynid.io.dataset import Dataset
from dynid.io.load import check_velocities, load_data

GARBAGE_ROWS = 9


def run(*argv: str) -> tuple[int, str, str]:
    """`dynid ARGV` in this process (so that two fits compare bit for bit): exit code, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def panda_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("panda")
    code, _, err = run("simulate", "--robot", "panda", "--duration", "6", "--out", str(root / "sim"))
    assert code == 0, err
    return root / "sim" / "data.csv"


def with_garbage(clean: Path, out: Path) -> Path:
    """`clean` as a controller logs it: nine garbage rows first, and one more row at the end, cut short."""
    header, *rows = clean.read_text().splitlines()
    width = header.count(",") + 1
    garbage = [",".join(["-0.12"] + [f"{1.7e150 * (1 + k / 10):.4e}"] * (width - 1)) for k in range(GARBAGE_ROWS)]
    last = rows[-1].split(",")
    last[0] = repr(float(last[0]) + 0.001)
    cut = ",".join(last[: width // 2])[:-3]  # the logger stopped mid-number
    out.write_text("\n".join([header, *garbage, *rows, cut]))  # no line end after the cut row
    return out


def test_a_log_with_garbage_rows_is_refused_in_one_line_then_fits_with_skip_like_the_clean_log(
        panda_run: Path, tmp_path: Path) -> None:
    bad = with_garbage(panda_run, tmp_path / "bad.csv")
    code, _, err = run("fit", "--robot", "panda", "--data", str(bad), "--out", str(tmp_path / "m.json"))
    lines = err.splitlines()
    assert code == 2 and len(lines) == 1, err
    assert (f"{GARBAGE_ROWS + 1} bad rows of" in lines[0] and f"{GARBAGE_ROWS} with a value beyond ±1e+06" in lines[0]
            and "1 cut short" in lines[0] and "at row 1 (line 2), row 2 (line 3)" in lines[0]
            and "--bad-rows skip" in lines[0]), lines[0]
    assert not (tmp_path / "m.json").exists()

    skipped, clean = tmp_path / "skipped.json", tmp_path / "clean.json"
    code, out, err = run("fit", "--robot", "panda", "--data", str(bad), "--bad-rows", "skip", "--out", str(skipped),
                         "--json", str(tmp_path / "fit.json"))
    assert code == 0, err
    assert f"skipped {GARBAGE_ROWS + 1} bad rows of" in out
    reported = json.loads((tmp_path / "fit.json").read_text())["bad_rows"][str(bad)]
    assert reported["count"] == GARBAGE_ROWS + 1 and reported["policy"] == "skip"
    assert reported["kinds"] == {"cut_short": 1, "out_of_range": GARBAGE_ROWS}
    recorded = load_model(str(skipped)).data[0].bad_rows
    assert recorded == reported

    code, _, err = run("fit", "--robot", "panda", "--data", str(panda_run), "--out", str(clean))
    assert code == 0, err
    # The rows kept are the clean log's, bit for bit; so is the fit (one process: the same arithmetic).
    config = load_config("panda")
    a, b = load_data(bad, config, bad_rows="skip"), load_data(panda_run, config)
    assert all(np.array_equal(x, y) for (_, x), (_, y) in zip(a.columns(), b.columns(), strict=True))
    assert load_model(str(skipped)).phi.tolist() == load_model(str(clean)).phi.tolist()
    # validate and detect say what they dropped too, and a reload (momentum calibration) repeats the skip.
    code, out, err = run("detect", "--model", str(skipped), "--data", str(bad), "--bad-rows", "skip", "--json",
                         str(tmp_path / "detect.json"))
    assert code == 0, err
    assert json.loads((tmp_path / "detect.json").read_text())["bad_rows"]["count"] == GARBAGE_ROWS + 1


def table(tmp_path: Path, rows: list[str], end: str = "\n") -> Path:
    joints = load_config().joints
    header = ",".join(["t", *(f"q.{j}" for j in joints)])
    path = tmp_path / "rows.csv"
    path.write_text(header + "\n" + "\n".join(rows) + end)
    return path


def good(t: float, joints: int) -> str:
    return ",".join([repr(t)] + ["0.1"] * joints)


def test_every_kind_is_counted_and_only_bad_rows_are_dropped(tmp_path: Path) -> None:
    config = load_config()
    n = len(config.joints)
    rows = [good(0.001 * k, n) for k in range(200)]
    rows[3] = ""                                             # empty
    rows[10] = good(0.010, n) + ",0.1"                       # a field too many
    rows[20] = good(0.020, n).replace("0.1", "abc", 1)       # not a number
    rows[30] = good(0.030, n).replace("0.1", "nan", 1)       # non-finite
    rows[40] = good(0.040, n).replace("0.1", "2e6", 1)       # beyond ±1e6
    rows[50] = good(-0.5, n)                                 # a negative time
    rows[60] = good(0.055, n)                                # re-sent: t goes back
    rows[199] = ",".join(good(0.199, n).split(",")[:3])      # the last line, cut short
    path = table(tmp_path, rows, end="")
    with pytest.raises(DataError) as refused:
        read_csv(path, config, require_all=False)
    message = str(refused.value)
    for words in ("8 bad rows of 200", "1 cut short", "1 empty", "1 with a wrong number of fields",
                  "1 with a cell that is not a number", "1 with a non-finite value", "1 with a value beyond ±1e+06",
                  "1 with a negative time", "1 whose time is out of order",
                  "at row 4 (line 5), row 11 (line 12), row 21 (line 22), row 31 (line 32), row 41 (line 42), ...",
                  "the first: line 5 is empty"):
        assert words in message, message
    kept = read_csv(path, config, require_all=False, bad_rows="skip")
    dropped = {3, 10, 20, 30, 40, 50, 60, 199}
    assert kept.t.tolist() == [0.001 * k for k in range(200) if k not in dropped]
    assert kept.meta["bad_rows"]["count"] == 8 and kept.meta["bad_rows"]["rows_read"] == 200


@pytest.mark.parametrize(("stamp", "says"), [
    # a stale row: the message it always had
    (0.05, r"t is not strictly increasing at row 101 \(line 102\): 0\.05 s follows 0\.099 s \(1 bad row of 600;"),
    # a stamp ahead of its neighbours: the rule "beat every earlier stamp" kept it and dropped the 499 good rows after
    # it, up to t = 0.6 s; the longest increasing run keeps them and drops it
    (0.6, r"t is out of order at row 101 \(line 102\): 0\.6 s, ahead of the next row kept \(0\.101 s\) \(1 bad row "
          r"of 600;"),
])
def test_one_row_out_of_order_drops_itself_only(tmp_path: Path, stamp: float, says: str) -> None:
    config = load_config()
    n = len(config.joints)
    rows = [good(0.001 * k, n) for k in range(600)]
    rows[100] = good(stamp, n)
    path = table(tmp_path, rows)
    with pytest.raises(DataError, match=says):
        read_csv(path, config, require_all=False)
    kept = read_csv(path, config, require_all=False, bad_rows="skip")
    assert kept.t.tolist() == [0.001 * k for k in range(600) if k != 100]


def _with_velocities(clean: Path, out: Path, change=None) -> Path:
    """`clean` with dq columns, the derivative of its q (as a controller records them), `change`d: (dq, tau) -> dq."""
    config = load_config("panda")
    ds = load_data(clean, config)
    dq = np.gradient(ds.q, ds.t, axis=0)
    if change is not None:
        dq = change(dq, np.column_stack([ds.tau[j] for j in ds.joints]))
    header, *rows = clean.read_text().splitlines()
    names = [f"dq.{j}" for j in ds.joints]
    out.write_text("\n".join([header + "," + ",".join(names)]
                             + [r + "," + ",".join(repr(float(x)) for x in dq[k]) for k, r in enumerate(rows)]) + "\n")
    return out


def test_recorded_velocities_are_checked_against_the_positions(panda_run: Path, tmp_path: Path) -> None:
    config = load_config("panda")
    good = load_data(_with_velocities(panda_run, tmp_path / "good.csv"), config)
    assert good.meta.get("derivatives", {}).get("dq", "recorded") == "recorded"
    with pytest.raises(DataError, match=r"dq\.panda_joint1 is 57\.\d times the rate of q\.panda_joint1 \(the "
                                        r"velocity in deg/s, or q in rad declared deg\?"):
        load_data(_with_velocities(panda_run, tmp_path / "deg.csv", lambda dq, tau: np.degrees(dq)), config)

    def torque_in_place(dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        moving = int(np.argmax(np.sqrt(np.mean(dq**2, axis=0))))  # a joint that moves: the check looks at it
        dq[:, moving] = tau[:, moving]
        return dq

    with pytest.raises(DataError, match=r"does not follow the motion of q\.panda_joint\d \(its travel, scaled, leaves "
                                        r"\d+ % unexplained while the joint moves\): another signal's column\?"):
        load_data(_with_velocities(panda_run, tmp_path / "shifted.csv", torque_in_place), config)


def test_an_input_within_its_noise_while_its_joint_moves_is_noted(panda_run: Path, tmp_path: Path) -> None:
    # A walkthrough's UR10e with a current declared mA that the log holds in A: read 1000 times too small, the fit
    # took it and validate's overall figure looked better. Here the Panda's joint torques, one of them so scaled.
    from dynid.io.load import quiet_inputs

    config = load_config("panda")
    ds = load_data(panda_run, config)
    assert quiet_inputs(config, ds) == []
    ds.tau["panda_joint1"] = ds.tau["panda_joint1"] * 1e-3
    notes = quiet_inputs(config, ds)
    assert len(notes) == 1 and notes[0].startswith("tau.panda_joint1 stays within its noise while its joint moves"), notes
    code, _, err = run("fit", "--robot", "panda", "--data", str(panda_run), "--out", str(tmp_path / "m.json"))
    assert code == 0 and "stays within its noise" not in err, err


def test_a_velocity_column_of_zeros_is_named_as_such() -> None:
    t = np.arange(5000) * 1e-3
    with pytest.raises(DataError, match=r"dq\.a is zero throughout while q\.a moves"):
        check_velocities(Dataset(t=t, joints=("a",), q=np.sin(t)[:, None], dq=np.zeros((t.size, 1))))


def test_a_joint_at_constant_speed_with_a_wrapped_angle_passes_the_velocity_check() -> None:
    t = np.arange(20000) * 1e-3
    q = (2.0 * t[:, None] + np.pi) % (2 * np.pi) - np.pi  # a continuous joint turning at 2 rad/s, logged in [−π, π)
    check_velocities(Dataset(t=t, joints=("wheel",), q=q, dq=np.full((t.size, 1), 2.0)))
    with pytest.raises(DataError, match=r"dq\.wheel is 57\.3 times the rate of q\.wheel \(the velocity in deg/s"):
        check_velocities(Dataset(t=t, joints=("wheel",), q=q, dq=np.full((t.size, 1), np.degrees(2.0))))


def test_positions_read_in_the_wrong_unit_are_caught_where_they_look_still() -> None:
    # rad declared deg: q imported 57.3 times too small, so the joint looks still (0.01 rad/s RMS, under the check's
    # moving speed) while its recorded velocity travels at 0.7 rad/s. The fit would take it (the walkthrough's Panda).
    t = np.arange(20000) * 1e-3
    q_true = np.sin(t)[:, None]
    dq = np.cos(t)[:, None]
    with pytest.raises(DataError, match=r"dq\.a is 57\.3 times the rate of q\.a \(the velocity in deg/s, or q in rad "
                                        r"declared deg\?"):
        check_velocities(Dataset(t=t, joints=("a",), q=np.radians(q_true), dq=dq))
    with pytest.raises(DataError, match=r"dq\.a moves while q\.a stays still"):
        check_velocities(Dataset(t=t, joints=("a",), q=np.zeros_like(q_true), dq=dq))
    # a still joint's velocity noise travels nowhere (integrated over each stretch) and is not judged
    noise = np.random.default_rng(0).normal(0.0, 0.05, dq.shape)
    check_velocities(Dataset(t=t, joints=("a",), q=np.full_like(q_true, 0.3), dq=noise))


@pytest.mark.parametrize(("stamps", "dropped"), [
    (np.r_[np.arange(10.0), 3.5, np.arange(10.0, 20.0)], [10]),          # re-sent with an old stamp
    (np.r_[np.arange(10.0), 50.0, np.arange(10.0, 20.0)], [10]),         # stamped ahead
    (np.r_[0.0, 1.0, 1.0, 2.0], [2]),                                    # repeated: the later one goes
    (np.r_[np.arange(8.0), np.arange(3.0)], [8, 9, 10]),                 # a clock that restarts: the longer stretch
    (np.r_[np.arange(3.0), np.arange(8.0)], [3, 4, 5]),
    (np.arange(5.0), []),
])
def test_keep_increasing_keeps_the_longest_increasing_run_earliest_first(stamps: np.ndarray, dropped: list[int]
                                                                         ) -> None:
    keep = keep_increasing(stamps)
    assert np.flatnonzero(~keep).tolist() == dropped
    assert np.all(np.diff(stamps[keep]) > 0)


def test_a_window_per_run_cuts_that_run_alone_and_the_model_file_keeps_it(panda_run: Path, tmp_path: Path) -> None:
    windowed, whole = tmp_path / "w.npz", tmp_path / "g.npz"
    assert run("import", "--robot", "panda", "--data", f"{panda_run}@1.5:4", "--out", str(windowed))[0] == 0
    assert run("import", "--robot", "panda", "--data", str(panda_run), "--from", "1.5", "--to", "4", "--out",
               str(whole))[0] == 0
    a, b = (load_data(p, load_config("panda")) for p in (windowed, whole))
    assert a.t[0] >= 1.5 and a.t[-1] <= 4 and np.array_equal(a.t, b.t)

    model = tmp_path / "m.json"
    other = tmp_path / "other"  # a second run of the same arm (windows of one run may not overlap: they count twice)
    assert run("simulate", "--robot", "panda", "--duration", "6", "--seed", "1", "--out", str(other))[0] == 0
    code, _, err = run("fit", "--robot", "panda", "--data", f"{panda_run}@1:5", "--data", str(other / "data.csv"),
                       "--from", "0.5", "--out", str(model))
    assert code == 0, err
    first, second = load_model(str(model)).data
    assert first.window == (1.0, 5.0) and second.window == (0.5, None)
    assert first.samples == 4001 and second.samples == 5500
    # The momentum detector recalibrates on the runs as fitted: the recorded windows, not the whole files.
    code, _, err = run("detect", "--model", str(model), "--data", str(panda_run), "--residual", "momentum")
    assert code == 0, err


def test_samples_given_twice_are_refused_before_the_fit(panda_run: Path, tmp_path: Path) -> None:
    # Two windows of one run that share time, or one recording under two names (a walkthrough's folder and its own
    # `dynid import`): the shared samples would count twice, and the copies pose as independent runs.
    model = tmp_path / "m.json"
    code, _, err = run("fit", "--robot", "panda", "--data", f"{panda_run}@1:5", "--data", str(panda_run),
                       "--from", "0.5", "--out", str(model))
    assert code == 2 and err.strip().endswith(f"--data: {panda_run}@1:5 and {panda_run}@0.5: are windows of one run "
                                              "that overlap: the samples they share would count twice (give windows "
                                              "that do not overlap)"), err
    copy = tmp_path / "copy.npz"
    assert run("import", "--robot", "panda", "--data", str(panda_run), "--out", str(copy))[0] == 0
    code, _, err = run("fit", "--robot", "panda", "--data", f"{panda_run}@:4", "--data", f"{copy}@:4", "--out",
                       str(model))
    assert code == 2 and f"--data {panda_run} and {copy} hold the same samples" in err, err
    assert not model.exists()
    # ... and with its stamps moved to the epoch (a walkthrough's bag of the same log): the same samples all the same
    from dataclasses import replace

    from dynid.config.robot_config import load_config
    from dynid.io.load import load_data

    recorded = load_data(copy, load_config("panda"))
    shifted = tmp_path / "epoch.npz"
    replace(recorded, t=recorded.t + 1.7e9).save(shifted)
    code, _, err = run("fit", "--robot", "panda", "--data", f"{copy}", "--data", f"{shifted}", "--out", str(model))
    assert code == 2 and f"--data {copy} and {shifted} hold the same samples" in err, err
    code, _, err = run("fit", "--robot", "panda", "--data", f"{panda_run}@:3", "--data", f"{copy}@3:", "--out",
                       str(model))
    assert code == 0, err


@pytest.mark.parametrize(("suffix", "says"), [("@a:4", "'a': 'a' is not a number"),
                                              ("@:", "names neither FROM nor TO"),
                                              ("@5:2", "the window's end, 2 s, must come after its start, 5 s")])
def test_a_wrong_window_is_one_line(panda_run: Path, tmp_path: Path, suffix: str, says: str) -> None:
    code, _, err = run("import", "--robot", "panda", "--data", f"{panda_run}{suffix}", "--out", str(tmp_path / "x.npz"))
    assert code == 2 and len(err.splitlines()) == 1 and says in err, err
