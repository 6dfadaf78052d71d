"""ROS 2 bags in (dynid.io.rosbag), without the real data: a simulated run written as MCAP and SQLite bags reads
back bit for bit and fits as its CSV does; wrenches on their own clock are interpolated (or taken nearest) at the
joint states' stamps against an analytic signal; several topics go onto one grid; every bag that cannot be read or
aligned is refused in one line. tests/realdata/test_realdata_bags.py does the same on the real runs."""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dynid.cli import main
from dynid.config.robot_config import BUNDLED_DIR, load_config
from dynid.errors import DataError
from dynid.identify.model_file import load_model
from dynid.io.csv_format import write_csv
from dynid.io.load import load_data
from dynid.io.rosbag_write import BagWriter, stamp_ns, write_bag

T0 = 1_700_000_000  # s: a Unix time, as a real robot's header stamps are
ARM = load_config().joints  # the default arm's seven joints


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def panda_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 6 s simulated Panda run as a CSV whose times are whole nanoseconds, as a ROS clock's are (the simulator's
    k·0.001 is not always the float nearest k ms: 9·0.001 = 0.009000000000000001)."""
    root = tmp_path_factory.mktemp("panda")
    code, _, err = run("simulate", "--robot", "panda", "--duration", "6", "--out", str(root / "sim"))
    assert code == 0, err
    ds = load_data(root / "sim" / "data.csv", load_config("panda"))
    write_csv(replace(ds, t=np.round(ds.t * 1e9) / 1e9), root / "run.csv")
    return root / "run.csv"


def test_a_run_written_as_mcap_and_sqlite_bags_reads_back_and_fits_bit_for_bit(panda_csv: Path, tmp_path: Path) -> None:
    config = load_config("panda")
    csv = load_data(panda_csv, config)
    for storage in ("mcap", "sqlite3"):
        write_bag(csv, tmp_path / storage, config, storage)
        bag = load_data(tmp_path / storage, config)
        assert bag.column_names() == csv.column_names()
        assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(bag.columns(), csv.columns(), strict=True))
        assert bag.meta["ros2"]["storage"] == storage and bag.meta["source_format"] == "ros2 bag"
    mcap_file = next((tmp_path / "mcap").glob("*.mcap"))  # one storage file alone is a bag too
    assert np.array_equal(load_data(mcap_file, config).q, csv.q)
    models = {}
    for name, data in (("csv", panda_csv), ("bag", tmp_path / "sqlite3")):
        models[name] = tmp_path / f"{name}.json"
        code, _, err = run("fit", "--robot", "panda", "--data", str(data), "--out", str(models[name]))
        assert code == 0, err
    csv_model, bag_model = (load_model(str(models[k])) for k in ("csv", "bag"))
    assert bag_model.phi.tolist() == csv_model.phi.tolist()  # one process: the same arithmetic, bit for bit
    assert ({k: e.to_json() for k, e in bag_model.estimators.items()}
            == {k: e.to_json() for k, e in csv_model.estimators.items()})
    assert bag_model.data[0].sha256 != csv_model.data[0].sha256
    code, out, err = run("import", "--robot", "panda", "--data", f"{tmp_path / 'mcap'}@1:3", "--out",
                         str(tmp_path / "d.npz"), "--json", str(tmp_path / "import.json"))
    assert code == 0 and "ROS 2 bag (mcap): /joint_states" in out, err
    assert json.loads((tmp_path / "import.json").read_text())["ros2"]["clock"] == "/joint_states"


def arm_config(tmp_path: Path, ros2: str) -> Path:
    """The default arm's configuration with a `ros2:` field."""
    path = tmp_path / "arm.yaml"
    path.write_text((BUNDLED_DIR / "icub_right_arm.yaml").read_text() + "\nros2:\n" + ros2)
    return path


WRIST = "  joint_states: /joint_states\n  wrenches:\n    - {topic: /ft, sensor: r_arm_ft, frame: r_upper_arm}\n"


