"""Write the real runs of shared/realdata as ROS 2 bags (MCAP or SQLite), with `rosbags` (dynid.io.rosbag_write).

Usage::

    python tests/realdata/to_bag.py OUT_DIR [--storage mcap|sqlite3] [--source DIR]

Each run becomes the bag a ROS 2 user of the robot records, through the bundled configuration's `ros2:` field:

- the UR10e's headerless logs (`ur10e`): /joint_states, positions, the controller's velocities, currents as efforts;
- the Panda (`panda`): /joint_states with the recorded velocities and the measured torques as efforts;
- the TIAGo (`tiago_wrist`): /joint_states and the wrist's /wrist_ft (convert.py's run, t on whole nanoseconds);
- the iCub leg (`icub_right_leg_standing`): every YARP port of the folder as its own topic, with the port's own
  stamps and messages (a `stateExt:o` as a JointState of its positions in rad, an `analog:o` as a WrenchStamped),
  so that the bag is read as the folder is, on one 100 Hz grid.

A bag read back gives the run's samples bit for bit (tests/realdata/test_realdata_bags.py asserts it, and that the
fits are the same). The bags are written to OUT_DIR, never into the repository.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dynid.config.log_columns import UNITS
from dynid.config.robot_config import RobotConfig, load_config
from dynid.config.yarp_ports import YarpPort
from dynid.io.load import load_data
from dynid.io.rosbag_write import BagWriter, stamp_ns, write_bag
from dynid.io.yarp import _GROUP, _read_port

try:  # run as a script or imported by the tests
    from . import convert
except ImportError:  # pragma: no cover - `python tests/realdata/to_bag.py`
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tests.realdata import convert

UR10E = convert.REALDATA / "ur10e_mamedov"
LEG = convert.REALDATA / "icub_leg_insitu"
LEG_URDF = LEG / "iCubGenova02.urdf"
DUMP = LEG / "dumperLeftLegNoIMU"


def ur10e_config() -> RobotConfig:
    return load_config("ur10e", convert.UR10E_URDF)


def ur10e_runs(source: Path = UR10E) -> list[Path]:
    """Every controller log of the UR10e folder (not the episode labels)."""
    return [p for p in sorted(source.glob("*/*.csv")) if not p.name.endswith(".episodes.csv")]


def ur10e_bag(log: Path, out: Path, storage: str = "mcap") -> Path:
    """One UR10e controller log as the bag of its /joint_states."""
    write_bag(load_data(log, ur10e_config()), out, ur10e_config(), storage)
    return out


def panda_bag(csv: Path, out: Path, storage: str = "mcap") -> Path:
    """The Panda run (a CSV of convert.py) as the bag of its /joint_states."""
    config = load_config("panda")
    write_bag(load_data(csv, config), out, config, storage)
    return out


def tiago_bag(csv: Path, out: Path, storage: str = "mcap") -> Path:
    """The TIAGo run (a CSV of convert.py) as the bag of /joint_states and /wrist_ft."""
    config = load_config("tiago_wrist", convert.TIAGO_URDF)
    write_bag(load_data(csv, config), out, config, storage)
    return out


def icub_leg_bag(out: Path, storage: str = "mcap", dump: Path = DUMP) -> Path:
    """Every port of the iCub leg's YARP folder as its own topic, message for message (module docstring)."""
    config = load_config("icub_right_leg_standing", LEG_URDF)
    assert config.yarp is not None
    configured = {p.port: p for p in config.yarp.ports}
    messages: list[tuple[int, str, str, list[str], np.ndarray]] = []  # (ns, kind, topic, names, values)
    for log in sorted(dump.glob("**/data.log")):
        port = log.parent.relative_to(dump).as_posix()  # icub/<part>/<stateExt:o | analog:o>
        part = log.parent.parent.name
        spec = configured.get(port) or _port_spec(log, port)
        read = _read_port(dump, spec)
        if spec.joints:  # a joint the configuration does not name is <part>_<slot>
            names = [j if j != "_" else f"{part}_{k}" for k, j in enumerate(spec.joints)]
            topic, kind = f"/icub/{part}/joint_states", "joints"
        else:
            names, topic, kind = [], f"/icub/{part}/ft", "wrench"
        messages += [(stamp_ns(float(t)), kind, topic, names, v) for t, v in zip(read.stamps, read.values)]
    messages.sort(key=lambda m: (m[0], m[2]))
    with BagWriter(out, storage) as bag:
        for ns, kind, topic, names, values in messages:
            if kind == "joints":
                bag.joint_state(topic, ns, names, values)
            else:
                bag.wrench(topic, ns, "", values)
    return out


def _port_spec(log: Path, port: str) -> YarpPort:
    """A port the configuration does not read, described from its first line: a stateExt:o's joints (deg) or an
    analog:o's six values."""
    first = log.read_text().split("\n", 1)[0]
    if port.endswith("stateExt:o"):
        width = len(_GROUP.findall(first)[0].split())
        return YarpPort(port, joints=("_",) * width, scale=(UNITS["q"]["deg"],) * width)
    return YarpPort(port, sensor="_", scale=(1.0,) * 6)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the folder to write the bags into (created; never the repository)")
    parser.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    written = [ur10e_bag(log, args.out / f"ur10e_{log.stem}", args.storage) for log in ur10e_runs()]
    for robot, conversion, write in (("panda", convert.convert_panda, panda_bag),
                                     ("tiago", convert.convert_tiago, tiago_bag)):
        csv = args.out / f"{robot}.csv"
        conversion().write(csv)
        written.append(write(csv, args.out / robot, args.storage))
    written.append(icub_leg_bag(args.out / "icub_leg", args.storage))
    for path in written:
        print(f"{path} ({args.storage})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
