"""Reading a candump log (dynid.io.candump) on small logs written here: what it says about contact ground truth, and
its bad lines under `--bad-rows` (docs/formats.md#candump-log).

The logs are written by `write_candump` from a synthetic run of 200 samples at 1 kHz (the iCub arm, whose bus carries
five skin boards, and the iCub leg, whose bus carries none), then edited line by line.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.errors import DataError, DataNote
from dynid.io.candump import write_candump
from dynid.io.dataset import Dataset
from dynid.io.load import load_data

from conftest import dynid

ARM = load_config("icub_right_arm")
LEG = load_config("icub_right_leg_standing", need_urdf=False)  # the bus alone: no URDF needed to read a log
N = 200


def run_of(config, contact: bool = True, seed: int = 0) -> Dataset:
    rng = np.random.default_rng(seed)
    n_j = len(config.joints)
    t = 0.001 * np.arange(N)
    q = 0.3 * np.sin(2 * np.pi * 0.5 * t[:, None] + rng.uniform(0, 1, n_j))
    labels = (np.arange(N) // 40) % 2  # contact on every other 40 ms
    return Dataset(t=t, joints=config.joints, q=q, pwm={m: rng.uniform(-0.5, 0.5, N) for m in config.motor_names},
                   ft={s.name: rng.normal(0, 5, (N, 6)) for s in config.ft_sensors},
                   contact=labels.astype(np.uint8) if contact else None)


def log_of(tmp_path: Path, config, data: Dataset, keep=lambda line: True, name: str = "run.log") -> Path:
    path = tmp_path / name
    write_candump(data, config, path)
    lines = path.read_text().splitlines()
    path.write_text("".join(line + "\n" for line in lines if keep(line)))
    return path


def read(path: Path, config, **kw) -> tuple[Dataset, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataNote)
        data = load_data(path, config, **kw)
    return data, [str(w.message) for w in caught if issubclass(w.category, DataNote)]


# ---- contact ground truth: only where the bus carried the skin's frames ----


def test_a_bus_without_skin_gives_a_run_without_contact_ground_truth(tmp_path: Path) -> None:
    """The iCub leg's bus has no skin board: its log knows nothing of contact, so the run has no contact column (an
    all-zero one made `dynid detect` report an FPR as if the run were known to be contact-free)."""
    data, notes = read(log_of(tmp_path, LEG, run_of(LEG)), LEG)
    assert data.contact is None and notes == []


def test_the_skin_frames_give_the_contact_column(tmp_path: Path) -> None:
    written = run_of(ARM)
    data, notes = read(log_of(tmp_path, ARM, written), ARM)
    assert data.contact is not None and notes == []
    np.testing.assert_array_equal(data.contact, written.contact[-data.n_samples:])
    # skin frames that report no contact are ground truth too: a run known to be contact-free
    known_free = replace(run_of(ARM), contact=np.zeros(N, np.uint8))
    quiet, _ = read(log_of(tmp_path, ARM, known_free, name="quiet.log"), ARM)
    assert quiet.contact is not None and not quiet.contact.any()
    # a run without contact labels is written without skin frames (not as all-zero taxels): it reads back without
    unlabelled, notes = read(log_of(tmp_path, ARM, run_of(ARM, contact=False), name="unlabelled.log"), ARM)
    assert unlabelled.contact is None and notes == []


def skin_frames(config) -> dict[str, str]:
    """patch -> the ` ID#` its board's frames carry in a candump line."""
    return {s.target[5:]: f" {f.id:03X}#" for f in config.bus.frames for s in f.signals if s.target.startswith("skin.")}


def test_a_log_without_the_skin_frames_has_no_contact_ground_truth(tmp_path: Path) -> None:
    ids = skin_frames(ARM)
    assert len(ids) == 5
    data, notes = read(log_of(tmp_path, ARM, run_of(ARM), lambda line: not any(i in line for i in ids.values())), ARM)
    assert data.contact is None and notes == []
    # one board silent: contact on its patch is unknown, so the labels of the others are no ground truth either
    data, notes = read(log_of(tmp_path, ARM, run_of(ARM), lambda line: ids["forearm"] not in line, "one.log"), ARM)
    assert data.contact is None
    assert len(notes) == 1 and "the contact of skin patch forearm is unknown" in notes[0], notes


# ---- bad lines: the --bad-rows policy of a CSV's rows ----


def damaged(tmp_path: Path, extra: dict[int, str], cut: str = "", name: str = "bad.log") -> tuple[Path, Path]:
    """The arm's clean log and a copy with `extra` lines inserted before the given 0-based lines of it, and `cut` (a
    frame line cut short) at its end without a line end."""
    clean = log_of(tmp_path, ARM, run_of(ARM), name="clean.log")
    lines = clean.read_text().splitlines()
    for at in sorted(extra, reverse=True):
        lines.insert(at, extra[at])
    bad = tmp_path / name
    bad.write_text("\n".join(lines) + "\n" + cut)
    return clean, bad


def same_run(a: Dataset, b: Dataset) -> None:
    for (name, x), (other, y) in zip(a.columns(), b.columns(), strict=True):
        assert name == other
        np.testing.assert_array_equal(x, y, err_msg=name)