def q_at(t: float) -> np.ndarray:
    return 0.2 * np.sin(t + np.arange(len(ARM)))


def wrench_at(t: float) -> np.ndarray:
    """A wrench linear in time: interpolation between two messages gives it exactly (to rounding)."""
    return np.array([1.0, -2.0, 3.0, 0.1, -0.2, 0.3]) + t * np.array([2.0, 1.0, -1.0, 0.5, 0.2, -0.1])


def write_arm_bag(path: Path, wrench_period: float = 0.0025, gap_at: float | None = None,
                  garbage: tuple[int, ...] = (), storage: str = "mcap", ahead: dict[int, float] | None = None) -> None:
    """Joint states at 1 kHz for 0.5 s; a wrench at 400 Hz starting 10.3 ms late; a gripper's joint states on the same
    topic; an optional silence of the wrench topic, garbage joint states, and joint states stamped `ahead` s late."""
    with BagWriter(path, storage) as bag:
        for k in range(500):
            t = k * 1e-3
            position = np.full(len(ARM), 1e150) if k in garbage else q_at(t)
            stamp = T0 + t + (ahead or {}).get(k, 0.0)  # the header's; the bag records it at T0 + t
            bag.joint_state("/joint_states", stamp_ns(stamp), list(ARM), position, log_ns=stamp_ns(T0 + t))
            if k % 50 == 0:
                bag.joint_state("/joint_states", stamp_ns(T0 + t) + 1, ["r_hand_finger"], np.array([0.5]))
        k = 0
        while (t := 0.0103 + k * wrench_period) < 0.5:
            if gap_at is None or not gap_at <= t < gap_at + 0.01:
                bag.wrench("/ft", stamp_ns(T0 + t), "r_upper_arm", wrench_at(t))
            k += 1


def test_a_wrench_on_its_own_clock_is_interpolated_at_the_joint_states(tmp_path: Path) -> None:
    config = load_config(arm_config(tmp_path, WRIST))
    write_arm_bag(tmp_path / "bag")
    ds = load_data(tmp_path / "bag", config, require_all=False)
    info = ds.meta["ros2"]
    # Joint states before the first wrench (10.3 ms) are left out, and so are those after the last (497.8 ms).
    assert info["outside_wrench_span"] == {"before": 11, "after": 2}
    assert info["topics"]["/joint_states"]["other_publishers"] == 10  # the gripper's messages
    assert ds.n_samples == 487 and ds.t[0] == T0 + 0.011  # the header stamps, in seconds
    t = ds.t - T0
    expected = np.array([wrench_at(x) for x in t])
    assert np.max(np.abs(ds.ft["r_arm_ft"] - expected)) < 1e-6  # stamps at 0.24 µs resolution near T0
    assert np.array_equal(ds.q, np.array([q_at(k * 1e-3) for k in range(11, 498)]))  # the messages' own floats

    (tmp_path / "n").mkdir()
    nearest = load_config(arm_config(tmp_path / "n", WRIST + "  wrench_alignment: nearest\n  wrench_tolerance: 0.0013\n"))
    ds = load_data(tmp_path / "bag", nearest, require_all=False)
    taken = np.round((ds.t - T0 - 0.0103) / 0.0025)  # the index of the nearest wrench message
    assert np.max(np.abs(ds.ft["r_arm_ft"] - np.array([wrench_at(0.0103 + k * 0.0025) for k in taken]))) == 0.0


