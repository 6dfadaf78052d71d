"""The sweep's cases for the C programs: `rt_monitor` (configuration lines, coefficient files, candump lines,
flags and paths) and `boards` (configuration, data.csv, flags, sinks). Exit codes as documented (docs/formats.md,
"Exit codes"); a refusal is one line on stderr (a usage error: the line, then the synopsis) and publishes or
writes nothing. The monitor replays into a file:// LCM log in the case's output directory, so a refusal that
published anything would leave it there."""

from __future__ import annotations

import math

from dynid.export.capacity import file_version

from .case import Case, Maker, boards, monitor, unreadable
from .inputs import (
    append,
    candump,
    candump_lines,
    coef,
    coef_field,
    conf,
    cut,
    directory,
    flip,
    garbage,
    mode_000,
    raw,
    replace,
    set_key,
    spoiled,
    stamp,
    with_crc,
    without,
)

URL = ("--lcm-url", "file://{out}/events.lcmlog?mode=w")
RUN = ("--model", "{coef}", "--config", "{conf}", "--replay")


def _conf(name: str, says: str, make: Maker | None, code: int = 2) -> Case:
    """rt_monitor on a mutated configuration: every refusal names the file, the line and the problem."""
    return monitor(f"monitor-conf-{name}", "--model", "{coef}", "--config", "{in}/bad.conf", "--replay", "{log}", *URL,
                   code=code, says=says, make=make)


