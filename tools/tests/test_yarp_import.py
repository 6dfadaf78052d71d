"""The yarpdatadumper importer (dynid.io.yarp, the configuration's `yarp:` field) on folders with known content.

Each port's signals are linear in time, so interpolation onto the common grid is exact and every value can be
checked; the ports tick at ~100 Hz with their own jitter, as the iCub's do.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.errors import ConfigError, DataError, DataNote
from dynid.io.load import load_data

ARM = ["r_shoulder_pitch", "r_shoulder_roll", "r_shoulder_yaw", "r_elbow", "r_wrist_prosup", "r_wrist_pitch", "r_wrist_yaw"]
UNIX0 = 1457614036.0

CONFIG = """\
name: yarp_arm
urdf: {icub_models: iCubGenova04}
base_link: chest
joints: [%s]
ft_sensors:
  - {name: r_arm_ft, joint: r_arm_ft_sensor}
yarp:
%s
"""
PORTS = """\
  ports:
    - {port: icub/right_arm/stateExt:o, joints: [%s, _, _]}
    - {port: icub/right_arm/analog:o, sensor: r_arm_ft}
""" % ", ".join(ARM)


def _config(tmp_path: Path, yarp: str = PORTS):
    path = tmp_path / "arm.yaml"
    path.write_text(CONFIG % (", ".join(ARM), yarp))
    return load_config(path)


def _q_deg(t: np.ndarray) -> np.ndarray:
    return np.column_stack([10.0 * (k + 1) + (k - 3) * 2.0 * t for k in range(9)])


def _ft(t: np.ndarray) -> np.ndarray:
    """Ramps, the torques a tenth of the forces: a lever arm of 0.27 m, within the arm (dynid.io.wrenches)."""
    return np.column_stack([(5.0 - k + (0.5 + k) * t) * (1.0 if k < 3 else 0.1) for k in range(6)])


def _write_port(root: Path, port: str, stamps: np.ndarray, lines: list[str], cut: str = "") -> None:
    folder = root / port
    folder.mkdir(parents=True)
    (folder / "info.log").write_text(f"Type: Bottle;\n[{stamps[0]:.6f}] /{port} [connected]\n")
    body = "".join(f"{100 + i} {s:.6f} {line}\n" for i, (s, line) in enumerate(zip(stamps, lines)))
    (folder / "data.log").write_text(body + cut)


def _stamps(rng: np.random.Generator, start: float, n: int) -> np.ndarray:
    return UNIX0 + start + np.cumsum(np.full(n, 0.01) + rng.uniform(-0.004, 0.006, n))


def _dumper(tmp_path: Path, *, stale: bool = False, cut: bool = False, gap: float = 0.0) -> Path:
    rng = np.random.default_rng(1)
    root = tmp_path / "dump"
    ts = _stamps(rng, 0.3, 600)
    if gap:
        ts[300:] += gap
    q = _q_deg(ts - UNIX0)
    groups = [" ".join(f"{v:.6f}" for v in row) for row in q]
    state = [f"({g}) [ok] (0 0 0 0 0 0 0 0 0) [ok] (1 2 3) [ok]" for g in groups]
    if stale:  # a port re-sending an old message: its stamp goes back
        ts = np.insert(ts, 200, ts[150])
        state.insert(200, "(" + " ".join(["999"] * 9) + ") [ok]")
    _write_port(root, "icub/right_arm/stateExt:o", ts, state)
    tf = _stamps(rng, 0.25, 610)
    ft = [" ".join(f"{v:.6f}" for v in row) for row in _ft(tf - UNIX0)]
    _write_port(root, "icub/right_arm/analog:o", tf, ft, cut="1234 1457614099.5 1.0 2.0" if cut else "")
    other = root / "icub/head/stateExt:o"  # a port the configuration does not read: it sets the time origin
    other.mkdir(parents=True)
    (other / "info.log").write_text("Type: Bottle;\n")
    (other / "data.log").write_text(f"1 {UNIX0 + 0.1:.6f} (0 0 0) [ok]\n2 {UNIX0 + 0.11:.6f} (0 0 0) [ok]\n")
    return root


def test_ports_on_one_time_base_in_radians(tmp_path: Path) -> None:
    config = _config(tmp_path)
    data = load_data(_dumper(tmp_path), config)
    t_abs = data.t + UNIX0 + 0.1  # the origin is the earliest stamp of any port (the head's)
    assert data.meta["yarp"]["origin_unix_s"] == pytest.approx(UNIX0 + 0.1)
    assert np.allclose(np.diff(data.t), 0.01)
    np.testing.assert_allclose(data.q, np.radians(_q_deg(t_abs - UNIX0)[:, :7]), atol=1e-7)
    np.testing.assert_allclose(data.ft["r_arm_ft"], _ft(t_abs - UNIX0), atol=1e-5)
    ports = data.meta["yarp"]["ports"]
    assert ports["icub/right_arm/stateExt:o"]["messages"] == 600
    assert 0.009 < ports["icub/right_arm/analog:o"]["median_interval_s"] < 0.012
    assert data.meta["source_format"] == "yarp dumper"


def test_a_stale_message_and_a_cut_last_line_are_dropped_and_counted(tmp_path: Path) -> None:
    data = load_data(_dumper(tmp_path, stale=True, cut=True), _config(tmp_path))
    ports = data.meta["yarp"]["ports"]
    assert ports["icub/right_arm/stateExt:o"]["dropped_not_increasing"] == 1
    assert ports["icub/right_arm/analog:o"]["dropped_cut_last_line"] == 1
    assert np.degrees(data.q).max() < 200  # the stale 999° never reaches the data


def test_a_silent_port_is_refused_with_where_and_how_long(tmp_path: Path) -> None:
    with pytest.raises(DataError, match=r"port icub/right_arm/stateExt:o is silent for 0\.2\d\d s from t = 3\.\d+ s"):
        load_data(_dumper(tmp_path, gap=0.2), _config(tmp_path))


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: p.write_text("1 2.5 (1 2 3) [ok]\n"), r"line 1: 3 joint positions, the configuration's port has 9"),
        (lambda p: p.write_text("1 abc (1 2 3) [ok]\n"), r"line 1: the stamp 'abc' is not a number"),
        (lambda p: p.write_bytes(b"\xff\xfe\x00"), r"not a text file"),
        (lambda p: p.write_text("1 2.5 (" + "x " * 9 + ") [ok]\n2 2.6 (1) [ok]\n"), r"line 1: .* not a number"),
        (lambda p: p.unlink(), r"no port 'icub/right_arm/stateExt:o'"),
    ],
)
def test_a_damaged_port_is_one_line(tmp_path: Path, damage, message: str) -> None:
    root = _dumper(tmp_path)
    damage(root / "icub/right_arm/stateExt:o/data.log")
    with pytest.raises(DataError, match=message) as info:
        load_data(root, _config(tmp_path))
    assert "\n" not in str(info.value)


def _damage_lines(path: Path, lines: dict[int, str]) -> None:
    """Replace the given 1-based lines of a port's data.log."""
    text = path.read_text().splitlines()
    for k, line in lines.items():
        text[k - 1] = line
    path.write_text("\n".join(text) + "\n")


