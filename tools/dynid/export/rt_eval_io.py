"""The monitor's offline evaluator, `rt_eval --stream`, from Python: its matrix files and its output columns.

`rt_eval --stream IN OUT` runs the real-time core sample by sample on IN and writes one row per sample to OUT (the
layout: rt_monitor/tools/rt_eval.cpp). Both are DYMX files: b"DYMX", rows and columns as little-endian int64, then
the rows as little-endian float64. The tests, the RT report and the event-rule replay read and write them here.
"""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import numpy as np

from .lcm_coefficients import coefficients_t

MAGIC = b"DYMX"


def write_matrix(path: Path, x: np.ndarray) -> None:
    x = np.ascontiguousarray(x, dtype="<f8")
    path.write_bytes(MAGIC + struct.pack("<qq", *x.shape) + x.tobytes())


def read_matrix(path: Path) -> np.ndarray:
    data = path.read_bytes()
    if data[:4] != MAGIC:
        raise ValueError(f"{path}: not a DYMX matrix")
    rows, cols = struct.unpack_from("<qq", data, 4)
    return np.frombuffer(data, "<f8", offset=20).reshape(rows, cols)


def raw_samples(ds, c: coefficients_t) -> np.ndarray:
    """(N, joints [+ joints] + outputs): what the monitor receives per sample, in the coefficient file's joint and
    channel order (channels by name: `ft.<sensor>.<fx…tz>`, `pwm.<motor>`, `current.<motor>`, `tau.<joint>`); where
    the file's observer takes the robot's measured q̇ (`observer_velocity` 1), that q̇ after q."""
    from ..detect.momentum import robot_velocity

    columns = dict(ds.columns())
    missing = [n for n in c.channel_names if n not in columns]
    if missing:
        raise KeyError(f"the data have no column {missing[0]} for the coefficient file's channel")
    velocity = []
    if c.observer_velocity == 1:
        dq = robot_velocity(c.joint_names, ds)
        if dq is None:
            raise KeyError("the data carry no measured joint velocity, which the coefficient file's observer takes")
        velocity = [dq]
    return np.column_stack([ds.q] + velocity + [columns[n] for n in c.channel_names])


def detector_columns(c: coefficients_t) -> dict[str, int | slice]:
    """Where `rt_eval --stream` writes T², each sensor's share, the detector's state and each sensor's side; then r
    (`n_outputs`), τ_ext (`n_joints`) and the isolated joint."""
    ns = c.n_sensors
    at = 1 + 3 * c.n_joints + 3 * c.n_outputs
    state = at + 1 + ns
    return {"t2": at, "t2_sensor": slice(at + 1, at + 1 + ns), "above": state, "in_contact": state + 1,
            "event": state + 2, "side": slice(state + 3, state + 3 + ns), "r": state + 3 + ns,
            "tau_ext": state + 3 + ns + c.n_outputs, "joint": state + 3 + ns + c.n_outputs + c.n_joints}


def run_stream(exe: Path, coef: Path, raw: np.ndarray, work: Path, *options: str) -> np.ndarray:
    """The core's per-sample output rows for the raw samples `raw` (`exe --coef COEF OPTIONS --stream`)."""
    write_matrix(work / "in.mx", raw)
    done = subprocess.run([str(exe), "--coef", str(coef), *options, "--stream", str(work / "in.mx"),
                           str(work / "out.mx")], capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise RuntimeError(f"rt_eval: {done.stderr.strip()}")
    return read_matrix(work / "out.mx")
