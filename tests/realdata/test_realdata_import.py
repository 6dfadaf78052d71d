"""Real robot runs (shared/realdata) convert to the project CSV and import through dynid.io.csv_format."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import RobotConfig, load_config
from dynid.io.csv_format import read_csv

from . import convert

HERE = Path(__file__).resolve().parent
REALDATA = convert.REALDATA
needs_data = pytest.mark.skipif(
    not REALDATA.is_dir(), reason=f"real robot data not found at {REALDATA} (clone shared/ beside the repository)"
)


def urdf_limits(config: RobotConfig) -> dict[str, tuple[float, float]]:
    """Joint limits straight from the URDF (top-level <joint> elements only: <transmission> reuses the tag)."""
    root = ET.parse(config.urdf).getroot()
    limits = {}
    for joint in root.findall("joint"):
        limit = joint.find("limit")
        if joint.get("name") in config.joints and limit is not None:
            limits[joint.get("name")] = (float(limit.get("lower")), float(limit.get("upper")))
    return limits


def check_chain(config: RobotConfig) -> None:
    """The configured joints, base link and F/T joints exist in the URDF, with the base above every joint."""
    root = ET.parse(config.urdf).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}
    parent_of = {j.find("child").get("link"): j for j in joints.values()}
    for name in config.joints:
        assert joints[name].get("type") in ("revolute", "continuous", "prismatic"), name
        link, chain = joints[name].find("parent").get("link"), []
        while link != config.base_link:
            assert link in parent_of, f"{config.base_link} is not above {name}"
            chain.append(parent_of[link].get("name"))
            link = parent_of[link].find("parent").get("link")
        assert not set(chain) - set(config.joints) - {j for j, e in joints.items() if e.get("type") == "fixed"}
    for sensor in config.ft_sensors:
        assert joints[sensor.joint].get("type") == "fixed"


@needs_data
def test_configs_load_and_match_their_urdf() -> None:
    panda = load_config("panda")
    assert panda.joints == convert.PANDA_JOINTS and panda.base_link == "panda_link0" and not panda.ft_sensors
    assert [(g.input, g.joints) for g in panda.actuation] == [("torque", convert.PANDA_JOINTS)]
    tiago = load_config("tiago_wrist", convert.TIAGO_URDF)
    assert tiago.joints == convert.TIAGO_JOINTS and not tiago.actuation
    assert [(s.name, s.joint, s.force_noise, s.torque_noise) for s in tiago.ft_sensors] == [
        ("wrist_ft", "wrist_ft_joint", 0.1, 0.01)
    ]
    assert tiago.urdf.resolve() == (REALDATA / "tiago_wrist_ft" / "urdf" / "tiago_48_hey5.urdf").resolve()
    for config in (panda, tiago):
        check_chain(config)


@needs_data
def test_panda_run_imports(tmp_path: Path) -> None:
    conversion = convert.convert_panda()
    # The Panda stamps are jittered (steps 0.70..8.81 ms, 4 gaps of ~8.5 ms) but strictly increasing: nothing
    # is dropped, so all 20544 samples of the log arrive.
    assert conversion.rows_read == 20544 and conversion.dropped.size == 0
    assert "nothing dropped" in conversion.notes[0]
    path = tmp_path / "panda.csv"
    conversion.write(path)
    config = load_config("panda")
    ds = read_csv(path, config, joint_limits=urdf_limits(config))
    assert ds.n_samples == 20544 and ds.joints == convert.PANDA_JOINTS
    assert np.all(np.diff(ds.t) > 0) and ds.t[0] == 0.0 and ds.t[-1] == pytest.approx(20.9991)
    assert ds.dq is not None and ds.ddq is None and list(ds.tau) == list(convert.PANDA_JOINTS)
    assert not ds.pwm and not ds.ft and not ds.extra and ds.contact is None
    assert ds.q[0, 0] == -0.9584 and ds.tau["panda_joint1"][0] == -0.518286  # the logged text, exactly
    assert np.abs(ds.tau["panda_joint2"]).max() == pytest.approx(38.33, abs=0.01)  # Nm, gravity on the shoulder


@needs_data
def test_tiago_run_imports(tmp_path: Path) -> None:
    conversion = convert.convert_tiago()
    assert conversion.rows_read == 8022 and conversion.dropped.size == 0  # 8022 stamps, strictly increasing
    path = tmp_path / "tiago.csv"
    conversion.write(path)
    config = load_config("tiago_wrist", convert.TIAGO_URDF)
    ds = read_csv(path, config, joint_limits=urdf_limits(config))
    assert ds.n_samples == 8022 and ds.joints == convert.TIAGO_JOINTS
    assert np.all(np.diff(ds.t) > 0) and ds.t[-1] == pytest.approx(80.211, abs=1e-3)
    assert ds.dq is None and ds.ddq is None and not ds.tau and not ds.pwm  # PAL's lagging velocity is not dq
    assert list(ds.ft) == ["wrist_ft"] and ds.ft["wrist_ft"].shape == (8022, 6)
    assert list(ds.extra) == [f"velocity_filtered.{j}" for j in convert.TIAGO_JOINTS] + [
        f"effort.{j}" for j in convert.TIAGO_JOINTS  # raw units, not tau
    ]
    fz = ds.ft["wrist_ft"][:, 2]
    assert fz.min() == pytest.approx(-75.5) and fz.max() == pytest.approx(-60.4)  # the README's ranges: not tared
    assert ds.ft["wrist_ft"][0].tolist() == pytest.approx([3.8, -2.6, -69.0, 0.73, 0.0, 0.64])


def test_non_increasing_stamps_are_dropped_and_reported(tmp_path: Path) -> None:
    t = np.array([0.0, 0.001, 0.001, 0.002, 0.0015, 0.003])
    log = tmp_path / "rbt_log"
    log.mkdir()
    np.savetxt(log / "exciting_traj_time.txt", t)
    for name in ("positions", "velocity", "torques"):
        np.savetxt(log / f"exciting_traj_{name}.txt", np.arange(7.0 * t.size))
    conversion = convert.convert_panda(tmp_path)
    assert conversion.dropped.tolist() == [2, 4]
    assert conversion.dataset.t.tolist() == [0.0, 0.001, 0.002, 0.003]
    assert conversion.dataset.q[:, 0].tolist() == [0.0, 7.0, 21.0, 35.0]  # rows stay aligned with their stamps
    assert (
        conversion.notes[0].startswith("dropped 2 samples")
        and "raw samples (0-based) 2 (t=0.001), 4 (t=0.0015)" in conversion.notes[0]
    )


@needs_data
@pytest.mark.parametrize("robot", ["panda", "tiago"])
def test_command_line(tmp_path: Path, robot: str) -> None:
    out = tmp_path / f"{robot}.csv"
    run = subprocess.run(
        [sys.executable, str(HERE / "convert.py"), robot, str(out)], capture_output=True, text=True, check=False
    )
    assert run.returncode == 0, run.stderr
    assert "0 dropped" in run.stdout and "nothing dropped" in run.stdout and out.is_file()


@needs_data
@pytest.mark.parametrize("robot", ["panda", "tiago_wrist"])
def test_the_loggers_folder_imports_as_its_converted_csv(tmp_path: Path, robot: str) -> None:
    """`dynid import --data FOLDER` reads the lab's own files through the configuration's `files:` field alone, and
    gives the samples this folder's independent converter gives: every value bit for bit, t to the converter's
    nanosecond rounding (TIAGo; the Panda's t is not rounded)."""
    from dynid.io.dataset import Dataset

    from . import cli

    folder, conversion, urdf = ((REALDATA / "panda_gaz2019" / "rbt_log", convert.convert_panda(), ())
                                if robot == "panda" else
                                (REALDATA / "tiago_wrist_ft" / "dynamic", convert.convert_tiago(),
                                 ("--urdf", str(convert.TIAGO_URDF))))
    out = tmp_path / "run.npz"
    result = cli.dynid("import", "--robot", robot, *urdf, "--data", str(folder), "--out", str(out))
    ref, ds = conversion.dataset, Dataset.load(out)
    assert result["samples"] == ref.n_samples == ds.n_samples
    assert ds.meta["source_format"] == "file set"
    assert np.max(np.abs(ds.t - ref.t)) <= (0.0 if robot == "panda" else 0.51e-9)  # half a ns, and the sum's rounding
    for kind in ("q", "dq"):
        a, b = getattr(ds, kind), getattr(ref, kind)
        assert (a is None and b is None) or np.array_equal(a, b), kind
    for family in ("tau", "ft", "extra"):
        a, b = getattr(ds, family), getattr(ref, family)
        assert sorted(a) == sorted(b) and all(np.array_equal(a[k], b[k]) for k in b), family


# Each real run with F/T, as a user gives it: (configuration, --urdf, the folder).
FT_RUNS = {
    "icub_leg": ("icub_right_leg_standing", REALDATA / "icub_leg_insitu" / "iCubGenova02.urdf",
                 REALDATA / "icub_leg_insitu" / "dumperLeftLegNoIMU"),
    "tiago": ("tiago_wrist", convert.TIAGO_URDF, REALDATA / "tiago_wrist_ft" / "dynamic"),
}
UNITS = {  # what is done to a sensor's columns fx fy fz tx ty tz, words of the refusal
    "torques in N·mm": (lambda w: w * [1, 1, 1, 1e3, 1e3, 1e3], "torques in N·mm"),
    "forces in mN": (lambda w: w * [1e3, 1e3, 1e3, 1, 1, 1], "forces in mN"),
    "swapped": (lambda w: w[:, [3, 4, 5, 0, 1, 2]], "swapped"),
    "torques ÷1000": (lambda w: w * [1, 1, 1, 1e-3, 1e-3, 1e-3], "torques in N·m declared N·mm"),
}


@needs_data
@pytest.mark.parametrize("run", list(FT_RUNS))
def test_real_wrenches_pass_the_unit_check_and_in_another_unit_do_not(run: str) -> None:
    """dynid.io.wrenches on the real sensors, untared (the TIAGo's Fz −69 N at rest): every run loads; each sensor's
    columns in another unit are refused, naming the sensor (docs/formats.md#dataset-file has the figures)."""
    from dynid.errors import DataError
    from dynid.io.load import check_plausible, load_data

    robot, urdf, folder = FT_RUNS[run]
    config = load_config(robot, urdf)
    data = load_data(folder, config)  # passes check_plausible, the wrenches' check with it
    for sensor in data.ft:
        for change, words in UNITS.values():
            bad = data.slice(0, data.n_samples)
            bad.ft = {**data.ft, sensor: change(data.ft[sensor])}
            with pytest.raises(DataError, match=f"ft.{sensor}'s .*{words}"):
                check_plausible(bad, config=config)


@needs_data
@pytest.mark.parametrize("unit, refused", [("rad", True), ("deg", True), ("mm", False)])
def test_a_prismatic_joints_columns_are_a_length(tmp_path: Path, unit: str, refused: bool) -> None:
    """TIAGo's torso lift is prismatic: its position column declared in an angle's unit was taken as metres (a
    walkthrough's own configuration); now refused naming the field, at the configuration's first use of the URDF."""
    from dynid.config.robot_config import BUNDLED_DIR
    from dynid.errors import ConfigError
    from dynid.robot.model import RobotModel

    mine = tmp_path / "tiago.yaml"
    text = (BUNDLED_DIR / "tiago_wrist.yaml").read_text()
    assert text.count("q.torso_lift_joint m,") == 1
    mine.write_text(text.replace("q.torso_lift_joint m,", f"q.torso_lift_joint {unit},"))
    config = load_config(str(mine), convert.TIAGO_URDF)
    if not refused:
        RobotModel(config)
        return
    with pytest.raises(ConfigError, match=rf"field 'files.tiago_position.csv\[1\]' gives q.torso_lift_joint in {unit}, "
                                          r"but torso_lift_joint is prismatic in .*: its positions are a length"):
        RobotModel(config)
