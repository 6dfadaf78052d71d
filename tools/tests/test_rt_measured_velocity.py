"""The observer on the robot's own measured q̇ (coefficient file `observer_velocity` 1): where the robot's bus carries
every joint's velocity (a dq.J signal each, as the Panda's and the UR10e's do) and the calibration runs hold it, the
export calibrates the observer on it and the monitor takes it from the bus, as `dynid detect` takes the data's
velocity columns offline. On the UR10e's collisions this is 11 of 11 where the estimate from q gave 5
(tests/realdata/test_realdata_monitor.py, docs/detection.md#the-monitor); here, without real data, a simulated Panda
run that carries velocity columns."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from test_rt_core import BUILDS, EXIT_BASE, dynid, rt_eval

from dynid.config.robot_config import load_config
from dynid.export.coefficients import read_coefficients, unwrap, wrap
from dynid.export.lcm_coefficients import coefficients_t
from dynid.export.rt_eval_io import raw_samples, write_matrix
from dynid.io.load import load_data


@pytest.fixture(scope="module")
def panda(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A simulated Panda run with the robot's velocity columns (here the simulator's q, differentiated: any signal the
    robot sends is one), its fit and its export."""
    work = tmp_path_factory.mktemp("panda_velocity")
    done = dynid("simulate", "--robot", "panda", "--kind", "identification", "--duration", "20", "--out",
                 str(work / "sim"))
    assert done.returncode == 0, done.stderr
    config = load_config("panda")
    ds = load_data(work / "sim", config)
    for i, joint in enumerate(ds.joints):
        ds.extra[f"velocity.{joint}"] = np.gradient(ds.q[:, i], ds.t)
    ds.save(work / "run.npz")
    for step in (("fit", "--robot", "panda", "--data", str(work / "run.npz"), "--out", str(work / "model.json")),
                 ("export", "--model", str(work / "model.json"), "--out", str(work / "model.dcoef")),
                 ("export", "--robot", "panda", "--monitor-config", str(work / "monitor.conf"), "--lcm-url",
                  "memq://")):
        done = dynid(*step)
        assert done.returncode == 0, done.stderr
    return {"run": work / "run.npz", "coef": work / "model.dcoef", "conf": work / "monitor.conf", "work": work}


def test_the_export_takes_the_robots_velocity_and_the_core_reproduces_it(panda: dict[str, Path]) -> None:
    """The file says so, its known answers carry q̇ after q, and both builds' cores reproduce them at load."""
    c = read_coefficients(panda["coef"])
    assert c.observer_velocity == 1 and c.residual == 2
    assert c.known_width == 2 * c.n_joints + c.n_outputs and c.n_known > 1000
    for build in BUILDS:
        done = rt_eval("--coef", str(panda["coef"]), "--check", exe=build / "rt_monitor" / "rt_eval")
        assert done.returncode == 0, done.stderr


def test_the_core_takes_the_given_velocity(panda: dict[str, Path], tmp_path: Path) -> None:
    """Not the estimate from q: the same file with its known answers' q̇ moved by 0.01 rad/s is refused (the core's
    observer then gives other numbers), and a stream without the q̇ columns is refused in one line."""
    c = coefficients_t.decode(unwrap(panda["coef"].read_bytes()))
    nj = c.n_joints
    c.known_input = [list(row[:nj]) + [v + 0.01 for v in row[nj:2 * nj]] + list(row[2 * nj:]) for row in c.known_input]
    moved = tmp_path / "moved.dcoef"
    moved.write_bytes(wrap(c.encode()))
    done = rt_eval("--coef", str(moved), "--check")
    assert done.returncode == EXIT_BASE + 12 and "does not reproduce the file's known answers" in done.stderr, done.stderr

    file = read_coefficients(panda["coef"])
    raw = raw_samples(load_data(panda["run"], load_config("panda")), file)
    assert raw.shape[1] == 2 * nj + file.n_outputs
    write_matrix(tmp_path / "short.mx", np.delete(raw[:300], np.s_[nj:2 * nj], axis=1))
    done = rt_eval("--coef", str(panda["coef"]), "--stream", str(tmp_path / "short.mx"), str(tmp_path / "out.mx"))
    assert done.returncode == 2 and "2·n_joints + n_outputs columns (q, the measured q̇, y)" in done.stderr


def test_the_monitor_refuses_a_bus_without_the_velocity(panda: dict[str, Path], tmp_path: Path) -> None:
    """A configuration whose bus carries no dq.J for a joint cannot feed the observer the file was calibrated for:
    refused at start-up with one line naming the joint, never run on the estimate."""
    text = panda["conf"].read_text()
    assert "dq.panda_joint3" in text
    conf = tmp_path / "no_velocity.conf"
    conf.write_text(re.sub(r"^signal .* dq\.panda_joint3$\n", "", text, flags=re.M))
    done = subprocess.run([str(BUILDS[0] / "rt_monitor" / "rt_monitor"), "--model", str(panda["coef"]), "--config",
                           str(conf), "--replay", "/dev/null", "--lcm-url", "memq://"], capture_output=True, text=True,
                          timeout=60)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "takes the robot's measured q̇" in lines[0] and "dq.panda_joint3" in lines[0], done.stderr
