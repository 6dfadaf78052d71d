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

import contextlib
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
from ..outputs import written_by
from .monitor_config import check_capacity, monitor_config_text

BOARDS = Path(__file__).resolve().parents[3] / "build" / "firmware_like" / "boards"
ENCODERS = ("auto", "generic", "icub")
STAMPS = ("recorded", "nominal")


@dataclass(frozen=True)
class Played:
    samples: int
    frames: int
    load: dict[str, float]  # per bus, fraction of the bus description's bit rate over the run (worst-case bit stuffing)
    summary: str  # boards' own lines
    period_s: float  # the run's mean sample period, as recorded
    step_range_s: tuple[float, float]  # its smallest and largest step (the jitter sent as recorded)
    nominal_s: float | None = None  # stamps="nominal": the grid's step the samples went out on
    drift: ClockDrift | None = None  # stamps="recorded": how far the stamps drift from the monitor's grid
    bus_period_s: float = 0.0  # the bus's own period (1 / its rate): the nominal one where the run's steps agree
    dq_estimated: bool = False  # the bus carries q̇, the run records none: sent as estimated from q


@dataclass(frozen=True)
class ClockDrift:
    """Recorded stamps against the grid the monitor's sample clock puts samples on (one per period): a run whose
    steps are not whole periods (the UR10e logger's 10 and 12 ms at 100 Hz, the Panda's 0.97-1.00 ms at 1 kHz)
    drifts off it, and the clock, made for boards that send on a timer and following a drift of a few hundred ppm
    only (rt_monitor/include/rt_monitor/sample_clock.hpp), reads the excess as samples lost or late: it bridges or
    holds samples the run never lost."""

    period_s: float  # the monitor's period for this run (the bus's, or the median step: BusDescription.nominal_period)
    span_s: float  # the stamps' span, first to last
    drift_s: float  # that span less the whole periods the steps round to
    periods: int  # the drift in whole periods: grid slots more (fewer) than the rounded steps account for

    @property
    def ppm(self) -> float:
        return 0.0 if self.span_s <= 0 else 1e6 * abs(self.drift_s) / self.span_s

    def misleads(self) -> bool:
        """Whether the drift reaches a whole period, faster than the clock follows."""
        return abs(self.periods) >= 1 and self.ppm > DRIFT_FOLLOWED_PPM


DRIFT_FOLLOWED_PPM = 500.0  # the sample clock's slow leak follows a board clock "a few hundred ppm" off


def clock_drift(t: np.ndarray, period_s: float) -> ClockDrift:
    """How the recorded stamps `t` sit against a grid of `period_s` from their first."""
    steps = np.diff(t)
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    whole = np.rint(steps / period_s)
    drift = span - float(whole.sum()) * period_s
    return ClockDrift(period_s, span, drift, int(round(span / period_s) - whole.sum()))


CLAMPED_SHARE = 0.01  # of a run's samples, a value's signal may clamp before its scale is judged wrong


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
            lo, hi = s.physical_range
            step = abs(s.scale) / 2
            out = np.flatnonzero((np.asarray(v) < lo - step) | (np.asarray(v) > hi + step))
            # Clamped, a position is another posture: the log would lie. Another value is clamped at its signal's
            # range as the robot's board would send it, a few samples of a run; beyond CLAMPED_SHARE of them the
            # signal's scale cannot carry the run (a walkthrough's F/T scale a thousand times small: every sample
            # clamped, said in one line, exit 0)
            where = f"its signal {f.name}.{s.name} carries ({s.length} bits, scale {s.scale:g})"
            check = f"check the signal's scale, offset and length in {robot}'s bus"
            if s.target.startswith("q.") and out.size:
                raise DataError(f"{s.target} reaches {float(v[out[0]]):.6g} (sample {int(out[0])}), beyond the "
                                f"{lo:.6g} to {hi:.6g} {where}: {check}")
            if out.size > CLAMPED_SHARE * len(v):
                raise DataError(f"{s.target} is beyond the {lo:.6g} to {hi:.6g} {where} on {out.size} of {len(v)} "
                                f"samples (the first: {float(v[out[0]]):.6g}, sample {int(out[0])}): {check}")
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
    # the bus carries q̇ and the run records none (a simulated run): sent as the offline filter estimates it; a run with
    # the controller's velocity.J sends that (dynid.io.candump.target_values)
    carried = {s.target.partition(".")[2] for f in bus.frames for s in f.signals if s.target.startswith("dq.")}
    estimated = data.dq is None and any(f"velocity.{j}" not in data.extra for j in carried)
    if estimated:
        options = dict(config.derivatives)
        try:
            data = data.with_derivatives(options.pop("method", None), **options)
        except ValueError as e:
            raise DataError(f"the bus carries q̇, the run records none, and it cannot be estimated from q: {e}") from None
    steps = np.diff(data.t)
    # the run's period as the monitor takes it: the bus's where its rate agrees with the median step, else the
    # median step (to the µs), as `dynid export` takes the file's period
    period = round(bus.nominal_period(float(np.median(steps))) * 1e6) * 1e-6 if steps.size else 1.0 / bus.rate
    nominal = drift = None
    if stamps == "nominal":  # the run's own samples on the grid of that period
        nominal = period
        data = replace(data, t=data.t[0] + np.arange(data.n_samples) * nominal)
    else:
        drift = clock_drift(data.t, period)
    kind, _, where = sink.partition(":")
    # candump:- streams the log to our standard output (boards then puts its summary on stderr)
    to_stdout = sink == "candump:-"
    with contextlib.ExitStack() as stack:
        tmp = stack.enter_context(tempfile.TemporaryDirectory(prefix="dynid-play-"))
        # A candump log is written by boards at a path of our own beside it, moved into place when boards is done
        # (at the command's end: dynid.outputs): boards's own temporary file stays in there, removed with it,
        # when boards is stopped (Ctrl-C reaches it too; a SIGKILL from subprocess.run) or fails.
        log = None if kind != "candump" or to_stdout else stack.enter_context(written_by(where))
        conf, csv = Path(tmp) / "monitor.conf", Path(tmp) / "data.csv"
        conf.write_text(monitor_config_text(config))
        csv.write_text(player_csv(data, bus, config.name))
        args = [str(BOARDS), "--config", str(conf), "--data", str(csv), "--sink", sink if log is None else
                f"candump:{log}", "--encoder", encoder, "--strain-sat", long_form, "--bitrate", str(bus.bitrate)]
        if realtime:
            args.append("--realtime")
        if t0 is not None:
            args += ["--t0", repr(float(t0))]
        done = subprocess.run(args, stdout=None if to_stdout else subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        text = done.stderr if to_stdout else done.stdout
        if log is not None:  # boards names the path it was given: the user's
            text, stderr = (t.replace(str(log), where) for t in (text, done.stderr))
        else:
            stderr = done.stderr
        if done.returncode < 0:  # e.g. SIGPIPE: whatever read `candump:-` went away
            raise DataError(f"boards was stopped by signal {-done.returncode} "
                            f"({signal.Signals(-done.returncode).name})")
        if done.returncode != 0:
            why = (stderr.strip().splitlines() or [f"boards exited {done.returncode}"])[0]
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
                  nominal, drift, 1.0 / bus.rate, estimated)
