"""Any robot's run onto its CAN bus (`dynid play`): dynid reads the run in any form it reads (CSV, a headerless log,
a YARP dumper folder, a ROS 2 bag, a simulated run, a dataset, a candump log), hands its samples to firmware_like's
`boards` as one uniform CSV (a column per value the robot's bus description carries, and the skin's ground truth),
and `boards` encodes the frames from the compiled bus table onto the sink: a candump log, the loopback transport or
SocketCAN, paced (`realtime`) or as fast as possible.

Unevenly sampled runs (the UR10e's, the Panda's and TIAGo's logs jitter) are never resampled: the samples played are
the run's own, one for one (an interpolated F/T or current sample is one no robot sent). By default they are sent at
their recorded stamps (`stamps="recorded"`): the log's time is kept, `dynid import` of the candump gives the run back,
and the monitor's sample clock meets the jitter as recorded (a gap of more than 1.5 periods is a lost sample it
bridges). `stamps="nominal"` sends sample k at t0 + k · the run's nominal period (the bus's where its rate agrees
with the run's median step to 5 %, else that median, to the µs)
instead: the monitor then evaluates
exactly the run's samples in order, none bridged, as the offline analysis does (the way to compare the two sample for
sample); a controller's log jitter is its logger's, not its bus's. Samples closer together than the bus table spreads
one sample's frames (it sends them between its earliest offset and the clock frame) are refused, as they would mix.
"""

from __future__ import annotations

import signal
import subprocess
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..config.bus import BusDescription, is_value_target
from ..config.robot_config import RobotConfig
from ..errors import DataError, InputError
from ..io.candump import target_values
from ..io.dataset import Dataset
from .monitor_config import check_capacity, monitor_config_text

BOARDS = Path(__file__).resolve().parents[3] / "build" / "firmware_like" / "boards"
ENCODERS = ("auto", "generic", "icub")
STAMPS = ("recorded", "nominal")


@dataclass(frozen=True)
class Played:
    samples: int
    frames: int
    load: dict[str, float]  # per bus, fraction of 1 Mbit/s over the run (worst-case bit stuffing)
    summary: str  # boards' own lines
    period_s: float  # the run's mean sample period, as recorded
    step_range_s: tuple[float, float]  # its smallest and largest step (the jitter sent as recorded)
    nominal_s: float | None = None  # stamps="nominal": the grid's step the samples went out on


def player_csv(data: Dataset, bus: BusDescription, robot: str) -> str:
    """The run as `boards` reads it: t, every value target of the bus (q.J, dq.J, pwm.M, current.M, tau.J, ft.S.C),
    contact and skin.patch, every number written so that it reads back exactly."""
    columns: list[tuple[str, np.ndarray]] = [("t", data.t)]
    for f in bus.frames:
        for s in f.signals:
            if not is_value_target(s.target):
                continue
            v = target_values(data, s.target)
            if v is None:
                raise DataError(f"the run has no {s.target}, which frame {f.name} of {robot}'s bus carries "
                                f"(signal {s.name})")
            columns.append((s.target, v))
    if data.contact is not None:
        columns.append(("contact", data.contact.astype(float)))
    if "skin.patch" in data.extra:
        columns.append(("skin.patch", data.extra["skin.patch"]))
    table = np.column_stack([np.asarray(v, float) for _, v in columns])
    lines = [",".join(name for name, _ in columns)]
    lines += [",".join(repr(x) for x in row) for row in table.tolist()]
    return "\n".join(lines) + "\n"


def play_run(config: RobotConfig, data: Dataset, sink: str, realtime: bool = False, encoder: str = "auto",
             t0: float | None = None, long_form: str = "auto", stamps: str = "recorded") -> Played:
    """Play `data` onto `sink` (candump:PATH, loopback:DIR, socketcan) through the robot's bus, with `boards`."""
    bus = check_capacity(config)
    if encoder not in ENCODERS:
        raise InputError(f"--encoder must be one of {', '.join(ENCODERS)}, got {encoder!r}")
    if stamps not in STAMPS:
        raise InputError(f"--stamps must be one of {', '.join(STAMPS)}, got {stamps!r}")
    if not BOARDS.is_file():
        raise InputError(f"{BOARDS} is not built: run scripts/setup")
    steps = np.diff(data.t)
    nominal = None
    if stamps == "nominal":  # the run's own samples on the grid of its nominal period: the bus's where its rate
        # agrees with the median step, else the median step (to the µs), as `dynid export` takes the file's period
        nominal = round(bus.nominal_period(float(np.median(steps))) * 1e6) * 1e-6
        data = replace(data, t=data.t[0] + np.arange(data.n_samples) * nominal)
    with tempfile.TemporaryDirectory(prefix="dynid-play-") as tmp:
        conf, csv = Path(tmp) / "monitor.conf", Path(tmp) / "data.csv"
        conf.write_text(monitor_config_text(config))
        csv.write_text(player_csv(data, bus, config.name))
        args = [str(BOARDS), "--config", str(conf), "--data", str(csv), "--sink", sink, "--encoder", encoder,
                "--strain-sat", long_form]
        if realtime:
            args.append("--realtime")
        if t0 is not None:
            args += ["--t0", repr(float(t0))]
        # candump:- streams the log to our standard output (boards then puts its summary on stderr)
        to_stdout = sink == "candump:-"
        done = subprocess.run(args, stdout=None if to_stdout else subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    text = done.stderr if to_stdout else done.stdout
    if done.returncode < 0:  # e.g. SIGPIPE: whatever read `candump:-` went away
        raise DataError(f"boards was stopped by signal {-done.returncode} ({signal.Signals(-done.returncode).name})")
    if done.returncode != 0:
        why = (done.stderr.strip().splitlines() or [f"boards exited {done.returncode}"])[0]
        raise DataError(why.removeprefix("boards: error: "))
    samples = frames = 0
    load: dict[str, float] = {}
    for line in text.splitlines():
        words = line.split()
        if " samples, " in line:
            samples, frames = int(words[1]), int(words[3])
        elif words[1:2] == ["bus"]:
            load[words[2]] = float(words[4]) / 100
    return Played(samples, frames, load, text.strip(), float(steps.mean()), (float(steps.min()), float(steps.max())),
                  nominal)
