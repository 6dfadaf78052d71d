"""The Dataset structure, its on-disk format (atomic, versioned, validated) and `load_data` dispatch."""

from __future__ import annotations

import json
import types
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.errors import DataError
from dynid.io import dataset as dataset_module
from dynid.io.csv_format import write_csv
from dynid.io.dataset import FORMAT_VERSION, Dataset
from dynid.io.load import MIN_SAMPLES, load_data

CFG = load_config("icub_right_arm")
JOINTS = CFG.joints


def make(n: int = 20, **overrides: Any) -> Dataset:
    rng = np.random.default_rng(3)
    fields: dict[str, Any] = dict(
        t=0.001 * np.arange(n) + 0.5,
        joints=JOINTS,
        q=rng.uniform(-1, 1, (n, 7)),
        pwm={m: rng.uniform(-1, 1, n) for m in CFG.motor_names},
        ft={"r_arm_ft": rng.standard_normal((n, 6))},
        contact=(np.arange(n) % 5 == 0),
        extra={"contact_side": np.arange(n) % 3 * 1.0},
        meta={"robot": CFG.name, "note": "synthetic"},
    )
    fields.update(overrides)
    return Dataset(**fields)


def same(a: Dataset, b: Dataset) -> bool:
    ca, cb = a.columns(), b.columns()
    return (
        a.joints == b.joints
        and [n for n, _ in ca] == [n for n, _ in cb]
        and all(x.dtype == y.dtype and np.array_equal(x, y) for (_, x), (_, y) in zip(ca, cb, strict=True))
        and a.meta == b.meta
    )