def test_a_bad_line_is_refused_by_default_and_skip_drops_that_ports_message(tmp_path: Path) -> None:
    """A line cut to 3 values in one port: refused by default naming its file and line; with skip, that port's message
    is dropped and its neighbours interpolated across it (the signals are linear in time: exactly), the other port and
    every sample of the grid untouched."""
    config = _config(tmp_path)
    clean = load_data(_dumper(tmp_path), config)
    root = _dumper(tmp_path / "bad")
    log = root / "icub/right_arm/analog:o/data.log"
    _damage_lines(log, {301: " ".join(log.read_text().splitlines()[300].split()[:5])})
    with pytest.raises(DataError) as refused:
        load_data(root, config)
    assert str(refused.value) == (
        f"{root}: icub/right_arm/analog:o/data.log line 301: 3 values (an F/T sensor's fx fy fz tx ty tz), the "
        "configuration's port has 6 (1 bad row of 1210; --bad-rows skip drops bad rows and reports their count)")
    data = load_data(root, config, bad_rows="skip")
    assert data.n_samples == clean.n_samples and np.array_equal(data.t, clean.t)
    np.testing.assert_allclose(data.ft["r_arm_ft"], clean.ft["r_arm_ft"], atol=1e-5)
    np.testing.assert_array_equal(data.q, clean.q)
    assert data.meta["bad_rows"] == {"policy": "skip", "count": 1, "rows_read": 1210, "kinds": {"column_count": 1},
                                     "first": ["icub/right_arm/analog:o/data.log line 301"]}
    assert data.meta["yarp"]["ports"]["icub/right_arm/analog:o"]["dropped_bad_lines"] == 1
    assert data.meta["yarp"]["ports"]["icub/right_arm/analog:o"]["messages"] == 609