def test_a_garbage_line_and_a_cut_last_line_are_refused_by_default_and_skipped_with_skip(tmp_path: Path) -> None:
    clean, bad = damaged(tmp_path, {99: "garbage here", 500: "(1700000000.000500) can0 141#00112"},
                         cut="(1700000000.199900) can0 3DA#00112")
    with pytest.raises(DataError) as refused:
        load_data(bad, ARM)
    message = str(refused.value)
    assert message.startswith(f"{bad}: 3 bad rows of ") and "\n" not in message
    assert "1 cut short, 2 not a candump -L frame; at line 100, line 502, line " in message
    assert "the first: line 100 is no classic-CAN candump -L frame" in message and "'garbage here'" in message

    data, _ = read(bad, ARM, bad_rows="skip")
    same_run(data, load_data(clean, ARM))
    record = data.meta["bad_rows"]
    assert record["count"] == 3 and record["kinds"] == {"cut_short": 1, "not_a_frame": 2}
    assert record["first"][:2] == ["line 100", "line 502"] and data.meta["skipped_lines"] == 3


def test_other_frames_blank_lines_and_comments_are_no_bad_rows(tmp_path: Path) -> None:
    """Extended, error and remote frames are bus traffic (skipped as frames of unknown IDs are, as rt_monitor --replay
    does); blank lines and `#` comments are no lines of the log."""
    clean, other = damaged(tmp_path, {10: "(1700000000.000010) can0 20000080#0000000000000000",
                                      20: "(1700000000.000020) can1 1ABCDEF0#0011", 30: "(1700000000.000030) can2 123#R",
                                      40: "", 50: "# a note"})
    data, notes = read(other, ARM)
    same_run(data, load_data(clean, ARM))
    assert "bad_rows" not in data.meta and data.meta["skipped_lines"] == 0 and notes == []


def test_a_can_fd_frame_is_a_bad_row_named_as_one(tmp_path: Path) -> None:
    _, bad = damaged(tmp_path, {10: "(1700000000.000010) can0 123##100112233"})
    with pytest.raises(DataError, match=r"line 11 is a CAN FD frame, .*: the log of a classic-CAN bus has none \(1 bad "
                                        r"row of \d+; --bad-rows skip"):
        load_data(bad, ARM)


def test_every_command_that_reads_the_log_follows_the_policy(tmp_path: Path, default_experiments: dict[str, Path],
                                                              default_model: Path) -> None:
    """import, fit, validate and detect read a candump log through one reader: the same refusal, and with skip the
    same count (a 1.5 s stretch of the default validation run as its boards send it)."""
    run = load_data(default_experiments["validation"], ARM)
    log = tmp_path / "run.log"
    write_candump(run.slice(0, 1500), ARM, log)
    lines = log.read_text().splitlines()
    lines.insert(1000, "(1700000000.5) can0 141#0011")  # a stamp of one digit of fraction: no candump -L line
    log.write_text("\n".join(lines) + "\n")
    refusal = f"{log}: line 1001 is no classic-CAN candump -L frame"
    for command in (("import", "--out", str(tmp_path / "d.npz")), ("fit", "--out", str(tmp_path / "m.json")),
                    ("validate", "--model", str(default_model)), ("detect", "--model", str(default_model))):
        done = dynid(command[0], "--data", str(log), *command[1:])
        assert done.returncode == 2 and refusal in done.stderr and done.stderr.count("\n") == 1, done.stderr
    for command in (("import", "--out", str(tmp_path / "d.npz")), ("validate", "--model", str(default_model))):
        done = dynid(command[0], "--data", str(log), *command[1:], "--bad-rows", "skip", "--json", "-")
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout)["bad_rows"]["first"] == ["line 1001"]
        assert f"{log}: skipped 1 bad row of {len(lines)} (1 not a candump -L frame; first at line 1001)" in done.stderr


@pytest.mark.parametrize("chunk", [1, 97, 4096])
def test_a_log_read_a_chunk_at_a_time_is_the_log_read_whole(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            chunk: int) -> None:
    """The log is parsed a chunk of whole lines at a time (bounded memory: a 182 MB log took 2.36 GB read whole,
    0.82 GB by chunks): at any chunk size, down to one byte, the run, the bad lines' numbers and kinds, a frame whose
    stamp is out of order (it sorts into place across chunks) and the last line cut short are those of one read."""
    import dynid.io.candump as candump

    clean, bad = damaged(tmp_path, {99: "garbage here", 500: "(1700000000.000500) can0 141#00112",
                                    700: "(1700000000.000001) can9 7FF#00"},
                         cut="(1700000000.199900) can0 3DA#00112")
    whole_data, whole_skip = read(bad, ARM, bad_rows="skip")
    with pytest.raises(DataError) as whole:
        load_data(bad, ARM)
    monkeypatch.setattr(candump, "_CHUNK", chunk)
    data, _ = read(bad, ARM, bad_rows="skip")
    same_run(data, whole_data)
    assert data.meta == whole_data.meta and data.meta["bad_rows"]["first"][:2] == ["line 100", "line 502"]
    with pytest.raises(DataError) as chunked:
        load_data(bad, ARM)
    assert str(chunked.value) == str(whole.value)
    frames = candump._read_frames(bad)
    assert np.all(np.diff(frames.t_us) >= 0) and "can9" in frames.buses
