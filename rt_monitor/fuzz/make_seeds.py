"""Writes the fuzz harnesses' seed inputs (files named seed-*) from the project's fixtures; docs/fuzzing.md.

    .venv/bin/python rt_monitor/fuzz/make_seeds.py     (after the CMake build: it runs build/firmware_like/boards)

Sources: the committed CAD coefficient file (rt_monitor/tests/data/icub_cad.dcoef), as a file and as a payload,
a variant with both effects and supply tracking on, and one with known answers
(wrong ones: they reach the loader's check); the bundled configuration (rt_monitor/config) in its order
and with buses last; the candump lines of rt_monitor/tests/test_frame_source.cpp; a short deterministic run (a
synthetic data.csv of the bundled arm, one with a saturated strain channel) played by `boards` into a candump log,
that log as frames for the assembler, and one frame of every message class of the arm's bus table (and of what is
none: error, remote and extended frames, wrong lengths, reserved bits), and a small table of another protocol
(big-endian signals, a float, a clock frame of its own, a pair that does not clock) for the configuration readers. The corpora also hold what the
fuzzers found and `-merge=1` kept (files named by their sha1); those are left alone here.
"""

from __future__ import annotations

import math
import re
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RT = ROOT / "rt_monitor" / "fuzz" / "corpus"
FW = ROOT / "firmware_like" / "fuzz" / "corpus"
COEF = ROOT / "rt_monitor" / "tests" / "data" / "icub_cad.dcoef"
CONF = ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"
BOARDS = ROOT / "build" / "firmware_like" / "boards"
BUSES = ["can0", "can1", "can2"]

sys.path.insert(0, str(ROOT / "tools"))
from dynid.export.coefficients import unwrap, wrap  # noqa: E402
from dynid.export.lcm_coefficients import coefficients_t  # noqa: E402


def put(corpus: Path, name: str, data: bytes | str) -> None:
    corpus.mkdir(parents=True, exist_ok=True)
    (corpus / f"seed-{name}").write_bytes(data.encode() if isinstance(data, str) else data)


def coefficient_seeds() -> None:
    good = COEF.read_bytes()
    payload = unwrap(good)
    d = RT / "coefficients"
    put(d, "icub_cad.dcoef", good)
    put(d, "icub_cad.payload", payload)  # the harness wraps it validly too
    c = coefficients_t.decode(payload)
    c.n_effects = 2
    c.effect_kind = [1, 2]
    c.effect_joint = [3, 1]
    c.effect_param = [[0.4, 0.05, 0.0], [2.0, 0.3, 0.0]]
    c.supply_time_constant = 5.0
    c.supply_prior = 1.0
    c.supply_gate = [0.2 if k == 1 else 0.0 for k in c.channel_kind]
    put(d, "effects_supply.payload", c.encode())
    put(d, "effects_supply.dcoef", wrap(c.encode()))
    m = coefficients_t.decode(payload)  # the momentum observer selected, with supply tracking and a band
    m.residual = 1
    m.supply_time_constant, m.supply_prior, m.supply_gate = c.supply_time_constant, c.supply_prior, c.supply_gate
    m.joint_band = [[0.05, 0.04] for _ in m.joint_band]
    put(d, "momentum.payload", m.encode())
    put(d, "momentum.dcoef", wrap(m.encode()))
    k = coefficients_t.decode(payload)  # known answers to reach the loader's check (not the core's: it refuses them)
    k.estimator = "iv"
    k.n_known = k.window + 9
    k.known_input = [[0.01 * math.sin(0.1 * i + j) for j in range(k.known_width)] for i in range(k.n_known)]
    k.known_answer = [[math.nan if i < k.window - 1 else 1.0] * k.known_columns for i in range(k.n_known)]
    put(d, "known_answers.payload", k.encode())
    put(d, "known_answers.dcoef", wrap(k.encode()))