def test_every_kind_of_bad_line_in_every_port_is_counted_at_once(tmp_path: Path) -> None:
    config = _config(tmp_path)
    root = _dumper(tmp_path)
    state, ft = root / "icub/right_arm/stateExt:o/data.log", root / "icub/right_arm/analog:o/data.log"
    _damage_lines(state, {100: "", 200: "300 -1.5 (" + "1 " * 9 + ") [ok]"})
    _damage_lines(ft, {50: "150 1457614036.75 1 2 3 4 5 nan", 400: "500 1457614040.3 1 2 3 4 5 1e300",
                       450: "550 1457614040.8 1 2 3 4 x 6"})
    with pytest.raises(DataError, match=r": 5 bad rows of 1210: 1 empty, 1 with a cell that is not a number, 1 with a "
                                        r"non-finite value, 1 with a value beyond ±1e\+06, 1 with a negative time; at "
                                        r"icub/right_arm/stateExt:o/data.log line 100, .*line 200, "
                                        r"icub/right_arm/analog:o/data.log line 50, .*line 400, .*line 450; the first: "
                                        r"icub/right_arm/stateExt:o/data.log line 100: a blank line between messages"):
        load_data(root, config)
    data = load_data(root, config, bad_rows="skip")
    assert data.meta["bad_rows"]["count"] == 5 and np.degrees(data.q).max() < 200


def test_skipped_lines_that_leave_a_port_silent_are_refused_as_the_silence(tmp_path: Path) -> None:
    config = _config(tmp_path)
    root = _dumper(tmp_path)
    _damage_lines(root / "icub/right_arm/stateExt:o/data.log", {k: "garbage" for k in range(300, 320)})
    with pytest.raises(DataError, match=r"port icub/right_arm/stateExt:o is silent for 0\.2\d\d s from t = "):
        load_data(root, config, bad_rows="skip")


def _keep_lines(path: Path, lines: slice) -> None:
    path.write_text("".join(line + "\n" for line in path.read_text().splitlines()[lines]))


def test_a_port_that_ends_long_before_the_others_is_cut_short_refused_or_skipped_with_a_note(tmp_path: Path) -> None:
    """A port's log cut in half (the others run 3 s longer, more than yarp.max_skew): the run would silently end
    where it does. Refused by default naming the port and where it ends against the others, as a folder of files
    refuses a file that ends before the others; with skip the run ends there, the others' messages after it counted as
    cut short, and a note names the port."""
    config = _config(tmp_path)
    clean = load_data(_dumper(tmp_path), config)
    root = _dumper(tmp_path / "cut")
    _keep_lines(root / "icub/right_arm/analog:o/data.log", slice(0, 300))
    with pytest.raises(DataError, match=r"^\S+/cut/dump: (\d+) bad rows of 900: \1 cut short; at "
                                        r"icub/right_arm/stateExt:o/data.log line \d+, line \d+, .*; the first: "
                                        r"icub/right_arm/analog:o/data.log ends at t = 3\.\d{3} s, 3\.\d{3} s before "
                                        r"icub/right_arm/stateExt:o/data.log \(6\.\d{3} s\), by more than the 2 s the "
                                        r"ports' ends may differ \(yarp.max_skew\): the \1 messages the other ports hold "
                                        r"after it are cut short \(--bad-rows skip"):
        load_data(root, config)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataNote)
        data = load_data(root, config, bad_rows="skip")
    notes = [str(w.message) for w in caught if issubclass(w.category, DataNote)]
    assert len(notes) == 1 and "icub/right_arm/analog:o/data.log ends at t = 3." in notes[0] and "the run ends there" \
        in notes[0]
    ports = data.meta["yarp"]["ports"]
    assert ports["icub/right_arm/stateExt:o"]["cut_short"] > 0
    assert data.meta["bad_rows"]["kinds"] == {"cut_short": ports["icub/right_arm/stateExt:o"]["cut_short"]}
    assert data.t[-1] <= ports["icub/right_arm/analog:o"]["last_s"] < data.t[-1] + 0.01
    np.testing.assert_array_equal(data.q, clean.q[: data.n_samples])  # the same grid, shorter


def test_a_port_that_starts_long_after_the_others_is_cut_short_too(tmp_path: Path) -> None:
    config = _config(tmp_path)
    root = _dumper(tmp_path)
    _keep_lines(root / "icub/right_arm/stateExt:o/data.log", slice(300, None))
    with pytest.raises(DataError, match=r"icub/right_arm/stateExt:o/data.log starts at t = 3\.\d{3} s, 3\.\d{3} s after "
                                        r"icub/right_arm/analog:o/data.log \(0\.\d{3} s\), by more than the 2 s the "
                                        r"ports' starts may differ"):
        load_data(root, config)
    with pytest.warns(DataNote, match="the run starts there"):
        assert load_data(root, config, bad_rows="skip").t[0] > 3.0


def test_ports_that_start_and_stop_within_max_skew_are_cut_to_the_common_span_as_ever(tmp_path: Path) -> None:
    """The dumpers start and stop one after another (the iCub leg's ports end up to 1.24 s apart): the run is their
    common span, no bad row, no note; a configuration that allows less skew refuses the same folder."""
    root = _dumper(tmp_path)
    _keep_lines(root / "icub/right_arm/analog:o/data.log", slice(0, 560))  # 0.5 s before the other port's end
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        data = load_data(root, _config(tmp_path))
    assert "bad_rows" not in data.meta and data.meta["yarp"]["ports"]["icub/right_arm/stateExt:o"]["cut_short"] == 0
    with pytest.raises(DataError, match=r"by more than the 0.2 s the ports' ends may differ \(yarp.max_skew\)"):
        load_data(root, _config(tmp_path, "  max_skew: 0.2\n" + PORTS))


