"""Every given real run onto its robot's bus and back (issue 30): `dynid play` (the iCub leg with the board emulators,
the UR10e, the Panda and TIAGo with the generic encoder) into a candump log; `cantools decode` with the DBC of
`dynid export --dbc` decodes every frame (no unknown ID, no wrong size); `dynid import` of the log gives the run back
within each signal's quantisation; `rt_monitor --replay` with the robot's CAD coefficient file assembles every sample,
none stale or unknown, and with `--stamps nominal` evaluates exactly the run's samples (none bridged). One test per
robot; each skips, with the reason, without the data. A window of each run keeps it to seconds.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.io.load import apply_window, load_data

from . import cli, convert

REALDATA = convert.REALDATA
ROOT = Path(__file__).resolve().parents[2]
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"

# robot: (run, its URDF, the coefficient file's rate in Hz, the window in the run's seconds)
RUNS = {
    "icub_right_leg_standing": ("icub_leg_insitu/dumperLeftLegNoIMU", "icub_leg_insitu/iCubGenova02.urdf", 100, (14, 44)),
    "ur10e": ("ur10e_mamedov/contact/collision_3link.csv", "ur10e_mamedov/ur10e.urdf", 100, (1690, 1720)),
    "panda": ("panda_gaz2019/rbt_log", None, 1000, (2, 6)),  # the loggers' folders of files (`files:`)
    "tiago_wrist": ("tiago_wrist_ft/dynamic", "tiago_wrist_ft/urdf/tiago_48_hey5.urdf", 100, (0, 30)),
}


def run(*args: object, stdin: Path | None = None) -> subprocess.CompletedProcess:
    with open(stdin or "/dev/null", "rb") as f:
        return subprocess.run([str(a) for a in args], stdin=f, capture_output=True, text=True, timeout=900)


@pytest.mark.parametrize("robot", sorted(RUNS))
def test_a_real_run_onto_the_bus_and_back(robot: str, tmp_path: Path) -> None:
    source, urdf, rate, (t_from, t_to) = RUNS[robot]
    if not REALDATA.is_dir():
        pytest.skip(f"real robot data not found at {REALDATA} (clone shared/ beside the repository)")
    data_path = REALDATA / source
    urdf_args = ("--urdf", REALDATA / urdf) if urdf else ()
    config = load_config(robot, REALDATA / urdf if urdf else None)
    window = f"{data_path}@{t_from}:{t_to}"
    log, dbc, conf, coef = (tmp_path / n for n in ("run.log", "bus.dbc", "monitor.conf", "cad.dcoef"))
    done = cli.run("play", "--robot", robot, *urdf_args, "--data", window, "--sink", f"candump:{log}",
               "--bad-rows", "skip")
    assert done.returncode == 0, done.stderr
    assert "clamped" not in done.stdout  # the bus description keeps the run's values in range
    for args in (("--dbc", dbc, "--monitor-config", conf, "--lcm-url", "memq://"),
                 ("--cad", "--rate", str(rate), "--out", coef)):
        done = cli.run("export", "--robot", robot, *urdf_args, *args)
        assert done.returncode == 0, done.stderr

    decoded = run(sys.executable, "-m", "cantools", "decode", "--single-line", dbc, stdin=log)
    lines = decoded.stdout.splitlines()
    assert decoded.returncode == 0 and len(lines) == len(log.read_text().splitlines()) > 0
    assert not [l for l in lines if "Unknown frame id" in l or "Wrong data size" in l]

    want = apply_window(load_data(data_path, config, bad_rows="skip"), t_from, t_to)
    got = load_data(log, config)
    assert got.n_samples == want.n_samples
    assert np.abs(got.t - (want.t - want.t[0])).max() <= 1e-6  # µs stamps, taken from t0 + t in float64
    scale = {s.target: s.scale for f in config.bus.frames for s in f.signals}
    for name, values in got.columns():
        if name in scale:
            reference = dict(want.columns()).get(name)
            if reference is None and name.startswith("dq."):
                reference = want.extra[f"velocity.{name[3:]}"]  # the UR10e controller's velocities
            assert np.abs(values - reference).max() <= scale[name] / 2 * (1 + 1e-9), name

    for stamps in ("recorded", "nominal"):
        if stamps == "nominal":
            assert cli.run("play", "--robot", robot, *urdf_args, "--data", window, "--sink", f"candump:{log}",
                       "--bad-rows", "skip", "--stamps", "nominal").returncode == 0
        done = run(RT_MONITOR, "--model", coef, "--config", conf, "--replay", log)
        # 7: read to its end with a watchdog fault, named on stderr (a CAD model on a real run, a logger's stamps); the
        # bus is what this test checks, the faults test_realdata_monitor's
        assert done.returncode in (0, 7), done.stderr
        n = want.n_samples
        assert f"samples {n}, " in done.stdout and ", stale 0," in done.stdout, done.stdout
        assert "unknown id 0, bad length 0, error frames 0, unpaired halves 0," in done.stdout, done.stdout
        if stamps == "nominal":
            assert f"evaluated {n}, " in done.stdout and "interpolated 0, late 0," in done.stdout, done.stdout