def test_several_topics_go_onto_one_grid_from_the_earliest_stamp(tmp_path: Path) -> None:
    config = load_config(arm_config(tmp_path, "  joint_states: [/shoulder/joint_states, /forearm/joint_states]\n"
                                    "  wrenches: [{topic: /ft, sensor: r_arm_ft}]\n  rate: 200\n"))
    with BagWriter(tmp_path / "bag", "sqlite3") as bag:
        bag.joint_state("/head/joint_states", stamp_ns(T0 - 0.5), ["neck_pitch"], np.zeros(1))  # the origin
        for k in range(700):  # 1 kHz, and 300 Hz with another phase
            bag.joint_state("/shoulder/joint_states", stamp_ns(T0 + k * 1e-3), list(ARM[:4]), 0.1 * np.arange(4) * k * 1e-3)
            if k < 210:
                t = 0.0021 + k / 300
                bag.joint_state("/forearm/joint_states", stamp_ns(T0 + t), list(ARM[4:]), 0.3 * np.arange(1, 4) * t)
        for k in range(350):
            bag.wrench("/ft", stamp_ns(T0 + 0.001 + k * 0.002), "", wrench_at(0.001 + k * 0.002))
    ds = load_data(tmp_path / "bag", config, require_all=False)
    assert ds.meta["ros2"]["origin_s"] == T0 - 0.5 and ds.meta["ros2"]["clock"] == "grid"
    t = ds.t - 0.5  # seconds after T0
    assert np.allclose(np.diff(ds.t), 0.005) and t[0] == pytest.approx(0.0021, abs=1e-6) and t[-1] <= 0.0021 + 209 / 300 + 1e-6
    # Linear signals interpolate exactly, but for the stamps' resolution near T0 (2^-22 s) times their slopes.
    assert np.allclose(ds.q[:, :4], 0.1 * np.arange(4) * t[:, None], rtol=0, atol=1e-6)
    assert np.allclose(ds.q[:, 4:], 0.3 * np.arange(1, 4) * t[:, None], rtol=0, atol=1e-6)
    assert np.allclose(ds.ft["r_arm_ft"], [wrench_at(x) for x in t], rtol=0, atol=1e-6)


def test_garbage_joint_states_are_bad_rows_refused_or_skipped(tmp_path: Path) -> None:
    config = load_config(arm_config(tmp_path, WRIST))
    write_arm_bag(tmp_path / "bag", garbage=(100, 101, 300))
    # Rows are named by the message's place in its topic, the gripper's messages counted (one after k = 0, 50, 100, ...): 100 is the 103rd, 101 the 105th.
    with pytest.raises(DataError, match=r"3 bad rows of 487: 3 with a value beyond ±1e\+06; at message 103 of "
                                        r"/joint_states, message 105 of /joint_states, message 307 of /joint_states;"):
        load_data(tmp_path / "bag", config, require_all=False)
    ds = load_data(tmp_path / "bag", config, require_all=False, bad_rows="skip")
    assert ds.n_samples == 484 and ds.meta["bad_rows"]["count"] == 3


def test_one_header_stamp_ahead_drops_that_message_only(tmp_path: Path) -> None:
    # The rule "beat every earlier stamp" kept the message stamped 0.1 s ahead and dropped the 100 good ones after it.
    config = load_config(arm_config(tmp_path, WRIST))
    write_arm_bag(tmp_path / "bag", ahead={200: 0.1})
    with pytest.raises(DataError, match=r"t is out of order at message 205 of /joint_states: .* ahead of the next row "
                                        r"kept .*\(1 bad row of 487;"):
        load_data(tmp_path / "bag", config, require_all=False)
    ds = load_data(tmp_path / "bag", config, require_all=False, bad_rows="skip")
    assert ds.n_samples == 486 and ds.meta["bad_rows"]["count"] == 1
    assert np.all(np.diff(ds.t) > 0) and np.sum((ds.t > T0 + 0.2005) & (ds.t < T0 + 0.2995)) == 99  # k = 201..299


def bag_cases() -> list[tuple[str, str, str]]:
    """(case, ros2 field, what the one line says)."""
    return [
        ("no topic", WRIST.replace("/ft,", "/wrist/ft,"), "no topic /wrist/ft (the configuration's ros2 field names it)"),
        ("wrong type", WRIST.replace("/ft,", "/joint_states,") .replace("joint_states: /joint_states", "joint_states: /ft"),
         "topic /ft carries geometry_msgs/msg/WrenchStamped, not sensor_msgs/msg/JointState"),
        ("frame", WRIST.replace("r_upper_arm", "r_forearm"), "is in frame 'r_upper_arm', the configuration's is 'r_forearm'"),
        ("gap", WRIST + "  wrench_tolerance: 0.004\n", "has no message for 0.0125 s around the joint state"),
        ("nearest", WRIST + "  wrench_alignment: nearest\n  wrench_tolerance: 0.0005\n", "no message of /ft within 0.0005 s"),
        ("renamed joint", WRIST + "  joint_names: {right_elbow: r_elbow}\n", "has no joint 'right_elbow'"),
    ]