@pytest.mark.parametrize(
    "yarp, message",
    [
        ("  ports: []", r"field 'yarp.ports' must be a list"),
        ("  rate: 0\n" + PORTS, r"field 'yarp.rate' must be a number from 1"),
        ("  max_skew: -1\n" + PORTS, r"field 'yarp.max_skew' must be a number from 0 to 3600, got -1"),
        ("  ports:\n    - {port: a/b, joints: [r_elbow], sensor: r_arm_ft}", r"either 'joints'.*or 'sensor'"),
        ("  ports:\n    - {port: a/b, joints: [nope]}", r"names 'nope', which is not in the configuration's 'joints'"),
        ("  ports:\n    - {port: ../x, sensor: r_arm_ft}", r"'yarp.ports\[0\].port' must be the port's folder"),
        ("  ports:\n    - {port: a/b, joints: [%s], unit: grad}" % ", ".join(ARM), r"'yarp.ports\[0\].unit' must be one of rad, deg"),
        ("  ports:\n    - {port: a/b, joints: [r_elbow]}", r"gives no port for the joint 'r_shoulder_pitch'"),
        ("  ports:\n    - {port: a/b, joints: [%s]}\n    - {port: c/d, joints: [r_elbow]}" % ", ".join(ARM),
         r"names 'r_elbow', which a/b already gives"),
    ],
)
def test_a_wrong_yarp_field_names_itself(tmp_path: Path, yarp: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        _config(tmp_path, yarp)


def test_a_dumper_folder_without_a_yarp_field_says_so(tmp_path: Path) -> None:
    root = _dumper(tmp_path)
    with pytest.raises(DataError, match="yarpdatadumper folder, but the configuration icub_right_arm has no 'yarp'"):
        load_data(root, load_config("icub_right_arm"))


def test_a_fit_on_a_dumper_folder_is_recorded_and_export_finds_it_again(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """The model file keeps the folder's absolute path and a digest of its logs; export reuses the folder while
    the logs are unchanged, and says so when they changed or are gone."""
    import shutil
    from types import SimpleNamespace

    from dynid.export import model_export
    from dynid.export.model_export import calibration_data
    from dynid.identify.model_file import data_digest, data_record
    from dynid.robot.model import RobotModel

    config, root = _config(tmp_path), _dumper(tmp_path)
    record = data_record(root, 600, 6.0)
    assert record.path == str(root.resolve()) and record.sha256 == data_digest(root) is not None
    identified = SimpleNamespace(data=(record,), path="model.json")
    model = RobotModel(config)
    # the synthetic wrist leaves the URDF's limits, which the reader holds real data to: read without them here
    monkeypatch.setattr(model_export, "load_run", lambda path, robot, *_, **__: load_data(path, robot.config))
    runs, digests = calibration_data(identified, model, [])
    assert digests == record.sha256 and runs[0].meta["source_format"] == "yarp dumper"
    log = root / "icub/right_arm/analog:o/data.log"
    log.write_text(log.read_text().replace("100 ", "99 ", 1))
    with pytest.raises(DataError, match="changed since the fit"):
        calibration_data(identified, model, [])
    shutil.rmtree(root)
    with pytest.raises(DataError, match="are gone"):
        calibration_data(identified, model, [])
    assert data_digest(root) is None


def test_a_grid_slower_than_the_ports_is_noted(tmp_path: Path) -> None:
    """yarp.rate 20 Hz on ports that send every 10 ms keeps a fifth of their messages: said, with the ports' rate (a
    walkthrough's 10 Hz on the iCub leg's 100 Hz ports imported silently, and the fit then asked for a longer
    derivative window). At half the ports' rate, or the default 100 Hz, nothing is said."""
    with pytest.warns(DataNote, match=r"yarp.rate 20 Hz keeps fewer than half of the ports' messages \(the slowest "
                                      r"sends every 1\d.\d* ms"):
        data = load_data(_dumper(tmp_path), _config(tmp_path, "  rate: 20\n" + PORTS))
    assert np.allclose(np.diff(data.t), 0.05)
    for name, rate in (("half", "  rate: 50\n"), ("default", "")):
        (tmp_path / name).mkdir()
        with warnings.catch_warnings():
            warnings.simplefilter("error", DataNote)
            load_data(_dumper(tmp_path / name), _config(tmp_path / name, rate + PORTS))