# A frame of its own carrying r_elbow again (every frame of the arm's table is full: no free bits to add it to).
ELBOW_AGAIN = ("frame EXTRA can2 0x7F0 4 0 extra 0 -10", "signal EXTRA 0 32 le s 1e-05 0.0 q.r_elbow")
OLD_FORMAT = "is a line of the iCub-only format before the bus description: write the configuration again"
MONITOR_CONF = [
    # Issue 22's list, refused on main since the fuzz branch: this proves it through the program.
    _conf("robot-twice", "a second 'robot' line (the first is line 2)", conf(append("robot icub_right_arm"))),
    _conf("buses-twice", "a second 'buses' line (the first is line 3)", conf(append("buses can0"))),
    _conf("joint-carried-twice", "'q.r_elbow' is carried by another signal already (line 34)", conf(append(*ELBOW_AGAIN))),
    _conf("frame-twice", "a second frame 'MC_POSITION_1' (the first is line 9)",
          conf(append("frame MC_POSITION_1 can0 0x111 8 0 icub_mc_can0_1 0 -300"))),
    _conf("id-twice", "ID 0x111 on can0 is frame 'MC_POSITION_1''s already (line 9)",
          conf(append("frame OTHER can0 0x111 2 0 other 0 -10"))),
    _conf("clock-twice", "a second 'clock' line", conf(append("clock MC_POSITION_1"))),
    _conf("stale-ms-absurd", "stale_ms 1e12 is out of range: 0.1 to 1000 ms", conf(set_key("stale_ms", "1e12"))),
    _conf("stale-ms-zero", "stale_ms 0 is out of range", conf(set_key("stale_ms", "0"))),
    _conf("stale-ms-nan", "bad 'stale_ms' line: stale_ms nan", conf(set_key("stale_ms", "nan"))),
    _conf("pair-us-absurd", "pair_us 99999999 is out of range: 1 to 10000 µs", conf(set_key("pair_us", "99999999"))),
    _conf("status-hz-absurd", "status_hz 1e9 is out of range: 0.1 to 1000 Hz", conf(set_key("status_hz", "1e9"))),
    _conf("status-hz-tiny", "status_hz 1e-300 is out of range", conf(set_key("status_hz", "1e-300"))),
    _conf("status-hz-inf", "bad 'status_hz' line", conf(set_key("status_hz", "inf"))),
    _conf("residual-every-zero", "residual_every 0 is out of range", conf(set_key("residual_every", "0"))),
    _conf("contact-limit-zero", "contact_limit_s 0 is out of range: 0.1 to 86400 s", conf(set_key("contact_limit_s", "0"))),
    _conf("no-robot-line", "no 'robot' line (the coefficient file's robot is checked against it)", conf(without("robot "))),
    _conf("no-buses-line", "no 'buses' line", conf(without("buses "))),
    _conf("no-clock-line", "no 'clock' line (the frame that completes a sample)", conf(without("clock "))),
    _conf("joint-unserved", "joint r_elbow of the coefficient file is carried by no signal of the configuration",
          conf(lambda ls: [x.replace(" fault.q.r_elbow", " fault").replace(" q.r_elbow", " -") for x in ls])),
    _conf("channel-unserved", "channel pwm.m3 of the coefficient file is carried by no signal of the configuration",
          conf(lambda ls: [x.replace(" fault.pwm.m3", " fault").replace(" pwm.m3", " -") for x in ls])),
    _conf("another-robot", "exported for robot 'icub_right_arm', not for 'panda'", conf(set_key("robot", "panda")), code=20),
    _conf("unknown-key", "unknown key 'frobnicate'", conf(append("frobnicate 1"))),
    _conf("unknown-bus", "bus 'can9' is not in the 'buses' line", conf(append("frame X can9 0x7F0 1 0 x 0 -10"))),
    _conf("id-beyond-11-bits", "a frame's ID (11-bit, standard) must be an integer 0 to 2047, got '0x8C0'",
          conf(replace("frame SKIN_TAXELS_12 can2 0x4C0", "frame SKIN_TAXELS_12 can2 0x8C0"))),
    _conf("signal-outside-its-frame", "the signal at bit 8 (16 bits, le) leaves frame 'SKIN_TAXELS_12''s 2 bytes",
          conf(replace("signal SKIN_TAXELS_12 0 16", "signal SKIN_TAXELS_12 8 16"))),
    _conf("scale-zero", "a signal's scale must not be 0",
          conf(replace("signal MC_PID_VAL_2 16 16 le s 0.0007501875468867217", "signal MC_PID_VAL_2 16 16 le s 0"))),
    _conf("target-unknown", "'speed.r_wrist_yaw' is no signal target", conf(replace(" q.r_wrist_yaw", " speed.r_wrist_yaw"))),
    _conf("counter-scaled", "'seq' is a flag or a count: an integer signal with scale 1 and offset 0",
          conf(replace("signal MC_STATUS_1 24 8 le u 1.0 0.0 seq", "signal MC_STATUS_1 24 8 le u 2.0 0.0 seq"))),
    _conf("old-strain-line", "'strain' " + OLD_FORMAT, conf(append("strain can0 13 200.0 200.0 200.0 10.0 10.0 10.0"))),
    _conf("old-axis-line", "'axis' " + OLD_FORMAT, conf(append("axis can1 3 0 r_elbow 182.04444444444445 0.0"))),
    _conf("nul-byte", "unknown key 'robot\\x00'", conf(append("robot\x00 x"))),
    _conf("patch-side-sideways", "a patch's side is SENSOR:distal or SENSOR:proximal, got 'r_arm_ft:sideways'",
          conf(replace("patch hand r_arm_ft:distal", "patch hand r_arm_ft:sideways"))),
    _conf("nine-buses", "bad 'buses' line (1 to 8 bus names)", conf(set_key("buses", " ".join(f"can{i}" for i in range(9))))),
    _conf("empty", "no 'buses' line", raw("bad.conf", b"")),
    _conf("binary-garbage", "no 'buses' line", raw("bad.conf", garbage(3000, 12))),
]


def _coef(name: str, code: int, says: str, make: Maker | None) -> Case:
    return monitor(f"monitor-coef-{name}", "--model", "{in}/c.dcoef", "--config", "{conf}", "--replay", "{log}", *URL,
                   code=code, says=says, make=make)


