"""The rt_monitor configuration file (docs/formats.md, "rt_monitor configuration") written from a robot configuration:
the monitor's settings and its bus description compiled into a table of lines the C++ side reads without a DBC
parser or any robot-specific code (firmware_like's `boards` plays runs from the same lines):

    frame NAME BUS ID DLC LONG_DLC NODE PERIOD_US OFFSET_US
    signal FRAME START LENGTH le|be u|s|f SCALE OFFSET TARGET      (TARGET '-': carried, read by nobody)
    clock FRAME
    pair FIRST SECOND
    patch NAME [SENSOR:distal|proximal ...]

Numbers are written so that they read back exactly (repr of a double, IDs in hex). Before anything is written, the
description is checked against the monitor's capacity (dynid.export.capacity, from rt_monitor's capacity.hpp).
"""

from __future__ import annotations

from ..config.bus import BusDescription
from ..config.robot_config import RobotConfig, robot_argument
from ..errors import ConfigError, InputError
from .capacity import capacity

HEADER = "# rt_monitor configuration for {name} (written by dynid from its robot configuration: dynid export " \
         "--robot {robot} --monitor-config FILE)"


def check_capacity(config: RobotConfig) -> BusDescription:
    """The configuration's bus, if the monitor can hold it; else ConfigError, one line naming the capacity."""
    bus = config.bus
    if bus is None:
        raise ConfigError(f"robot configuration {config.name} describes no CAN bus (a 'bus' or 'can' section): "
                          "the monitor has no frames to read")
    cap = capacity()
    sensors = {s.target.split(".")[1] for f in bus.frames for s in f.signals if s.target.startswith("ft.")}
    for what, n, limit, name in (
        ("buses", len(bus.buses), cap.buses, "kMaxBuses"),
        ("frames", len(bus.frames), cap.frames, "kMaxFrames"),
        ("signals", sum(len(f.signals) for f in bus.frames), cap.signals, "kMaxSignals"),
        ("skin patches", len(bus.patches), cap.skins, "kMaxSkins"),
        ("F/T sensors", len(sensors), cap.sensors, "kMaxSensors"),
        ("joints", len(config.joints), cap.joints, "kMaxJoints"),
    ):
        if n > limit:
            raise ConfigError(f"robot configuration {config.name}: its bus has {n} {what}, the monitor holds at most "
                              f"{limit} ({name} in rt_monitor/include/rt_monitor/capacity.hpp)")
    return bus


def url_for_writing(url: str) -> str | None:
    """The LCM URL `url` should be for the monitor to write to it, or None if it is fine: LCM opens a file:// URL for
    reading unless its query says mode=w or mode=a (the last mode= wins, as in liblcm), and the monitor only
    publishes. rt_monitor refuses by the same rule (its file_url_for_writing; tools/tests/test_bus.py runs both)."""
    if not url.startswith("file://"):
        return None
    if "?" not in url:
        return url + "?mode=w"
    head, query = url.split("?", 1)
    pairs = query.split("&")
    last = max((i for i, pair in enumerate(pairs) if pair.startswith("mode=")), default=None)
    if last is None:
        return url + ("&" if query else "") + "mode=w"
    if pairs[last] in ("mode=w", "mode=a"):
        return None
    pairs[last] = "mode=w"
    return head + "?" + "&".join(pairs)


LCM_PROVIDERS = ("udpm", "mpudpm", "file", "memq", "tcpq")  # liblcm 1.5's


def _number(text: str) -> int | None:
    """A URL field of 1-5 ASCII digits as an int, else None (rt_monitor's `digits`)."""
    return int(text) if 1 <= len(text) <= 5 and all("0" <= c <= "9" for c in text) else None


