"""Reading a candump log (dynid.io.candump) on small logs written here: what it says about contact ground truth, and
its bad lines under `--bad-rows` (docs/formats.md#candump-log).

The logs are written by `write_candump` from a synthetic run of 200 samples at 1 kHz (the iCub arm, whose bus carries
five skin boards, and the iCub leg, whose bus carries none), then edited line by line.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.errors import DataNote
from dynid.io.candump import write_candump
from dynid.io.dataset import Dataset
from dynid.io.load import load_data

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
    quiet, _ = read(log_of(tmp_path, ARM, run_of(ARM, contact=False), name="quiet.log"), ARM)
    assert quiet.contact is not None and not quiet.contact.any()


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