COEFFICIENTS = [
    _coef("empty", 12, "truncated: 0 bytes, shorter than the header", raw("c.dcoef", b"")),
    _coef("truncated-header", 12, "shorter than the header", spoiled("coef", "c.dcoef", lambda b: b[:16])),
    _coef("truncated-half", 12, "truncated or padded", spoiled("coef", "c.dcoef", cut(0.5))),
    _coef("padded", 12, "truncated or padded", spoiled("coef", "c.dcoef", lambda b: b + b"\0")),
    _coef("bad-magic", 13, "not a dynid coefficient file (bad magic)", spoiled("coef", "c.dcoef", flip(0, 0x20))),
    _coef("format-version-3", 14, f"format version 3, this monitor reads {file_version()}: export the model again",
          spoiled("coef", "c.dcoef", lambda b: b[:8] + (3).to_bytes(4, "little") + b[12:])),
    _coef("format-version-next", 14, f"format version {file_version() + 1}, this monitor reads {file_version()}: a "
          "newer dynid wrote it", spoiled("coef", "c.dcoef", lambda b: b[:8] + (file_version() + 1).to_bytes(4, "little")
                                          + b[12:])),
    # a byte of the version flipped (a walkthrough: "a newer dynid wrote it: build this monitor from that dynid")
    _coef("format-version-flipped", 14, f"format version {file_version() | 0x100000}, this monitor reads "
          f"{file_version()}: no dynid wrote that, the file is damaged", spoiled("coef", "c.dcoef", flip(10, 0x10))),
    _coef("length-huge", 12, "the header says 4294967315",
          spoiled("coef", "c.dcoef", lambda b: b[:12] + (0xFFFFFFFF).to_bytes(4, "little") + b[16:])),
    _coef("bit-flipped-payload", 15, "CRC mismatch (the file is corrupt)", spoiled("coef", "c.dcoef", flip(0.5))),
    _coef("bit-flipped-crc", 15, "CRC mismatch", spoiled("coef", "c.dcoef", flip(-1, 0x80))),
    _coef("fingerprint-flipped-crc-fixed", 16, "payload is not a dynid.coefficients_t",
          spoiled("coef", "c.dcoef", lambda b: with_crc(flip(16, 0x01)(b)))),
    _coef("garbage-payload-crc-fixed", 16, "payload is not a dynid.coefficients_t",
          spoiled("coef", "c.dcoef", lambda b: with_crc(b[:16] + bytes(len(b) - 20) + b[-4:]))),
    _coef("joints-inconsistent", 18, "does not fit its joint type", coef(coef_field("n_joints", 3))),
    _coef("period-tiny", 18, "sample period 1e-300 s out of range: 1e-05 to 1 s", coef(coef_field("sample_period", 1e-300))),
    _coef("threshold-negative", 18, "detector settings out of range", coef(coef_field("threshold", -1.0))),
    _coef("period-nan", 19, "non-finite value in the detector or filter settings",
          coef(coef_field("sample_period", math.nan))),
    _coef("another-robot", 20, "exported for robot 'panda', not for 'icub_right_arm'", coef(coef_field("robot_name", "panda"))),
    unreadable(_coef("unreadable", 11, "cannot open the coefficient file: Permission denied", mode_000("coef", "c.dcoef"))),
    _coef("missing", 11, "cannot open the coefficient file: No such file or directory", None),
    # Found by this sweep: libstdc++'s filebuf threw on EISDIR, and the monitor died of SIGABRT.
    _coef("a-directory", 11, "cannot read the coefficient file: Is a directory", directory("c.dcoef")),
]


NOT_FRAMES = "2200 lines (the first: line 4) are not classic-CAN candump -L frames, skipped"


def _replay(name: str, prints: str, make: Maker | None, warns: str = NOT_FRAMES) -> Case:
    """A damaged candump log: the monitor counts and skips what it cannot use, runs to the end (exit 0), and says its
    start-up line on stderr, then one warning where it skipped lines of the log (how many, the first's number)."""
    return monitor(f"monitor-log-{name}", *RUN, "{in}/run.log", "--lcm-url", "memq://", code=0, says="rt_monitor: running:",
                   make=make, prints=prints, warns=warns)


