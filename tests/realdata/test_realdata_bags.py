"""Every given real run as a ROS 2 bag (tests/realdata/to_bag.py, MCAP and SQLite): the bag reads back as the run's
samples bit for bit, and `dynid fit` on the bag gives the model of `dynid fit` on the CSV (or the YARP folder), bit
for bit. Both fits run in this process, so that the same arithmetic runs on the same samples; the bundled
configurations' `ros2:` fields are the topics a ROS 2 user of each robot records. A UR10e log with the garbage rows
of a real controller log (t = −0.12 s, values near 1e150, a last row cut short) is refused, then fits with
`--bad-rows skip` to the clean log's model."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dynid.cli import main
from dynid.config.robot_config import load_config
from dynid.identify.model_file import load_model
from dynid.io.load import load_data

from . import convert, to_bag

pytestmark = pytest.mark.skipif(not convert.REALDATA.is_dir(), reason=f"no real data at {convert.REALDATA}")

UNLOADED, LOADED = (to_bag.UR10E / "identification" / f"ur-20_02_19_14harm50sec{s}.csv" for s in ("", "Load"))
UR = ("--robot", "ur10e", "--urdf", str(convert.UR10E_URDF))
PAIR = ("--payload", "0", "--payload", "2.805")  # the loaded run carries 2.805 kg (the folder's README)
LEG = ("--robot", "icub_right_leg_standing", "--urdf", str(to_bag.LEG_URDF))
LEG_WINDOW = ("--from", "23", "--to", "47")  # the swing test_realdata_icub_leg.py fits


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def fit(tmp_path: Path, name: str, *argv: str) -> dict[str, Any]:
    """`dynid fit ARGV` in this process: the model file's sections, as written."""
    out = tmp_path / f"{name}.json"
    code, _, err = run("fit", *argv, "--out", str(out))
    assert code == 0, err
    return load_model(str(out)).to_json() | {"phi": load_model(str(out)).phi.tolist()}


def without_timing(estimators: dict[str, Any]) -> dict[str, Any]:
    """The estimators' section less the wall-clock time of the consistent fit's solve (the leg's default fit is the
    consistent one: docs/consistency.md#default), which is a measurement, not the model."""
    out = dict(estimators)
    if isinstance(out.get("consistent"), dict) and isinstance(out["consistent"].get("detail"), dict):
        out["consistent"] = {**out["consistent"], "detail": {k: v for k, v in out["consistent"]["detail"].items()
                                                             if k != "solve_time_s"}}
    return out


def assert_same_fit(a: dict[str, Any], b: dict[str, Any]) -> None:
    """The same model bit for bit: parameters, every estimator, the base, the detectors, the residuals."""
    for key in ("phi", "estimators", "base", "detector", "outputs", "n_components"):
        if key == "estimators":
            assert without_timing(a[key]) == without_timing(b[key]), key
        else:
            assert a[key] == b[key], key
    assert [d["samples"] for d in a["data"]] == [d["samples"] for d in b["data"]]


def assert_same_samples(bag_path: Path, reference: Path, config: Any, *, extras_left_out: tuple[str, ...] = ()) -> None:
    bag, ref = load_data(bag_path, config), load_data(reference, config)
    bag_columns, ref_columns = dict(bag.columns()), dict(ref.columns())
    assert sorted(set(ref_columns) - set(bag_columns)) == sorted(extras_left_out)
    assert set(bag_columns) <= set(ref_columns)
    for name, values in bag_columns.items():
        assert values.dtype == ref_columns[name].dtype and np.array_equal(values, ref_columns[name]), name


def test_the_ur10e_pair_as_bags_fits_as_the_logs(tmp_path: Path) -> None:
    config = to_bag.ur10e_config()
    bags = [to_bag.ur10e_bag(UNLOADED, tmp_path / "unloaded", "mcap"), to_bag.ur10e_bag(LOADED, tmp_path / "loaded",
                                                                                          "sqlite3")]
    targets = tuple(f"{kind}.{x}" for kind, names in (("current_target", [m.name for m in config.motors]),
                                                       ("tau_target", config.joints)) for x in names)
    for bag, log in zip(bags, (UNLOADED, LOADED)):  # the log's desired currents and torques are no JointState field
        assert_same_samples(bag, log, config, extras_left_out=targets)
    from_logs = fit(tmp_path, "logs", *UR, "--data", str(UNLOADED), "--data", str(LOADED), *PAIR)
    from_bags = fit(tmp_path, "bags", *UR, "--data", str(bags[0]), "--data", str(bags[1]), *PAIR)
    assert_same_fit(from_bags, from_logs)


