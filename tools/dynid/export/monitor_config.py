"""The rt_monitor configuration file (rt_monitor/README.md, "Configuration") written from a robot configuration."""

from __future__ import annotations

from ..config.robot_config import RobotConfig
from ..errors import DataError


def monitor_config_text(config: RobotConfig, lcm_url: str | None = None) -> str:
    """The rt_monitor configuration (rt_monitor/README.md, "Configuration") for a robot configuration."""
    can = config.can
    if not can or len(can.get("strain", [])) != 1:
        raise DataError(f"robot configuration {config.name}: rt_monitor needs a 'can' mapping with one strain board")
    lines = [f"# rt_monitor configuration for {config.name} (written by dynid from its robot configuration)",
             f"robot {config.name}", "buses " + " ".join(can["buses"])]
    if lcm_url:
        lines.append(f"lcm_url {lcm_url}")
    lines += ["stale_ms 5", "pair_us 500", "status_hz 10", "residual_every 10"]
    s = can["strain"][0]
    lines.append(f"strain {s['bus']} {s['address']} " + " ".join(repr(float(x)) for x in s["full_scale"]))
    for b in can["motor_control"]:
        for slot, ax in enumerate(b["axes"]):
            lines.append(f"axis {b['bus']} {b['address']} {slot} {ax['joint']} {float(ax['ticks_per_degree'])!r} "
                         f"{float(ax.get('zero_deg', 0.0))!r}")
            if ax.get("motor"):
                lines.append(f"pwm {b['bus']} {b['address']} {slot} {ax['motor']} {float(b['pwm_full_scale'])!r}")
    for k in can.get("skin", []):
        lines.append(f"skin {k['bus']} {k['address']} {k['patch']} {k['side']}")
    return "\n".join(lines) + "\n"