def _blind(name: str, says: str, make: Maker | None, warns: str = "") -> Case:
    """A log from which no sample can be evaluated: the run is blind, exit 6, its last line naming why (before it, the
    start-up line and the watchdog's fault lines)."""
    return monitor(f"monitor-log-{name}", *RUN, "{in}/run.log", "--lcm-url", "memq://", code=6, says=says, make=make,
                   warns=warns)


CANDUMP_LINES = [
    _replay("truncated-lines", "bad source input 2200", candump(lambda x: x[: len(x) // 2])),
    _replay("bad-hex", "bad source input 2200", candump(lambda x: x.replace("#", "#ZZ", 1))),
    _replay("nine-data-bytes", "bad source input 2200", candump(lambda x: x + "001122334455667788")),
    _replay("odd-hex-digits", "bad source input 2200", candump(lambda x: x + "A")),
    _replay("can-fd", "bad source input 2200", candump(lambda x: x.replace("#", "##1", 1))),
    _replay("unknown-interface", "bad source input 2200", candump(lambda x: x.replace(" can", " vcan", 1)),
            "2200 lines (the first: line 4) are frames of interfaces not among the configuration's buses, skipped"),
    _replay("negative-stamps", "bad source input 2200", candump(stamp("(-1.000000)"))),
    _replay("stamps-past-int64", "bad source input 2200", candump(stamp("(99999999999999999999.000000)"))),
    _replay("no-parenthesis", "bad source input 2200", candump(lambda x: x.replace("(", "", 1))),
    _replay("nul-bytes", "bad source input 2200", candump(lambda x: x[:10] + "\x00" + x[10:])),
    _replay("non-utf8", "bad source input 2200", candump(lambda x: x + " \udce9")),
    _replay("error-frames", "error frames 2200", candump(lambda x: x.split("#")[0][:-3] + "20000004#0000000000000000"), ""),
    _replay("remote-frames", "unknown id 2200", candump(lambda x: x.split("#")[0] + "#R"), ""),
    _replay("extended-ids", "unknown id 2200", candump(lambda x: " ".join(x.split(" ")[:2]) + " 1FFFFFFF#00"), ""),
    _replay("a-huge-line", "bad source input 1",
            candump_lines(lambda ls: ls[:100] + ["(1700000000.000000) can0 123#" + "A" * 100000] + ls[100:]),
            "line 101 is not a classic-CAN candump -L frame, skipped"),
    # Logs that give no sample to evaluate: the monitor ran blind, and says so (exit 6, the watchdog's reason).
    _blind("every-line-twice", "the clock pair's halves are not paired", candump_lines(lambda ls: [x for x in ls for _ in (0, 1)])),
    _blind("reversed", "no sample", candump_lines(lambda ls: ls[::-1])),
    _blind("binary-garbage", "run.log holds no candump -L frame of the configuration's buses",
           raw("run.log", garbage(20000, 13)), "(the first: line 1) are not classic-CAN candump -L frames, skipped"),
    _blind("empty", "run.log holds no candump -L frame of the configuration's buses", raw("run.log", b"")),
]

MONITOR_FLAGS = [
    monitor("monitor-config-missing", "--model", "{coef}", "--config", "{in}/gone.conf", "--replay", "{log}", *URL, code=2,
            says="cannot open the configuration: No such file or directory"),
    # Found by this sweep: a directory read as an empty file ("no 'buses' line").
    monitor("monitor-config-a-directory", "--model", "{coef}", "--config", "{in}", "--replay", "{log}", *URL, code=2,
            says="cannot read the configuration: Is a directory"),
    monitor("monitor-replay-missing", *RUN, "{in}/gone.log", *URL, code=2, says="cannot open candump log: No such file"),
    # Found by this sweep: it started ("running: replay of DIR"), then failed reading (exit 1).
    monitor("monitor-replay-a-directory", *RUN, "{in}", *URL, code=2, says="cannot open candump log: Is a directory"),
    # Found by this sweep: an empty --replay fell through to SocketCAN.
    monitor("monitor-replay-empty-value", *RUN, "", *URL, code=2, says="'--replay' needs a value", synopsis=True),
    monitor("monitor-replay-and-loopback", *RUN, "{log}", "--loopback", "{out}", *URL, code=2,
            says="--replay and --loopback exclude each other", synopsis=True),
    # Found by stop 47's walkthrough: --realtime without --replay fell through to SocketCAN.
    monitor("monitor-realtime-without-replay", "--model", "{coef}", "--config", "{conf}", "--realtime", *URL, code=2,
            says="--realtime paces a --replay", synopsis=True),
    monitor("monitor-loopback-missing-directory", "--model", "{coef}", "--config", "{conf}", "--loopback", "{in}/no",
            *URL, code=1, says="loopback bind: No such file or directory"),
    # Found by this sweep: liblcm's own line came on stderr before the monitor's.
    monitor("monitor-lcm-unknown-provider", *RUN, "{log}", "--lcm-url", "bogus://x", code=2,
            says="LCM URL 'bogus://x': no LCM provider 'bogus'"),
    monitor("monitor-lcm-log-into-missing-directory", *RUN, "{log}", "--lcm-url", "file://{out}/no/e.lcmlog?mode=w",
            code=1, says="Failed to open {out}/no/e.lcmlog: No such file or directory"),
    monitor("monitor-lcm-log-onto-a-directory", *RUN, "{log}", "--lcm-url", "file://{out}?mode=w", code=1,
            says="Is a directory"),
    # Found by this sweep: found only after the whole run (exit 1), and onto a directory its .tmp stayed behind.
    monitor("monitor-latency-into-missing-directory", *RUN, "{log}", *URL, "--latency-out", "{out}/no/lat.txt", code=2,
            says="--latency-out {out}/no/lat.txt: No such file or directory"),
    monitor("monitor-latency-onto-a-directory", *RUN, "{log}", *URL, "--latency-out", "{out}", code=2,
            says="--latency-out {out}: Is a directory"),
    monitor("monitor-stats-into-missing-directory", *RUN, "{log}", *URL, "--stats-out", "{out}/no/s.json", code=2,
            says="--stats-out {out}/no/s.json: No such file or directory"),
    monitor("monitor-stats-onto-a-directory", *RUN, "{log}", *URL, "--stats-out", "{out}", code=2,
            says="--stats-out {out}: Is a directory"),
    monitor("monitor-stats-empty-value", *RUN, "{log}", *URL, "--stats-out", "", code=2,
            says="'--stats-out' needs a value", synopsis=True),
    monitor("monitor-priority-text", *RUN, "{log}", *URL, "--priority", "high", code=2,
            says="--priority needs an integer, got 'high'", synopsis=True),
    monitor("monitor-priority-zero", *RUN, "{log}", *URL, "--priority", "0", code=2,
            says="--priority 0: SCHED_FIFO's priorities are 1..99", synopsis=True),
    monitor("monitor-cpu-list-backwards", *RUN, "{log}", *URL, "--cpu", "3-1", code=2,
            says="--cpu needs a CPU list as taskset -c takes it", synopsis=True),
    monitor("monitor-cpu-absent", *RUN, "{log}", *URL, "--cpu", "4095", code=5, says="the system refused the CPU affinity"),
    monitor("monitor-no-model", "--config", "{conf}", code=2, says="--model and --config are required", synopsis=True),
    monitor("monitor-flag-without-value", "--config", "{conf}", "--model", code=2, says="'--model' needs a value",
            synopsis=True),
    monitor("monitor-unknown-flag", *RUN, "{log}", "--bogus", code=2, says="unknown argument '--bogus'", synopsis=True),
]


def _boards(name: str, *args: str, code: int, says: str, make: Maker | None = None, synopsis: bool = False) -> Case:
    return boards(f"boards-{name}", *args, code=code, says=says, make=make, synopsis=synopsis)


PLAY = ("--config", "{conf}", "--data")
SINK = ("--sink", "candump:{out}/b.log")
BAD_CONF = ("--config", "{in}/bad.conf", "--data", "{run}", *SINK)
BOARDS = [
    _boards("conf-missing", "--config", "{in}/gone.conf", "--data", "{run}", *SINK, code=3, says="gone.conf: No such file"),
    # Found by this sweep: a directory read as an empty configuration ("no 'buses' line", exit 4).
    _boards("conf-a-directory", "--config", "{in}", "--data", "{run}", *SINK, code=3, says="read error: Is a directory"),
    _boards("conf-buses-twice", *BAD_CONF, code=4, says="a second 'buses' line", make=conf(append("buses can0"))),
    # Found by this sweep: what rt_monitor refuses in the file they share, the boards played without a word.
    _boards("conf-unknown-key", *BAD_CONF, code=4, says="unknown key 'strian'",
            make=conf(append("strian can0 13 200 200 200 10 10 10"))),
    _boards("conf-joint-carried-twice", *BAD_CONF, code=4, says="'q.r_elbow' is carried by another signal already",
            make=conf(append(*ELBOW_AGAIN))),
    _boards("conf-frame-twice", *BAD_CONF, code=4, says="a second frame 'MC_POSITION_1'",
            make=conf(append("frame MC_POSITION_1 can0 0x111 8 0 icub_mc_can0_1 0 -300"))),
    _boards("conf-old-strain-line", *BAD_CONF, code=4, says="'strain' " + OLD_FORMAT,
            make=conf(append("strain can0 13 200 200 200 10 10 10"))),
    _boards("conf-a-long-line", *BAD_CONF, code=4, says="line longer than 65535 bytes", make=conf(append("# " + "x" * 70000))),
    _boards("conf-no-clock", *BAD_CONF, code=4, says="no 'clock' line", make=conf(without("clock "))),
    _boards("conf-id-beyond-11-bits", *BAD_CONF, code=4, says="a frame's ID is 11-bit, 0 to 0x7FF",
            make=conf(replace("frame SKIN_TAXELS_12 can2 0x4C0", "frame SKIN_TAXELS_12 can2 0x8C0"))),
    _boards("conf-binary-garbage", *BAD_CONF, code=4, says="or with a NUL byte", make=raw("bad.conf", garbage(3000, 14))),
    _boards("data-missing", *PLAY, "{in}/gone.csv", *SINK, code=3, says="gone.csv: No such file or directory"),
    unreadable(_boards("data-unreadable", *PLAY, "{in}/data.csv", *SINK, code=3, says="Permission denied",
                       make=mode_000("csv", "data.csv"))),
    _boards("data-directory-without-csv", *PLAY, "{in}", *SINK, code=3, says="data.csv: No such file or directory"),
    _boards("data-empty", *PLAY, "{in}/data.csv", *SINK, code=4, says="empty file, no CSV header", make=raw("data.csv", b"")),
    _boards("data-binary-garbage", *PLAY, "{in}/data.csv", *SINK, code=4, says="header line too long",
            make=raw("data.csv", garbage(70000, 15))),
    # Found by this sweep: one row was played and refused as a bus at 94 % (its load over no period), exit 6.
    _boards("data-one-row", *PLAY, "{in}/data.csv", *SINK, code=4, says="one data row: a run needs at least two",
            make=lambda fx, d: (d / "data.csv").write_text("\n".join(fx.csv_lines[:2]) + "\n")),
    # Found by this sweep: t in ms was played as 50 minutes of CAN at 1 Hz.
    _boards("data-t-in-ms", *PLAY, "{in}/data.csv", *SINK, code=4, says="t steps by 1 s on average, outside 10 us to under "
            "1 s: the t column must be in seconds (is it in milliseconds?)",
            make=lambda fx, d: (d / "data.csv").write_text("\n".join([fx.csv_lines[0]] + [
                ",".join([repr(float(x.split(",", 1)[0]) * 1000), x.split(",", 1)[1]]) for x in fx.csv_lines[1:]]) + "\n")),
    # Found by this sweep: the first of two 'q.r_elbow' columns was played.
    _boards("data-duplicated-column", *PLAY, "{in}/data.csv", *SINK, code=4, says="column 'q.r_elbow' appears twice",
            make=lambda fx, d: (d / "data.csv").write_text("\n".join(
                [fx.csv_lines[0] + ",q.r_elbow"] + [x + ",0.5" for x in fx.csv_lines[1:]]) + "\n")),
    _boards("data-nan", *PLAY, "{in}/data.csv", *SINK, code=4, says="is not a finite number: 'nan'",
            make=lambda fx, d: (d / "data.csv").write_text(fx.csv.read_text().replace(",0.0,", ",nan,", 1))),
    _boards("data-time-backwards", *PLAY, "{in}/data.csv", *SINK, code=4, says="t is not strictly increasing",
            make=lambda fx, d: (d / "data.csv").write_text("\n".join(fx.csv_lines[:3] + fx.csv_lines[2:4]) + "\n")),
    _boards("data-nul-byte", *PLAY, "{in}/data.csv", *SINK, code=4, says="or with a NUL byte",
            make=lambda fx, d: (d / "data.csv").write_bytes(fx.csv.read_bytes()[:3000] + b"\0" + fx.csv.read_bytes()[3000:])),
    _boards("data-missing-column", *PLAY, "{in}/data.csv", *SINK, code=4, says="no column 'q.r_elbow'",
            make=lambda fx, d: (d / "data.csv").write_text(fx.csv.read_text().replace("q.r_elbow", "q.r_elbo", 1))),
    _boards("sink-into-missing-directory", *PLAY, "{run}", "--sink", "candump:{out}/no/b.log", code=5,
            says="cannot write: No such file or directory"),
    _boards("sink-onto-a-directory", *PLAY, "{run}", "--sink", "candump:{out}", code=5, says="Is a directory"),
    _boards("sink-unknown", *PLAY, "{run}", "--sink", "pigeon:{out}/x", code=2, says="unknown sink 'pigeon:", synopsis=True),
    _boards("sink-without-path", *PLAY, "{run}", "--sink", "candump:", code=2, says="needs a path", synopsis=True),
    _boards("loopback-nobody-listening", *PLAY, "{run}", "--sink", "loopback:{out}", code=5,
            says="is rt_monitor --loopback running?"),
    _boards("t0-negative", *PLAY, "{run}", *SINK, "--t0", "-1", code=2, says="--t0 must be seconds >= 0", synopsis=True),
    _boards("repeat-zero", *PLAY, "{run}", *SINK, "--repeat", "0", code=2, says="--repeat N needs 1 <= N <= 100000",
            synopsis=True),
    _boards("restart-malformed", *PLAY, "{run}", *SINK, "--restart", "x", code=2, says="--restart NODE|ADDRESS@SAMPLE",
            synopsis=True),
    # Found by this sweep: a restart of a board that is not there, or after the run, did nothing, silently.
    _boards("restart-unknown-board", *PLAY, "{run}", *SINK, "--restart", "9@5", code=2,
            says="--restart 9@5: no motor-control board at address 9", synopsis=True),
    _boards("restart-after-the-run", *PLAY, "{run}", *SINK, "--restart", "1@99999999", code=2,
            says="--restart 1@99999999: the run has 1000 samples", synopsis=True),
    _boards("unknown-sensor", *PLAY, "{run}", *SINK, "--sensor", "nope", code=4, says="no column 'ft.nope.fx'"),
    _boards("strain-sat-maybe", *PLAY, "{run}", *SINK, "--strain-sat", "maybe", code=2, says="--strain-sat auto|on|off",
            synopsis=True),
    _boards("unknown-flag", *PLAY, "{run}", *SINK, "--bogus", code=2, says="unknown argument '--bogus'", synopsis=True),
    # Found by this sweep: refused (exit 6) after its log was renamed into place; now the log is not kept.
    _boards("bus-overloaded", "--config", "{in}/bad.conf", "--data", "{run}", *SINK, code=6,
            says="is loaded at 156 % (70 % or more at 1 Mbit/s)",
            make=conf(lambda ls: [x if x.startswith(("buses", "#", "robot")) else
                                  x.replace(" can1 ", " can0 ").replace(" can2 ", " can0 ") for x in ls])),
]