# Another protocol's table (rt_monitor/tests/test_assembler.cpp's robot): what the iCub arm's does not exercise.
OTHER = """robot arm
buses can0 can1
frame POS0 can0 0x181 8 0 drive 0 -400
signal POS0 0 32 le s 1e-06 0 q.j0
signal POS0 32 32 le s 1e-06 0 dq.j0
frame HB can0 0x701 2 0 drive 100000 -450
signal HB 0 4 le u 1 0 seq
signal HB 4 1 le u 1 0 fault.q.j0
signal HB 5 3 le u 1 0 reserved
signal HB 8 8 le u 1 0 restart
frame FT_F can1 0x281 6 0 ft 0 -300
signal FT_F 0 16 le s 0.01 0 ft.w.fx
frame FT_T can1 0x282 7 8 ft 0 -200
signal FT_T 0 16 le s 0.001 0 ft.w.tx
signal FT_T 63 8 be u 1 0 saturated.ft.w.tx
frame TEMP can1 0x381 4 0 temp 0 -100
signal TEMP 0 32 le f 1 0 -
frame CUR can0 0x191 4 0 amps 0 0
signal CUR 7 16 be s 0.001 0 current.m0
signal CUR 23 16 be s 0.001 0 current.m1
patch palm w:distal
frame SKIN can1 0x401 1 0 skin 0 -150
signal SKIN 0 1 le u 1 0 skin.palm
clock CUR
pair FT_F FT_T
"""


def config_seeds() -> tuple[str, str]:
    ordered = CONF.read_text()
    lines = ordered.splitlines()
    buses = [l for l in lines if l.startswith("buses ")]
    shuffled = "\n".join([l for l in lines if not l.startswith("buses ")] + ["lcm_url memq://"] + buses) + "\n"
    for d in (RT / "monitor_config", FW / "boards_conf"):
        put(d, "icub_right_arm.conf", ordered)
        put(d, "buses_last.conf", shuffled)
        put(d, "other_protocol.conf", OTHER)
    return ordered, shuffled


def run_csv(ordered: str, saturate: bool, reorder: bool) -> str:
    joints = re.findall(r"^signal \S+ .* q\.(\S+)$", ordered, re.M)
    motors = re.findall(r"^signal \S+ .* pwm\.(\S+)$", ordered, re.M)
    ft = [f"ft.r_arm_ft.{a}" for a in ("fx", "fy", "fz", "tx", "ty", "tz")]
    cols = ["t"] + [f"q.{j}" for j in joints] + [f"pwm.{m}" for m in motors] + ft + ["contact", "skin.patch"]
    rows = []
    for k in range(12):
        t = 0.001 * k
        row = [t] + [0.2 * math.sin(3 * t + j) for j in range(len(joints))]
        row += [0.3 * math.cos(5 * t + m) for m in range(len(motors))]
        row += [10.0 + k, -5.0, 30.0 * (1 + (saturate and k == 4) * 9), 0.5, -0.25, 0.1]
        row += [1.0 if 5 <= k <= 8 else 0.0, 2.0 if 5 <= k <= 8 else 0.0]
        rows.append(row)
    if reorder:  # the joints first: a header whose first byte is odd (the harness then names the sensor)
        order = list(range(1, len(cols))) + [0]
        cols = [cols[i] for i in order]
        rows = [[r[i] for i in order] for r in rows]
    return ",".join(cols) + "\n" + "\n".join(",".join(repr(v) for v in r) for r in rows) + "\n"


def candump_log(conf: str, csv: str) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "c.conf").write_text(conf)
        (Path(tmp) / "data.csv").write_text(csv)
        out = Path(tmp) / "run.log"
        subprocess.run([str(BOARDS), "--config", f"{tmp}/c.conf", "--data", f"{tmp}/data.csv",
                        "--sink", f"candump:{out}"], check=True, capture_output=True)
        return out.read_text()


def record(bus: int, can_id: int, flags: int, data: bytes, dt: int, length: int | None = None) -> bytes:
    """One frame as the assembler harness reads it (fuzz_assembler.cpp)."""
    n = len(data) if length is None else length
    return struct.pack("<BHBBhB8s", bus, can_id & 0xFFFF, flags, n, dt, 0, data.ljust(8, b"\0"))


def frames_of(log: str) -> bytes:
    out, prev = b"", None
    for line in log.splitlines():
        m = re.match(r"\((\d+)\.(\d{6})\) (\S+) ([0-9A-F]{3})#([0-9A-F]*)$", line)
        assert m, line
        t = int(m[1]) * 1_000_000 + int(m[2])
        dt = 0 if prev is None else max(-32768, min(32767, t - prev))
        prev = t
        out += record(BUSES.index(m[3]), int(m[4], 16), 0, bytes.fromhex(m[5]), dt)
    return out


