"""The `yarp:` field of a robot configuration: which ports of a `yarpdatadumper` folder hold which channels.

A YARP robot logs one folder per port (`icub/right_leg/stateExt:o/data.log`), each with its own clock. The field
names the ports to read and what each holds:

```yaml
yarp:
  rate: 100            # Hz: the common time base the ports are interpolated onto (default: 100)
  max_gap: 0.1         # s: a longer silence of a port inside the run is refused (default: 0.1)
  max_skew: 2.0        # s: how far the ports' first (and last) stamps may differ, the dumpers started and stopped one
                       #    after another; a port that starts later or ends sooner cuts the run short (default: 2)
  ports:
    - {port: icub/right_leg/stateExt:o, joints: [r_hip_pitch, ..., r_ankle_roll]}   # "_" skips a port's joint
    - {port: icub/right_leg/analog:o, sensor: r_leg_ft}
```

A port with `joints` is a `stateExt:o` port: its first group holds the joint positions, in the port's joint
order, in `unit` (default `deg`, YARP's). A port with `sensor` is an F/T sensor's `analog:o` port: six values,
forces in `force_unit` (default `N`) and torques in `torque_unit` (default `Nm`), in the sensor frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError
from .log_columns import SKIP, UNITS


@dataclass(frozen=True)
class YarpPort:
    port: str  # the folder under the dumper's root, e.g. "icub/right_leg/stateExt:o"
    joints: tuple[str, ...] = ()  # a stateExt port: configured joint per slot, "_" for skipped slots
    sensor: str = ""  # an analog:o port: the F/T sensor it carries
    scale: tuple[float, ...] = ()  # per value of the port: file unit -> project unit


@dataclass(frozen=True)
class YarpLayout:
    ports: tuple[YarpPort, ...]
    rate: float = 100.0  # Hz
    max_gap: float = 0.1  # s
    max_skew: float = 2.0  # s


def parse_yarp(robot: str, value: Any, joints: tuple[str, ...], sensors: tuple[str, ...]) -> YarpLayout | None:
    """Validate the `yarp:` field; every problem is a `ConfigError` naming the entry."""
    if value is None:
        return None
    where = f"{robot}: field 'yarp'"

    def fld(key: str) -> str:
        return f"{robot}: field 'yarp.{key}'"

    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a mapping with 'ports' (and optionally 'rate', 'max_gap', 'max_skew')")
    unknown = sorted(set(value) - {"ports", "rate", "max_gap", "max_skew"})
    if unknown:
        raise ConfigError(f"{where} has an unknown key '{unknown[0]}' (known: ports, rate, max_gap, max_skew)")
    rate = _number(value.get("rate", 100.0), fld("rate"), 1.0, 100000.0)
    max_gap = _number(value.get("max_gap", 0.1), fld("max_gap"), 1e-4, 60.0)
    if max_gap < 1.0 / rate:
        raise ConfigError(f"{fld('max_gap')} ({max_gap:g} s) must be at least one period of 'rate' ({1 / rate:g} s)")
    max_skew = _number(value.get("max_skew", 2.0), fld("max_skew"), 0.0, 3600.0)
    ports_raw = value.get("ports")
    if not isinstance(ports_raw, list) or not ports_raw:
        raise ConfigError(f"{fld('ports')} must be a list of ports, each with 'port' and 'joints' or 'sensor'")
    ports: list[YarpPort] = []
    covered_joints: dict[str, str] = {}
    covered_sensors: dict[str, str] = {}
    for i, entry in enumerate(ports_raw):
        at = fld(f"ports[{i}]")

        def key(name: str, i: int = i) -> str:
            return fld(f"ports[{i}].{name}")

        if not isinstance(entry, dict):
            raise ConfigError(f"{at} must be a mapping with 'port' and 'joints' or 'sensor', got {entry!r}")
        port = entry.get("port")
        if not isinstance(port, str) or not port.strip() or ".." in port.split("/") or port.startswith("/"):
            raise ConfigError(f"{key('port')} must be the port's folder under the dumper's root (e.g. icub/right_leg/stateExt:o)")
        if ("joints" in entry) == ("sensor" in entry):
            raise ConfigError(f"{at} must give either 'joints' (a stateExt:o port) or 'sensor' (an analog:o port)")
        if "joints" in entry:
            allowed = {"port", "joints", "unit"}
            listed = entry["joints"]
            if not isinstance(listed, list) or not listed or not all(isinstance(j, str) for j in listed):
                raise ConfigError(f"{key('joints')} must list the port's joints in its order ('_' skips one)")
            for j in listed:
                if j == SKIP:
                    continue
                if j not in joints:
                    raise ConfigError(f"{key('joints')} names '{j}', which is not in the configuration's 'joints'")
                if j in covered_joints:
                    raise ConfigError(f"{key('joints')} names '{j}', which {covered_joints[j]} already gives")
                covered_joints[j] = port
            unit = entry.get("unit", "deg")
            if unit not in UNITS["q"]:
                raise ConfigError(f"{key('unit')} must be one of {', '.join(UNITS['q'])}, got {unit!r}")
            scale = (UNITS["q"][unit],) * len(listed)
            ports.append(YarpPort(port.strip(), joints=tuple(listed), scale=scale))
        else:
            allowed = {"port", "sensor", "force_unit", "torque_unit"}
            sensor = entry["sensor"]
            if sensor not in sensors:
                raise ConfigError(f"{key('sensor')} names {sensor!r}, which is not in the configuration's 'ft_sensors'")
            if sensor in covered_sensors:
                raise ConfigError(f"{key('sensor')} names '{sensor}', which {covered_sensors[sensor]} already gives")
            covered_sensors[sensor] = port
            fu, tu = entry.get("force_unit", "N"), entry.get("torque_unit", "Nm")
            if fu not in UNITS["ft_force"] or tu not in UNITS["ft_torque"]:
                raise ConfigError(
                    f"{at}: force_unit must be one of {', '.join(UNITS['ft_force'])} and torque_unit one of "
                    f"{', '.join(UNITS['ft_torque'])}, got {fu!r}, {tu!r}"
                )
            scale = (UNITS["ft_force"][fu],) * 3 + (UNITS["ft_torque"][tu],) * 3
            ports.append(YarpPort(port.strip(), sensor=sensor, scale=scale))
        extra = sorted(set(entry) - allowed)
        if extra:
            raise ConfigError(f"{at} has an unknown key '{extra[0]}' (known: {', '.join(sorted(allowed))})")
    missing = [j for j in joints if j not in covered_joints]
    if missing:
        raise ConfigError(f"{fld('ports')} gives no port for the joint '{missing[0]}'")
    return YarpLayout(tuple(ports), rate, max_gap, max_skew)


def _number(value: Any, where: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not lo <= value <= hi:
        raise ConfigError(f"{where} must be a number from {lo:g} to {hi:g}, got {value!r}")
    return float(value)