@pytest.mark.parametrize(("ros2", "says"), [c[1:] for c in bag_cases()], ids=[c[0] for c in bag_cases()])
def test_a_bag_that_cannot_be_aligned_is_refused_in_one_line(tmp_path: Path, ros2: str, says: str) -> None:
    write_arm_bag(tmp_path / "bag", gap_at=0.2)
    code, _, err = run("import", "--robot", str(arm_config(tmp_path, ros2)), "--data", str(tmp_path / "bag"), "--out",
                       str(tmp_path / "d.npz"))
    assert code == 2 and len(err.splitlines()) == 1 and says in err, err
    assert not (tmp_path / "d.npz").exists()


@pytest.mark.parametrize(("name", "content", "robot", "says"), [
    ("bag.mcap", b"\x89MCAP0\r\n" + b"\x00" * 64, "panda", "not a readable ROS 2 bag"),
    ("bag.db3", b"not sqlite at all", "panda", "not a readable ROS 2 bag"),
    ("bag.bin", b"\x89MCAP0\r\n" + b"\x00" * 64, "panda", "is named .mcap or .db3"),
    ("bag.mcap", None, "icub_right_arm", "has no 'ros2' field naming its topics"),
])
def test_a_bag_that_cannot_be_read_is_refused_in_one_line(tmp_path: Path, name: str, content: bytes | None,
                                                         robot: str, says: str) -> None:
    path = tmp_path / name
    if content is None:
        with BagWriter(tmp_path / "b", "mcap") as bag:
            bag.joint_state("/joint_states", stamp_ns(T0), list(ARM), q_at(0.0))
        path = next((tmp_path / "b").glob("*.mcap"))
    else:
        path.write_bytes(content)
    code, _, err = run("import", "--robot", robot, "--data", str(path), "--out", str(tmp_path / "d.npz"))
    assert code == 2 and len(err.splitlines()) == 1 and says in err, err


def test_a_storage_file_without_its_metadata_is_named_and_readable_alone(tmp_path: Path) -> None:
    config = arm_config(tmp_path, WRIST)
    write_arm_bag(tmp_path / "bag")
    (tmp_path / "bag" / "metadata.yaml").unlink()
    code, _, err = run("import", "--robot", str(config), "--data", str(tmp_path / "bag"), "--out", str(tmp_path / "d.npz"))
    storage = next((tmp_path / "bag").glob("*.mcap"))
    assert code == 2 and err.strip().endswith(f"holds the ROS 2 bag storage file {storage.name} but no metadata.yaml: "
                                              f"give {storage} itself, or the bag's folder with its metadata.yaml"), err
    assert load_data(storage, load_config(config), require_all=False).n_samples == 487


def test_zero_header_stamps_are_refused_unless_the_log_time_is_asked_for(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag", "mcap") as bag:
        for k in range(200):
            bag.joint_state("/joint_states", 0, list(ARM), q_at(k * 1e-3), log_ns=stamp_ns(T0 + k * 1e-3))
    header = load_config(arm_config(tmp_path, "  joint_states: /joint_states\n"))
    with pytest.raises(DataError, match="every header stamp of /joint_states is zero; set the configuration's "
                                        "ros2.stamp to 'log'"):
        load_data(tmp_path / "bag", header, require_all=False)
    (tmp_path / "log").mkdir()
    logged = load_config(arm_config(tmp_path / "log", "  joint_states: /joint_states\n  stamp: log\n"))
    assert load_data(tmp_path / "bag", logged, require_all=False).t[-1] == T0 + 0.199