def main() -> int:
    coefficient_seeds()
    ordered, _ = config_seeds()
    csv = run_csv(ordered, saturate=False, reorder=False)
    csv_sat = run_csv(ordered, saturate=True, reorder=True)
    put(FW / "boards_csv", "run.csv", csv)
    put(FW / "boards_csv", "saturated_sensor_named.csv", csv_sat)
    put(FW / "boards_csv", "crlf.csv", csv.replace("\n", "\r\n"))
    log, log_sat = candump_log(ordered, csv), candump_log(ordered, csv_sat)

    # candump: the replayed log, the parser's test vectors (rt_monitor/tests/test_frame_source.cpp).
    put(RT / "candump", "boards.log", log)
    put(RT / "candump", "boards_saturated.log", log_sat)
    put(RT / "candump", "test_vectors.log", "\n".join([
        "(1700000000.000001) can1 3DA#00800180FF7F05", "(12.5) can2 1234ABCD#", "(1.000000) can0 113#R4",
        "(1.000000) can0 20000004#0004000000000000", "(1.0) can0 111#00.11.22", "# a comment", "   ",
        "(1.0 can0 111#00", "(1.) can0 111#00", "(1.0) can0 11#00", "(1.0) can0 800#00", "(1.0) can0 111#000",
        "(1.0) can0 111#001122334455667788", "(1.0) can0 111##10011", "(1.0) can0 111#0G", "(1.0) can0 111#00 x",
        "(1.0) can0 111", "(1.0) vcan9 111#00", "(1.0003) can1 112#" + "0" * 400, "(1.000400) can2 480#0100"]))

    # assembler: the log as frames, and every message class once (bus, ID, flags, payload).
    put(RT / "assembler", "boards.frames", frames_of(log))
    put(RT / "assembler", "boards_saturated.frames", frames_of(log_sat))
    classes = [
        (0, 0x3DA, 0, bytes.fromhex("008000800080")), (0, 0x3DB, 0, bytes.fromhex("008000800080")),  # strain
        (0, 0x3DA, 0, bytes.fromhex("FF7F0080008001")), (0, 0x3DB, 0, bytes.fromhex("00800080008008")),  # sat, reserved
        (0, 0x111, 0, bytes(8)), (0, 0x112, 0, bytes.fromhex("10000000")),  # POSITION, PID_VAL
        (0, 0x113, 0, bytes.fromhex("01000100")), (0, 0x113, 0, bytes.fromhex("20000000")),  # STATUS: restart, bad
        (2, 0x480, 0, bytes.fromhex("0100")), (2, 0x4C0, 0, bytes.fromhex("0000")),  # SKIN
        (0, 0x004, 4, bytes.fromhex("0004000000000000")), (0, 0x111, 2, b""), (0, 0x1234, 1, b"\1"),  # err, rtr, eff
        (1, 0x7FF, 0, b""), (0, 0x111, 0, bytes(4)), (0, 0x3DC, 0, bytes(6))]  # unknown, bad length, other type
    put(RT / "assembler", "every_class.frames", b"".join(record(b, i, f, d, 50) for b, i, f, d in classes))

    # icub_can: ID (16 bits), DLC, payload, two doubles, two int32 (fuzz_icub_can.c).
    def can(i: int, dlc: int, payload: bytes, a: float = 200.0, b: float = 10.0) -> bytes:
        return struct.pack("<HB8sddii", i, dlc, payload.ljust(8, b"\0"), a, b, 1000, 200000)
    for name, seed in {"strain": can(0x3DA, 6, bytes.fromhex("00800180FF7F")),
                       "strain_sat": can(0x3DB, 7, bytes.fromhex("00800180FF7F05")),
                       "position": can(0x111, 8, bytes.fromhex("1027000000F0FFFF")),
                       "pid_val": can(0x212, 4, bytes.fromhex("9AFF6400")),
                       "status": can(0x113, 4, bytes.fromhex("11020342")),
                       "skin": can(0x480, 2, bytes.fromhex("0100")),
                       "bad_id": can(0x0800, 0, b"", float("nan"), -1.0)}.items():
        put(FW / "icub_can", name, seed)

    for text in ("0", "1", "0-3", "0,2", "0-1,4-7", "50", "-1", "99"):
        put(RT / "rt_options", text.replace(",", "_"), text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
