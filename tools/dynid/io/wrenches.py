"""F/T wrenches against the robot that measured them: a channel in another unit refused at load.

Nothing else checks an F/T sensor's magnitudes: torques in N·mm (×1000) used to fit with exit 0, leaving a centre of
mass 87.8 m away and a residual 1659 times the noise. Two statistics of the run see a wrong unit, neither thrown by
the sensor's large constant offsets (each channel is taken about its median):

- the **lever arm** ‖τ − τ̃‖ / ‖F − f̃‖ (RMS over the run, m): what loads the sensor (the distal chain's weight and
  inertia, a contact on it) acts on the chain beyond the sensor, so torque over force is a distance within that
  chain's reach. Measured: 0.015–0.088 m, 0.11–0.30 of the reach (iCub leg and foot sensors, TIAGo wrist, the
  simulated iCub arm's three kinds); torques ×1000: 15–88 m, 115–300 reaches; force and torque columns swapped:
  11–68 m. Refused beyond `LEVER_FACTOR` reaches + `LEVER_MARGIN_M` (1.5–3.9 m there), and under `LEVER_FLOOR`
  reaches (torques ÷1000, N·m declared N·mm: 0.00011–0.0003 reaches, a model that fits them looks excellent).
- the **force swing** (99th percentile of ‖F − f̃‖, N) against the whole robot's weight: measured 0.01–0.52 weights
  (the iCub foot sensor carries the standing robot's swing), 11.5–518 with forces ×1000. Refused beyond
  `FORCE_WEIGHTS` weights.

The reach is the longest path of joint origins (and links' centres of mass) below the sensor in the URDF: no point of
the distal chain gets farther from the sensor in any configuration. The cases: tools/tests/test_fail_loud.py (the
simulated arm), tests/realdata/test_realdata_import.py (the real sensors).
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError
from .dataset import Dataset

LEVER_FACTOR = 5.0  # reaches: a payload or tool beyond the URDF's chain, inertial torques of a fast move
LEVER_MARGIN_M = 1.0  # m: the floor for a sensor with little or nothing modelled beyond it
LEVER_FLOOR = 0.01  # reaches: the least lever (measured 0.11 and up; torques ÷1000 give 0.0003 and less)
FORCE_WEIGHTS = 5.0  # the robot's weights: a humanoid's foot at a landing, an arm pushing on its surroundings
GRAVITY = 9.81


def _xyz(element: ET.Element | None) -> np.ndarray:
    origin = element.find("origin") if element is not None else None
    return np.array([float(v) for v in origin.get("xyz", "0 0 0").split()] if origin is not None else [0.0] * 3)


def _link(joint: ET.Element, end: str) -> str:
    return str(joint.find(end).get("link"))  # type: ignore[union-attr] - a joint without it: AttributeError, caught


@functools.lru_cache(maxsize=16)
def _geometry(urdf: str, mtime_ns: int, joints: tuple[str, ...]) -> tuple[dict[str, float], float] | None:
    """(each fixed joint of `joints` -> the reach of the chain beyond it, m; the URDF's total mass, kg), or None for a
    URDF this cannot read (the robot model names what is wrong with it)."""
    try:
        root = ET.parse(urdf).getroot()
        links = {link.get("name"): link for link in root.findall("link")}
        by_name = {j.get("name"): j for j in root.findall("joint")}
        below: dict[str, list[ET.Element]] = {}
        for j in by_name.values():
            below.setdefault(_link(j, "parent"), []).append(j)
        mass = sum(float(m.get("value", 0)) for m in root.findall("link/inertial/mass"))
        reach: dict[str, float] = {}
        for name in joints:
            far, stack, seen = 0.0, [(_link(by_name[name], "child"), 0.0)], set()
            while stack:  # every link below the sensor, at the length of its path of joint origins
                link, length = stack.pop()
                if link in seen:
                    continue
                seen.add(link)
                far = max(far, length + float(np.linalg.norm(_xyz(links[link].find("inertial")))))
                stack += [(_link(j, "child"), length + float(np.linalg.norm(_xyz(j)))) for j in below.get(link, [])]
            reach[name] = far
        return reach, mass
    except (ET.ParseError, OSError, KeyError, AttributeError, ValueError, IndexError):
        return None


def check_wrenches(dataset: Dataset, config: RobotConfig, where: str = "", headerless: bool = False) -> None:
    """Refuse an F/T sensor whose torques over forces are longer than the robot (torques in N·mm, forces in kN, the
    two swapped) or whose forces swing by more than the robot's weight can explain (forces in mN)."""
    sensors = [s for s in config.ft_sensors if s.name in dataset.ft]
    urdf = Path(config.urdf) if str(config.urdf) else None
    if not sensors or urdf is None or not urdf.is_file():
        return
    geometry = _geometry(str(urdf), urdf.stat().st_mtime_ns, tuple(s.joint for s in sensors))
    if geometry is None:
        return
    reach, mass = geometry
    declare = (" (a headerless log declares its units in the configuration's 'columns:' field, e.g. \"ft.S.tx Nmm\")"
               if headerless else "")
    for s in sensors:
        w = dataset.ft[s.name]
        w = w[np.all(np.isfinite(w), axis=1)]
        if w.shape[0] < 2:
            continue
        swing = w - np.median(w, axis=0)  # about the medians: the offsets, however large, drop out
        force, torque = np.linalg.norm(swing[:, :3], axis=1), np.linalg.norm(swing[:, 3:], axis=1)
        weight = mass * GRAVITY
        peak = float(np.percentile(force, 99))
        if weight > 0 and peak > FORCE_WEIGHTS * weight:
            raise DataError(
                f"{where}ft.{s.name}'s forces swing by {peak:.4g} N (99th percentile about their medians), "
                f"{peak / weight:.3g} times the weight of the whole robot ({mass:.3g} kg in its URDF), which no load "
                f"of the robot explains: forces in mN? (N expected; or is a payload missing from the URDF?){declare}")
        rms_force = float(np.sqrt(np.mean(force**2)))
        if not rms_force > 0:
            continue  # forces that never move: no lever to measure
        lever = float(np.sqrt(np.mean(torque**2))) / rms_force
        limit = LEVER_FACTOR * reach[s.joint] + LEVER_MARGIN_M
        if lever > limit:
            raise DataError(
                f"{where}ft.{s.name}'s torques are {lever:.3g} m times its forces (RMS about their medians: a lever "
                f"arm), beyond the {limit:.3g} m allowed where the chain beyond the sensor reaches "
                f"{reach[s.joint]:.3g} m: torques in N·mm, or forces in kN? (N·m and N expected; or are the force "
                f"and torque columns swapped, or is a tool beyond the sensor missing from the URDF?){declare}")
        floor = LEVER_FLOOR * reach[s.joint]
        if lever < floor:
            raise DataError(
                f"{where}ft.{s.name}'s torques are only {lever:.3g} m times its forces (RMS about their medians: a "
                f"lever arm), under the {floor:.3g} m that a chain reaching {reach[s.joint]:.3g} m beyond the sensor "
                f"gives at the least: torques in N·m declared N·mm, or forces in N declared kN? (N·m and N expected)"
                f"{declare}")