def one_line_error(fn: Any, *args: Any, **kwargs: Any) -> str:
    with pytest.raises(DataError) as info:
        fn(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


# ----------------------------------------------------------------------------------------------------------
# The structure


def test_basic_properties() -> None:
    ds = make(20)
    assert ds.n_samples == 20 and ds.n_joints == 7
    assert ds.duration == pytest.approx(0.019)
    assert ds.contact.dtype == np.uint8 and ds.contact.sum() == 4
    assert ds.column_names()[:2] == ["t", "q.r_shoulder_pitch"]
    assert ds.column_names()[-2:] == ["contact", "contact_side"]
    assert ds.validate() is ds


VALIDATION_CASES = {
    "q shape": (dict(q=np.zeros((20, 6))), "q must have shape (20, 7)"),
    "dq shape": (dict(dq=np.zeros((19, 7))), "dq must have shape (20, 7)"),
    "pwm shape": (dict(pwm={"m0": np.zeros(19)}), "pwm.m0 must have shape (20,)"),
    "ft shape": (dict(ft={"r_arm_ft": np.zeros((20, 3))}), "ft.r_arm_ft must have shape (20, 6)"),
    "tau joint": (dict(tau={"knee": np.zeros(20)}), "tau.knee names a joint"),
    "nan": (dict(extra={"x": np.r_[np.zeros(4), np.nan, np.zeros(15)]}), "x is nan at row 5"),
    "t repeats": (dict(t=np.r_[0.0, 0.1, 0.1, np.arange(3, 20) * 0.1]), "t is not strictly increasing at row 3"),
    "empty": (dict(t=np.zeros(0), q=np.zeros((0, 7)), pwm={}, ft={}, contact=None, extra={}), "non-empty"),
    "joints": (dict(joints=JOINTS[:-1] + (JOINTS[0],)), "distinct"),
    "meta": (dict(meta={"x": object()}), "JSON"),
}


@pytest.mark.parametrize("case", VALIDATION_CASES, ids=list(VALIDATION_CASES))
def test_validate(case: str) -> None:
    overrides, words = VALIDATION_CASES[case]
    assert words in one_line_error(make(20, **overrides).validate)


def test_slice_copies_rows_and_records_them() -> None:
    ds = make(20)
    part = ds.slice(5, 15)
    assert part.n_samples == 10 and part.t[0] == ds.t[5] and np.array_equal(part.q, ds.q[5:15])
    assert np.array_equal(part.ft["r_arm_ft"], ds.ft["r_arm_ft"][5:15]) and np.array_equal(
        part.contact, ds.contact[5:15]
    )
    assert part.meta["rows"] == [5, 15] and "rows" not in ds.meta
    part.q[0, 0] = 99.0
    assert ds.q[5, 0] != 99.0  # a copy, not a view
    assert part.slice(2, -1).meta["rows"] == [7, 14]
    assert ds.slice(None, None).n_samples == 20
    assert "select no sample" in one_line_error(ds.slice, 10, 10)


def test_with_derivatives_uses_the_estimator_only_for_missing_signals() -> None:
    calls = []

    def finite_difference(t: np.ndarray, q: np.ndarray) -> Any:
        calls.append(1)
        dq = np.gradient(q, t, axis=0)
        return types.SimpleNamespace(q=q, dq=dq, ddq=np.gradient(dq, t, axis=0))

    ds = make(20)
    full = ds.with_derivatives(finite_difference)
    assert ds.dq is None and full.dq.shape == (20, 7) and full.ddq.shape == (20, 7)
    assert full.meta["derivatives"] == {"dq": "finite_difference", "ddq": "finite_difference"}
    assert np.array_equal(full.q, ds.q)

    recorded = make(20, dq=np.ones((20, 7)))
    half = recorded.with_derivatives(finite_difference)
    assert np.array_equal(half.dq, np.ones((20, 7)))  # a recorded dq is kept
    assert half.meta["derivatives"] == {"dq": "recorded", "ddq": "finite_difference"}

    again = full.with_derivatives(finite_difference)
    assert len(calls) == 2 and again.meta["derivatives"]["dq"] == "finite_difference"  # nothing re-estimated


def test_with_derivatives_defaults_to_dynid_derivatives(monkeypatch: pytest.MonkeyPatch) -> None:
    seen = {}

    def estimate_derivatives(t: np.ndarray, q: np.ndarray, method: str = "savgol", **options: Any) -> Any:
        seen.update(method=method, **options)
        return types.SimpleNamespace(q=q, dq=np.zeros_like(q), ddq=np.ones_like(q))

    monkeypatch.setattr(dataset_module, "estimate_derivatives", estimate_derivatives)
    out = make(20).with_derivatives(window=0.05)
    assert seen == {"method": "savgol", "window": 0.05}
    assert out.meta["derivatives"] == {"dq": "savgol", "ddq": "savgol", "options": {"window": 0.05}}
    assert make(20).with_derivatives("spline").meta["derivatives"]["ddq"] == "spline"


def test_with_derivatives_real_estimator() -> None:
    t = np.arange(2000) * 1e-3
    q = np.sin(2 * np.pi * t)[:, None] * np.ones((1, 7))
    out = make(2000, t=t, q=q).with_derivatives()
    inner = slice(100, -100)
    assert np.allclose(out.dq[inner, 0], 2 * np.pi * np.cos(2 * np.pi * t[inner]), atol=1e-2)
    assert out.meta["derivatives"]["dq"] not in ("recorded", "")


# ----------------------------------------------------------------------------------------------------------
# On disk


def test_save_load_round_trip(tmp_path: Path) -> None:
    ds = make(
        20, dq=np.ones((20, 7)), ddq=np.zeros((20, 7)), tau={"r_elbow": np.arange(20.0)}, current={"m1": np.ones(20)}
    )
    ds.save(tmp_path / "d.npz")
    back = Dataset.load(tmp_path / "d.npz")
    assert same(ds, back)
    assert list(back.pwm) == list(ds.pwm)  # channel order survives
    with np.load(tmp_path / "d.npz") as z:
        assert int(z["format_version"]) == FORMAT_VERSION and str(z["format"]) == "dynid-dataset"


def test_save_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "d.npz"
    make(20).save(path)
    before = path.read_bytes()

    def half_write(file: Any, **arrays: Any) -> None:
        file.write(b"PK\x03\x04 half a zip")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", half_write)
    with pytest.raises(DataError, match="disk full"):  # one line for the CLI, and the old file intact
        make(30).save(path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["d.npz"]  # no temporary file left behind
    assert Dataset.load(path).n_samples == 20


def test_save_refuses_an_invalid_dataset_and_a_missing_directory(tmp_path: Path) -> None:
    assert "nan" in one_line_error(make(20, q=np.full((20, 7), np.nan)).save, tmp_path / "x.npz")
    assert "does not exist" in one_line_error(make(20).save, tmp_path / "no" / "x.npz")
    assert not list(tmp_path.iterdir())


def _npz(path: Path, **arrays: Any) -> Path:
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def _good_members() -> dict[str, Any]:
    return dict(
        format=np.array("dynid-dataset"),
        format_version=np.array(1),
        meta=np.array("{}"),
        joints=np.array(JOINTS),
        t=np.arange(5.0),
        q=np.zeros((5, 7)),
    )


CORRUPT_CASES = {
    "text file": (lambda p: p.write_text("t,q\n0,1\n"), "not a zip archive"),
    "truncated zip": (lambda p: p.write_bytes(b"PK\x03\x04" + b"\x00" * 40), "corrupt"),
    "foreign zip": (lambda p: zipfile.ZipFile(p, "w").writestr("readme.txt", "hello"), "not a dynid dataset"),
    "foreign npz": (lambda p: _npz(p, x=np.zeros(3)), "no 'dynid-dataset' format marker"),
    "newer version": (
        lambda p: _npz(p, **{**_good_members(), "format_version": np.array(99)}),
        "version 99 is not supported",
    ),
    "pickled member": (
        lambda p: _npz(p, **{**_good_members(), "meta": np.array([{}], dtype=object)}),
        "not a dynid dataset",
    ),
    "bad q shape": (lambda p: _npz(p, **{**_good_members(), "q": np.zeros((4, 7))}), "q must have shape (5, 7)"),
    "missing t": (lambda p: _npz(p, **{k: v for k, v in _good_members().items() if k != "t"}), "member 't' is missing"),
    "bad meta": (lambda p: _npz(p, **{**_good_members(), "meta": np.array("{")}), "not JSON"),
    "unknown member": (lambda p: _npz(p, **_good_members(), surprise=np.zeros(5)), "unknown member 'surprise'"),
    "text channel": (
        lambda p: _npz(p, **_good_members(), **{"pwm/m0": np.array(["a"] * 5)}),
        "'pwm/m0' is not numeric",
    ),
}


@pytest.mark.parametrize("case", CORRUPT_CASES, ids=list(CORRUPT_CASES))
def test_load_refuses_corrupt_or_foreign_files(tmp_path: Path, case: str) -> None:
    build, words = CORRUPT_CASES[case]
    path = tmp_path / "d.npz"
    build(path)
    message = one_line_error(Dataset.load, path)
    assert words in message and str(path) in message


def test_load_missing_file(tmp_path: Path) -> None:
    assert "not found" in one_line_error(Dataset.load, tmp_path / "none.npz")


# ----------------------------------------------------------------------------------------------------------
# load_data


def test_load_data_reads_a_dataset_file_and_checks_it_against_the_config(tmp_path: Path) -> None:
    make(MIN_SAMPLES).save(tmp_path / "d.npz")  # load_data wants a run a command can use
    assert same(load_data(tmp_path / "d.npz", CFG), make(MIN_SAMPLES))
    (tmp_path / "d.npz").rename(tmp_path / "d.bin")  # told by content, not only by extension
    assert load_data(tmp_path / "d.bin", CFG).n_samples == MIN_SAMPLES


def test_load_data_names_joint_differences(tmp_path: Path) -> None:
    other = (
        "r_shoulder_pitch",
        "r_shoulder_roll",
        "r_shoulder_yaw",
        "r_elbow",
        "r_wrist_prosup",
        "r_wrist_pitch",
        "r_knee",
    )
    make(20, joints=other, pwm={}, ft={}).save(tmp_path / "a.npz")
    message = one_line_error(load_data, tmp_path / "a.npz", CFG)
    assert "missing r_wrist_yaw" in message and "not in the configuration: r_knee" in message
    make(20, joints=tuple(reversed(JOINTS))).save(tmp_path / "b.npz")
    assert "another order" in one_line_error(load_data, tmp_path / "b.npz", CFG)


def test_load_data_checks_channels_and_units_of_a_dataset_file(tmp_path: Path) -> None:
    make(20, pwm={"m7": np.zeros(20)}).save(tmp_path / "a.npz")
    assert "unknown motor 'm7' in column pwm.m7" in one_line_error(load_data, tmp_path / "a.npz", CFG)
    make(MIN_SAMPLES, ft={}).save(tmp_path / "b.npz")
    assert "ft.r_arm_ft.fx is missing" in one_line_error(load_data, tmp_path / "b.npz", CFG)
    assert load_data(tmp_path / "b.npz", CFG, require_all=False).ft == {}
    make(20, pwm={m: np.full(20, 500.0) for m in CFG.motor_names}).save(tmp_path / "c.npz")
    assert "not board counts" in one_line_error(load_data, tmp_path / "c.npz", CFG)
    make(20, q=np.full((20, 7), 45.0)).save(tmp_path / "d.npz")
    limits = {j: (-1.0, 1.0) for j in JOINTS}
    assert "looks like degrees" in one_line_error(load_data, tmp_path / "d.npz", CFG, joint_limits=limits)
    make(20, q=np.full((20, 7), 2.69)).save(tmp_path / "e.npz")  # radians, within a turn: no hint of degrees
    message = one_line_error(load_data, tmp_path / "e.npz", CFG, joint_limits=limits)
    assert "not a posture this joint reaches" in message and "degrees" not in message


def test_load_data_csv(tmp_path: Path) -> None:
    write_csv(make(MIN_SAMPLES), tmp_path / "d.csv")
    ds = load_data(tmp_path / "d.csv", CFG)
    assert ds.n_samples == MIN_SAMPLES and ds.meta["source_format"] == "csv"


CANDUMP = "(1700000000.000000) can0 123#DEADBEEF\n(1700000000.001000) can0 35D#0102\n"


def test_load_data_candump_is_told_by_content_and_decoded(tmp_path: Path) -> None:
    # Told from its first line whatever the name; these frames are no board of the arm (the full import is
    # tested in test_can_e2e.py).
    (tmp_path / "run.log").write_text(CANDUMP)
    (tmp_path / "run.txt").write_text(CANDUMP)
    for name in ("run.log", "run.txt"):
        message = one_line_error(load_data, tmp_path / name, CFG)
        assert "no frame STRAIN_TORQUE_13 (0x3DB on can0), which completes every sample" in message


def test_load_data_refuses_unknown_and_missing_files(tmp_path: Path) -> None:
    (tmp_path / "data.json").write_text(json.dumps({"t": [0, 1]}))
    assert "unknown data format" in one_line_error(load_data, tmp_path / "data.json", CFG)
    assert "data file not found" in one_line_error(load_data, tmp_path / "gone.csv", CFG)
    assert "not a file" in one_line_error(load_data, tmp_path, CFG)
