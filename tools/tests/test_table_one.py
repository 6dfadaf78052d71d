"""Every row of the paper's Table I, by configuration: a known payload's torques on the right-hand side, the
scale check, supply tracking on PWM only, noise per channel, headerless logs described by `columns:` and the
--from/--to windows (docs/formats.md)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError, DataError, InputError
from dynid.identify.supply import tracked
from dynid.io.dataset import Dataset
from dynid.io.load import MIN_WINDOW_SAMPLES, apply_window, load_data
from dynid.pipeline import check_scale
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels
from dynid.robot.regressors.stack import Signals, build_stacked, row_channels


def icub_variant(tmp_path: Path, name: str, actuation: str, extra: str = "") -> Path:
    """The bundled iCub arm without its F/T sensor and CAN map, with another actuation."""
    text = open(load_config().source).read().split("\nft_sensors:")[0]
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.replace("name: icub_right_arm", f"name: {name}") + actuation + extra)
    return path


def torque_config(tmp_path: Path, extra: str = "") -> Path:
    joints = ", ".join(load_config().joints)
    return icub_variant(tmp_path, "icub_torque", f"\nactuation:\n  - {{name: arm, input: torque, joints: [{joints}]}}\n",
                        extra)


def current_config(tmp_path: Path, known: bool = False) -> Path:
    joints = load_config().joints
    motors = "".join(f"  c{i}: {{nominal_gain: 10.0{', known_gain: 9.0' if known and i == 0 else ''}}}\n"
                     for i in range(len(joints)))
    actuation = (f"\nmotors:\n{motors}actuation:\n  - {{name: arm, input: current, joints: [{', '.join(joints)}], "
                 f"motors: [{', '.join(f'c{i}' for i in range(len(joints)))}]}}\n")
    return icub_variant(tmp_path, "icub_current", actuation)


def states(model: RobotModel, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return tuple(rng.uniform(-1, 1, (n, model.n_joints)) for _ in range(3))  # type: ignore[return-value]


def test_a_payloads_torques_move_to_b(tmp_path: Path) -> None:
    """With a 2 kg payload 5 cm off the last link's origin, A·Φ = b holds where τ comes from RNEA on the arm with
    the payload added to its last body: the payload enters b, not A."""
    model = RobotModel(load_config(torque_config(tmp_path)))
    q, dq, ddq = states(model, 12, seed=3)
    payload = model.payload_parameters(2.0, [0.05, 0.0, 0.02])
    loaded = model.with_inertial_parameters(model.cad_inertial_parameters + payload)
    data = loaded.createData()
    Q, V, A = model.pinocchio_configuration(q), model.pinocchio_velocity(dq), model.pinocchio_velocity(ddq)
    tau = np.array([pin.rnea(loaded, data, Q[k], V[k], A[k])[model.v_index] for k in range(len(q))])
    sig = Signals(q, dq, ddq, {}, {j: tau[:, i] for i, j in enumerate(model.config.joints)}, {}, payload)
    system = build_stacked(model, sig)
    phi = np.zeros(len(model.layout))
    phi[model.layout.span("inertial")] = model.cad_inertial_parameters
    assert np.abs(system.A @ phi - system.b).max() <= 1e-9
    assert payload[-10] == 2.0 and np.count_nonzero(payload[:-10]) == 0  # in the last body's slot only
    unloaded = build_stacked(model, Signals(q, dq, ddq, {}, sig.tau, {}))
    assert np.abs(unloaded.A @ phi - unloaded.b).max() > 1e-3  # the payload matters


def test_a_payload_in_another_unit_is_refused(tmp_path: Path) -> None:
    """Grams for kg or millimetres for metres would scale every gain of the fit: refused, naming the unit."""
    model = RobotModel(load_config(torque_config(tmp_path)))
    own = float(np.sum(model.cad_inertial_parameters[0::10]))
    model.payload_parameters(9.9 * own)  # heavy, but a load
    with pytest.raises(ConfigError, match="--payload takes kg"):
        model.payload_parameters(2000.0 * own)
    with pytest.raises(ConfigError, match="--payload takes metres"):
        model.payload_parameters(2.0, [0.0, 0.0, 50.0])


def test_unknown_gains_without_ft_or_payload_cannot_be_scaled(tmp_path: Path) -> None:
    model = RobotModel(load_config(current_config(tmp_path)))
    ds = Dataset(t=np.arange(3.0), joints=model.config.joints, q=np.zeros((3, model.n_joints)))
    with pytest.raises(InputError, match="the scale cannot be identified.*no F/T sensor.*--payload"):
        check_scale(model, [ds])
    ds.meta["payload"] = {"mass": 1.0, "com": None}
    check_scale(model, [ds])  # a payload run fixes it
    check_scale(RobotModel(load_config(current_config(tmp_path, known=True))), [Dataset(
        t=np.arange(3.0), joints=model.config.joints, q=np.zeros((3, model.n_joints)))])  # so does one known gain
    check_scale(RobotModel(load_config()), [])  # and the iCub's F/T sensor


def test_supply_tracking_is_for_pwm_only(tmp_path: Path) -> None:
    icub = RobotModel(load_config())
    assert [o.name for o in output_channels(icub) if tracked(o)] == [f"pwm.{m}" for m in icub.config.motor_names]
    current = RobotModel(load_config(current_config(tmp_path)))
    assert not any(tracked(o) for o in output_channels(current))


def test_noise_per_channel(tmp_path: Path) -> None:
    path = current_config(tmp_path)
    text = path.read_text()
    motors = load_config(path).motor_names
    per = ", ".join(f"{m}: {0.01 * (i + 1)}" for i, m in enumerate(motors))
    path.write_text(text.replace("noise:\n", f"noise:\n  current: {{{per}}}\n", 1) if "noise:\n" in text
                    else text + f"noise:\n  current: {{{per}}}\n")
    model = RobotModel(load_config(path))
    outs = {o.name: o.sigma for o in output_channels(model)}
    assert outs["current.c0"] == pytest.approx(0.01) and outs[f"current.{motors[-1]}"] == pytest.approx(0.01 * len(motors))
    rows = {r.name: r.sigma for r in row_channels(model)}
    assert rows[f"joint.{model.config.joints[2]}"] == pytest.approx(0.03 * 10.0)  # noise × nominal gain
    path.write_text(path.read_text().replace(f", {motors[-1]}: {0.01 * len(motors)}", ""))
    with pytest.raises(ConfigError, match=f"noise.current.{motors[-1]}' is missing"):
        load_config(path)


def headerless_setup(tmp_path: Path) -> tuple[Path, RobotModel]:
    joints = load_config().joints
    columns = "columns:\n  - t ms\n" + "".join(f"  - q.{j} deg\n" for j in joints) + "".join(
        f"  - tau.{j} Nm\n" for j in joints) + "  - note.x V\n"
    return torque_config(tmp_path, columns), RobotModel(load_config(torque_config(tmp_path, columns)))


def test_a_headerless_log_read_through_columns(tmp_path: Path) -> None:
    path, model = headerless_setup(tmp_path)
    n, j = 300, model.n_joints
    q_deg = np.linspace(0, 10, n)[:, None] * np.ones(j)
    table = np.column_stack([np.arange(n) * 10.0, q_deg, np.ones((n, j)), np.full(n, 5.0)])
    log = tmp_path / "arm.csv"
    np.savetxt(log, table, delimiter=",", fmt="%.6f")
    ds = load_data(log, model.config, joint_limits=model.joint_limits)
    assert ds.t[1] == pytest.approx(0.01) and ds.q[-1, 0] == pytest.approx(math.radians(10))
    assert ds.extra["note.x"][0] == 5.0 and ds.meta["source_format"] == "headerless csv"
    short = tmp_path / "short.csv"  # a file that stops before the list does keeps the columns it has
    np.savetxt(short, table[:, : 1 + 2 * j], delimiter=",", fmt="%.6f")
    assert "note.x" not in load_data(short, model.config).extra
    cut = tmp_path / "cut.csv"
    np.savetxt(cut, table[:, : 1 + j], delimiter=",", fmt="%.6f")
    with pytest.raises(DataError, match=r"column tau\..* is missing.*\(the file has 8 of the 16 columns described\)"):
        load_data(cut, model.config)
    lost = tmp_path / "lost.csv"  # one q column lost: every later column would be read one to the left
    np.savetxt(lost, np.delete(table, 3, axis=1)[:, : 2 * j], delimiter=",", fmt="%.6f")
    with pytest.raises(DataError, match=r"14 fields, which ends inside .*'s tau\.\* columns \(6 of 7\): a column is "
                                        r"missing or extra.*end at field 1, 8, 15 and 16\)"):
        load_data(lost, model.config)
    bad = tmp_path / "bad.csv"
    bad.write_text(log.read_text().replace("5.000000\n", "x\n", 1))
    with pytest.raises(DataError, match="line 1, column 16: 'x' is not a number"):
        load_data(bad, model.config)


def test_columns_need_units_the_kind_knows(tmp_path: Path) -> None:
    path = torque_config(tmp_path, "columns:\n  - t s\n  - q.r_elbow A\n")
    with pytest.raises(ConfigError, match=r"columns\[1\]'.*rad, deg"):
        load_config(path)


def test_windows_in_the_datas_own_seconds() -> None:
    n = 1000
    ds = Dataset(t=100.0 + np.arange(n) * 0.01, joints=("a",), q=np.zeros((n, 1)))
    part = apply_window(ds, 102.0, 105.0)
    assert part.t[0] == pytest.approx(102.0) and part.t[-1] == pytest.approx(105.0) and part.n_samples == 301
    assert apply_window(ds, None, None) is ds
    with pytest.raises(DataError, match=f"holds only 51 samples \\(at least {MIN_WINDOW_SAMPLES} needed\\); the data "
                                        "run from 100 s to 109.99 s"):
        apply_window(ds, 102.0, 102.5)
    with pytest.raises(DataError, match="holds no sample"):
        apply_window(ds, 200.0, None)
    with pytest.raises(DataError, match="must come after"):
        apply_window(ds, 105.0, 104.0)
    # A window that reaches past the run is cut where the run ends, and says so (it was silent)
    from dynid.errors import DataNote

    with pytest.warns(DataNote, match=r"the window from 105 s to 150 s reaches past the data, which run from 100 s to "
                                      r"109.99 s: it takes 500 samples, 105 s to 109.99 s"):
        assert apply_window(ds, 105.0, 150.0).n_samples == 500
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        apply_window(ds, 100.0, 109.99)  # the whole run, to the last stamp: nothing to say


def test_the_papers_rows_only_on_the_papers_arm() -> None:
    from dynid.paper import PAPER
    from dynid.report import html as H

    stats = {"mean": 1.0, "std": 0.5}
    v = {"table_ii": {s: {"force": stats, "torque": stats} for s in ("identified", "cad")}}
    variant = {"threshold": 3.0, "fpr": 0.01, "tpr": 0.7, "auc": 0.9}
    det = {"variants": {"calibrated": variant}}
    assert "paper" in H.table_ii(v, dict(PAPER)) and "paper" not in H.table_ii(v, None)
    assert "real iCub arm" in H.detection(det, det, dict(PAPER), 0.99)
    assert "real iCub arm" not in H.detection(det, det, None, 0.99)


def test_a_headerless_log_may_stop_after_one_sensor_of_two() -> None:
    """Groups are a kind's consecutive columns, an F/T sensor's six its own: a log that stops after the first of two
    sensors stops at a group's end (a review found ft.left.* and ft.right.* taken as one group, and refused)."""
    from types import SimpleNamespace

    from dynid.io.headerless import check_group_end

    names = ["t"] + [f"ft.{s}.{c}" for s in ("left", "right") for c in ("fx", "fy", "fz", "tx", "ty", "tz")]
    config = SimpleNamespace(columns=[SimpleNamespace(name=n) for n in names + ["q.a", "q.b"]], name="two")
    for width in (1, 7, 13, 15):
        check_group_end(Path("log.csv"), config, width)  # type: ignore[arg-type]
    with pytest.raises(DataError, match=r"inside the configuration two's ft\.right\.\* columns \(3 of 6\)"):
        check_group_end(Path("log.csv"), config, 10)  # type: ignore[arg-type]