def lcm_url_problem(url: str) -> str:
    """Why liblcm could not open `url` as the monitor's LCM, or "" (an empty URL: LCM's default): a provider liblcm
    lacks, a UDP multicast group outside 224.0.0.0/4, a port or ttl out of range. rt_monitor refuses by the same
    rule (its lcm_url_problem, rt_monitor/tools/lcm_url.cpp; tools/tests/test_bus.py runs both), before anything is opened."""
    if not url:
        return ""
    provider, sep, rest = url.partition("://")
    if not sep or provider not in LCM_PROVIDERS:
        return f"no LCM provider '{provider if sep else url}' (liblcm has {', '.join(LCM_PROVIDERS)}: PROVIDER://...)"
    if provider == "file" and not rest.split("?", 1)[0]:
        return "a file:// URL names its log: file:///PATH?mode=w"
    if provider not in ("udpm", "mpudpm"):
        return ""
    network, _, query = rest.partition("?")
    if network:
        address, colon, port = network.partition(":")
        parts = [_number(p) for p in address.split(".")]
        if not (len(parts) == 4 and all(p is not None and p <= 255 for p in parts) and 224 <= parts[0] <= 239):
            return f"'{address}' is not a UDP multicast group (224.0.0.0-239.255.255.255)"
        if colon and not 1 <= (_number(port) or 0) <= 65535:
            return f"port '{port}' is not 1-65535"
    for pair in query.split("&") if query else ():
        key, _, value = pair.partition("=")
        if key == "ttl" and not ((ttl := _number(value)) is not None and ttl <= 255):
            return f"ttl '{value}' is not 0-255"
    return ""


def fits_a_configuration(token: str) -> bool:
    """Whether `token` can be one value of the monitor's configuration: the file is whitespace-separated tokens with
    # comments, so a URL holding whitespace, '#' or a control character would be read as something else."""
    return not any(c.isspace() or c == "#" or not c.isprintable() for c in token)


def monitor_config_text(config: RobotConfig, lcm_url: str | None = None) -> str:
    """The rt_monitor configuration (docs/formats.md, "rt_monitor configuration") for a robot configuration."""
    if lcm_url and (why := lcm_url_problem(lcm_url)):
        raise InputError(f"--lcm-url {lcm_url}: {why}")
    if lcm_url and not fits_a_configuration(lcm_url):
        raise InputError(f"--lcm-url {lcm_url!r}: a URL in the monitor's configuration cannot hold whitespace, '#' or "
                         "control characters (percent-encode them, or give the monitor --lcm-url)")
    if lcm_url and (fixed := url_for_writing(lcm_url)):
        raise InputError(f"--lcm-url {lcm_url} opens its file for reading (LCM's default without mode=w or mode=a), "
                         f"and the monitor writes: {fixed}")
    bus = check_capacity(config)
    lines = [HEADER.format(name=config.name, robot=robot_argument(config)), f"robot {config.name}", "buses " + " ".join(bus.buses)]
    if lcm_url:
        lines.append(f"lcm_url {lcm_url}")
    lines += [f"stale_ms {bus.stale_ms:g}", f"pair_us {bus.pair_us}", "status_hz 10", "residual_every 10",
              f"contact_limit_s {config.contact_limit_s:g}"]  # the configuration's `monitor: {contact_limit_s}`
    for f in bus.frames:
        period = 0 if f.period_ms is None else round(f.period_ms * 1000)
        lines.append(f"frame {f.name} {f.bus} 0x{f.id:03X} {f.dlc} {f.long_dlc} {f.node} {period} {f.offset_us}")
        for s in f.signals:
            lines.append(f"signal {f.name} {s.start} {s.length} {'le' if s.byte_order == 'little' else 'be'} "
                         f"{s.type[0]} {float(s.scale)!r} {float(s.offset)!r} {s.target or '-'}")
    lines.append(f"clock {bus.clock}")
    lines += [f"pair {a} {b}" for a, b in bus.pairs]
    for p in bus.patches:
        lines.append(" ".join(["patch", p.name] + [f"{sensor}:{side}" for sensor, side in p.sides]))
    return "\n".join(lines) + "\n"