def test_every_ur10e_log_reads_back_from_its_bag(tmp_path: Path) -> None:
    config = to_bag.ur10e_config()
    for log in to_bag.ur10e_runs():
        bag = to_bag.ur10e_bag(log, tmp_path / log.stem)
        assert np.array_equal(load_data(bag, config).q, load_data(log, config).q), log.name


@pytest.mark.parametrize("robot", ["panda", "tiago"])
def test_the_panda_and_the_tiago_as_bags_fit_as_their_csv(tmp_path: Path, robot: str) -> None:
    csv = tmp_path / f"{robot}.csv"
    (convert.convert_panda if robot == "panda" else convert.convert_tiago)().write(csv)
    if robot == "panda":
        config, args = load_config("panda"), ("--robot", "panda")
        bag = to_bag.panda_bag(csv, tmp_path / "bag", "sqlite3")
    else:
        config = load_config("tiago_wrist", convert.TIAGO_URDF)
        args = ("--robot", "tiago_wrist", "--urdf", str(convert.TIAGO_URDF))
        bag = to_bag.tiago_bag(csv, tmp_path / "bag", "mcap")
    assert_same_samples(bag, csv, config)
    assert_same_fit(fit(tmp_path, "bag", *args, "--data", str(bag)), fit(tmp_path, "csv", *args, "--data", str(csv)))


def test_the_icub_leg_as_a_bag_of_its_ports_fits_as_the_yarp_folder(tmp_path: Path) -> None:
    bag = to_bag.icub_leg_bag(tmp_path / "leg", "sqlite3")
    config = load_config("icub_right_leg_standing", to_bag.LEG_URDF)
    assert_same_samples(bag, to_bag.DUMP, config)
    from_bag = fit(tmp_path, "bag", *LEG, "--data", str(bag), *LEG_WINDOW)
    assert_same_fit(from_bag, fit(tmp_path, "folder", *LEG, "--data", str(to_bag.DUMP), *LEG_WINDOW))
    assert from_bag["data"][0]["window"] == [23.0, 47.0]


def test_the_loaded_log_with_a_controllers_garbage_rows_is_refused_then_fits_with_skip(tmp_path: Path) -> None:
    """The loaded run as the controller wrote it: nine garbage rows first (t = −0.12 s, values near 1e150) and a last
    row cut short. Refused in one line by default; with --bad-rows skip, the model of the clean pair."""
    raw = LOADED.read_bytes().rstrip(b"\n")
    width = raw.split(b"\n", 1)[0].count(b",") + 1
    garbage = b"".join(b"-0.1200," + b",".join(b"%.4e" % (1.7e150 * (1 + k / 10)) for _ in range(width - 1)) + b"\n"
                       for k in range(9))
    last = raw.rsplit(b"\n", 1)[1].split(b",")
    cut = b",".join([b"%.4f" % (float(last[0]) + 0.01), *last[1:17]])[:-2]  # one more row, stopped mid-number
    dirty = tmp_path / "loaded_dirty.csv"
    dirty.write_bytes(garbage + raw + b"\n" + cut)
    code, _, err = run("fit", *UR, "--data", str(UNLOADED), "--data", str(dirty), *PAIR, "--out", str(tmp_path / "m"))
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "10 bad rows of" in err and "1 cut short, 9 with a value beyond ±1e+06" in err and "at line 1, line 2" in err
    model = tmp_path / "skipped.json"
    code, out, err = run("fit", *UR, "--data", str(UNLOADED), "--data", str(dirty), *PAIR, "--bad-rows", "skip",
                         "--out", str(model), "--json", str(tmp_path / "fit.json"))
    assert code == 0, err
    assert f"{dirty}: skipped 10 bad rows of" in out
    assert json.loads((tmp_path / "fit.json").read_text())["bad_rows"][str(dirty)]["count"] == 10
    skipped = load_model(str(model)).to_json()
    assert skipped["data"][1]["bad_rows"]["count"] == 10 and "bad_rows" not in skipped["data"][0]
    clean = fit(tmp_path, "clean", *UR, "--data", str(UNLOADED), "--data", str(LOADED), *PAIR)
    assert_same_fit(skipped | {"phi": load_model(str(model)).phi.tolist()}, clean)
