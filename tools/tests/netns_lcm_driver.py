"""Run inside a private network namespace (test_lcm_udpm.py starts it with `ip netns exec`): set up multicast on
lo, subscribe with LCM's default URL (UDP multicast, ttl=0), run rt_monitor with that same default, and print
what arrived as JSON on stdout. SIGTERM is passed on to the monitor (tools/benchmarks/soak.py ends its paced run so).

Refuses (exit 3, before any socket is opened) unless it is in a network namespace other than HOST_NS whose only
interface is lo: nothing it sends can leave that namespace.

usage: netns_lcm_driver.py HOST_NS RT_MONITOR ARGS...
"""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def refuse(why: str) -> None:
    sys.stderr.write(f"netns_lcm_driver: refusing: {why}\n")
    sys.exit(3)


def main() -> None:
    host_ns, monitor = sys.argv[1], sys.argv[2:]
    here = os.readlink("/proc/self/ns/net")
    if here == host_ns:
        refuse(f"still in the host's network namespace ({here})")
    interfaces = sorted(os.listdir("/sys/class/net"))
    if interfaces != ["lo"]:
        refuse(f"interfaces other than lo in this namespace: {interfaces}")
    for cmd in (["ip", "link", "set", "lo", "up", "multicast", "on"], ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"]):
        subprocess.run(cmd, check=True)
    os.environ.pop("LCM_DEFAULT_URL", None)  # the default URL itself is what is tested

    import lcm

    types = {}
    gen = Path(__file__).resolve().parents[1] / "dynid" / "export" / "_lcmtypes"  # lcm-gen's, made by scripts/setup
    for name in ("contact_event_t", "monitor_status_t", "residual_t"):
        spec = importlib.util.spec_from_file_location(name, gen / f"{name}.py")
        assert spec and spec.loader
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        types[name] = getattr(mod, name)

    got: dict[str, list] = {"DYNID_CONTACT": [], "DYNID_STATUS": [], "DYNID_RESIDUAL": []}
    kinds = {"DYNID_CONTACT": "contact_event_t", "DYNID_STATUS": "monitor_status_t", "DYNID_RESIDUAL": "residual_t"}
    lc = lcm.LCM()
    for ch in got:
        lc.subscribe(ch, lambda c, data: got[c].append(types[kinds[c]].decode(data)))

    proc = subprocess.Popen(monitor, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={k: v for k, v in os.environ.items() if k != "LCM_DEFAULT_URL"})
    signal.signal(signal.SIGTERM, lambda *_: proc.send_signal(signal.SIGTERM))
    def handle(ms: int) -> int:
        try:
            return lc.handle_timeout(ms)
        except OSError:  # interrupted by the SIGTERM passed on
            return 0

    while proc.poll() is None:
        handle(50)
    quiet_since = time.monotonic()
    while time.monotonic() - quiet_since < 0.5:  # drain what is still queued
        if handle(100) > 0:
            quiet_since = time.monotonic()
    out, err = proc.communicate()
    last = got["DYNID_STATUS"][-1] if got["DYNID_STATUS"] else None
    json.dump({
        "netns": here, "interfaces": interfaces, "returncode": proc.returncode, "stdout": out, "stderr": err,
        "events": [[m.kind, m.utime] for m in got["DYNID_CONTACT"]],
        "statuses": len(got["DYNID_STATUS"]), "residuals": len(got["DYNID_RESIDUAL"]),
        "last_status": None if last is None else {k: getattr(last, k) for k in last.__slots__},
    }, sys.stdout)


if __name__ == "__main__":
    main()
