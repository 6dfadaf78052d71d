"""Robot configuration: the bundled iCub arm, and every wrong or incomplete field refused by name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError
from dynid.robot.model import RobotModel

ICUB = load_config("icub_right_arm")


def test_bundled_icub_right_arm() -> None:
    c = ICUB
    assert c.joints == ("r_shoulder_pitch", "r_shoulder_roll", "r_shoulder_yaw", "r_elbow",
                        "r_wrist_prosup", "r_wrist_pitch", "r_wrist_yaw")
    assert [s.joint for s in c.ft_sensors] == ["r_arm_ft_sensor"]
    shoulder, elbow = c.actuation
    r = 65 / 40
    assert np.allclose(shoulder.coupling.T, [[1, -r, -r], [0, r, r], [0, 0, r]])  # Tᵀ of docs/design.md §3
    assert shoulder.coupled and not elbow.coupled
    assert c.motors_with_input("pwm") == ("m0", "m1", "m2", "m3")
    assert c.urdf.name == "model.urdf" and "iCubGenova04" in str(c.urdf)


def test_icub_model_splits_the_upper_arm() -> None:
    model = RobotModel(ICUB)
    names = [b.name for b in model.bodies]
    assert names.index("r_shoulder_3") + 1 == names.index("r_upper_arm")
    assert model.layout.names[:2] == ("r_shoulder_1.m", "r_shoulder_1.mcx")
    for name in ("r_elbow_1.m", "m0.phi_m", "ft.r_arm_ft.offset.fx", "r_elbow.fc_pos", "m2.fv_neg"):
        assert name in model.layout.names


def write_variant(tmp_path: Path, edit) -> Path:
    data = yaml.safe_load(Path(ICUB.source).read_text())
    edit(data)
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _del(key):
    return lambda d: d.pop(key)


def _set(path, value):
    def edit(d):
        node = d
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
    return edit


BAD = [
    ("missing name", _del("name"), "'name' is missing"),
    ("missing joints", _del("joints"), "'joints' is missing"),
    ("missing urdf", _del("urdf"), "'urdf' is missing"),
    ("unknown icub model", _set(["urdf"], {"icub_models": "iCubNowhere"}), "iCubNowhere"),
    ("urdf file missing", _set(["urdf"], {"path": "nope.urdf"}), "missing file"),
    ("duplicate joint", _set(["joints"], ["r_elbow", "r_elbow"]), "lists a name twice"),
    ("actuated joint not in joints", _set(["actuation", 1, "joints"], ["r_elbw"]), "actuation[1].joints"),
    ("unknown motor", _set(["actuation", 1, "motors"], ["m9"]), "actuation[1].motors"),
    ("coupling shape", _set(["actuation", 0, "coupling"], [[1, 0], [0, 1]]), "actuation[0].coupling"),
    ("singular coupling", _set(["actuation", 0, "coupling"], [[1, 0, 0], [1, 0, 0], [0, 0, 1]]), "full column rank"),
    ("bad input kind", _set(["actuation", 1, "input"], "voltage"), "actuation[1].input"),
    ("negative gain", _set(["motors", "m3", "nominal_gain"], -1), "motors.m3.nominal_gain"),
    ("gravity", _set(["gravity"], [0, 0]), "'gravity'"),
    ("gravity in cm/s²", _set(["gravity"], [0, 0, -981]), "981 m/s² long"),
    ("noise", _set(["ft_sensors", 0, "noise", "force"], "low"), "ft_sensors[0].noise.force"),
    ("can bus", _set(["can", "strain", 0, "bus"], "can7"), "can.strain[0].bus"),
    ("can address", _set(["can", "motor_control", 0, "address"], 16), "can.motor_control[0].address"),
    ("can full scale", _set(["can", "strain", 0, "full_scale"], [1, 2, 3]), "can.strain[0].full_scale"),
    ("skin side", _set(["can", "skin", 0, "side"], "left"), "can.skin[0].side"),
    # a `can` section cut before its strain boards (test_reader_properties_files found it: an IndexError)
    ("can without strain", lambda d: d["can"].pop("strain"), "'can.strain' must list at least one strain board"),
    ("fit consistent", _set(["fit"], {"consistent": "maybe"}), "'fit.consistent' must be one of off, on"),
    ("misspelt coupling", lambda d: d["actuation"][0].__setitem__("couplng", d["actuation"][0].pop("coupling")),
     "'actuation[0].couplng' is not a known setting (did you mean 'coupling'?)"),
    ("misspelt top-level key", lambda d: d.__setitem__("nosie", d.pop("noise")), "did you mean 'noise'"),
    ("misspelt known gain", _set(["motors", "m3", "known_gian"], 3.0), "motors.m3.known_gian"),
    ("zero known gain", _set(["motors", "m3", "known_gain"], 0.0), "motors.m3.known_gain"),
    ("derivative polyorder", _set(["derivatives"], {"polyorder": 2.5}), "derivatives.polyorder"),
    ("derivative option", _set(["derivatives"], {"window": 0.1}), "derivatives.window"),
    ("derivative method", _set(["derivatives"], {"method": "savgoll"}), "derivatives.method' must be one of savgol, "
     "adaptive, got 'savgoll' (did you mean 'savgol'?)"),
    ("ft_steps not a list", _set(["ft_steps"], "24.4,61.2"), "'ft_steps' must be a list of change points"),
    ("ft_steps not numbers", _set(["ft_steps"], [24.4, "61.2 s"]), "'ft_steps' must be a list of change points"),
    ("ft_steps not finite", _set(["ft_steps"], [24.4, float("inf")]), "'ft_steps' must be a list of change points"),
    ("ft_steps decreasing", _set(["ft_steps"], [61.2, 24.4]), "'ft_steps' must increase"),
]


@pytest.mark.parametrize("label,edit,words", BAD, ids=[b[0] for b in BAD])
def test_bad_configuration_names_the_field(tmp_path: Path, label, edit, words) -> None:
    path = write_variant(tmp_path, edit)
    with pytest.raises(ConfigError) as e:
        load_config(path)
    assert words in str(e.value)
    assert "\n" not in str(e.value)


MODEL_BAD = [
    ("joint not in urdf", lambda d: (d.pop("can"), d["joints"].__setitem__(6, "r_wrist_yw")),
     "'r_wrist_yw', which is not a joint"),
    ("sensor joint not fixed", _set(["ft_sensors", 0, "joint"], "r_elbow"), "not a fixed joint"),
    # a base below the sensor: the tree is re-rooted at r_hand, which would swap the sensor's sides (robot/reroot.py)
    ("sensor between base link and root", _set(["base_link"], "r_hand"), "between the base link 'r_hand' and the URDF's root"),
    ("base link unknown", _set(["base_link"], "torso_99"), "'torso_99', not a link"),
    ("payload frame not in the urdf", _set(["payload_frame"], "tool_flange"), "'payload_frame' names 'tool_flange'"),
    ("payload frame on the base", _set(["payload_frame"], "root_link"), "fixed to the base"),
    ("sensor named unlike the URDF", lambda d: (d.pop("can"), d["ft_sensors"][0].__setitem__("name", "r_arm_ftt")),
     "the URDF names the sensor at r_arm_ft_sensor 'r_arm_ft' (rename the sensor to it, or give the joint of yours)"),
    # another sensor's joint (a walkthrough's leg config): the URDF says where the named sensor is
    ("sensor at another sensor's joint",
     lambda d: (d.pop("can"), d["ft_sensors"][0].__setitem__("joint", "l_arm_ft_sensor")),
     "the URDF names the sensor at l_arm_ft_sensor 'l_arm_ft'; the URDF puts r_arm_ft at joint r_arm_ft_sensor: is that "
     "its joint?"),
]


def test_urdf_sensor_convention_is_checked(tmp_path: Path) -> None:
    urdf = ICUB.urdf.read_text().replace(
        "<measure_direction>child_to_parent</measure_direction>", "<measure_direction>parent_to_child</measure_direction>"
    )
    (tmp_path / "model.urdf").write_text(urdf)
    path = write_variant(tmp_path, _set(["urdf"], {"path": "model.urdf"}))
    with pytest.raises(ConfigError, match="measure_direction 'parent_to_child'"):
        RobotModel(load_config(path))


@pytest.mark.parametrize("label,edit,words", MODEL_BAD, ids=[b[0] for b in MODEL_BAD])
def test_configuration_inconsistent_with_urdf(tmp_path: Path, label, edit, words) -> None:
    with pytest.raises(ConfigError) as e:
        RobotModel(load_config(write_variant(tmp_path, edit)))
    assert words in str(e.value)


def test_not_yaml(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text("name: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(path)


def test_unknown_bundled_name() -> None:
    with pytest.raises(ConfigError, match="unknown robot configuration 'icub_left_leg'"):
        load_config("icub_left_leg")


def test_ft_steps_are_read_in_seconds(tmp_path: Path) -> None:
    assert load_config("icub_right_arm").ft_steps == ()
    assert load_config(write_variant(tmp_path, _set(["ft_steps"], [24.4, 61]))).ft_steps == (24.4, 61.0)


def test_the_configurations_derivative_methods_are_the_estimators() -> None:
    from dynid.config.robot_config import DERIVATIVE_METHODS
    from dynid.io.derivatives import METHODS
    assert set(DERIVATIVE_METHODS) == set(METHODS)


def test_derivative_options_keep_their_types(tmp_path: Path) -> None:
    options = {"method": "adaptive", "d": 1e-4, "max_window": 20, "causal": False}
    assert load_config(write_variant(tmp_path, _set(["derivatives"], options))).derivatives == options
