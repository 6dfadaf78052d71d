"""The lines `dynid detect` prints about its alarms: how many stretches above the level, and the same alarms as the
exported monitor's debounce and hysteresis make contact events of them (`monitor_events`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..detect.momentum_t2 import alarm_runs
from ..detect.t2 import debounced_events
from .common import plural


def stretches(t: np.ndarray, statistic: np.ndarray, events: list | None) -> str:
    """'N stretches above its threshold' of a normalised statistic (a contact above 1; dynid.detect.momentum_t2
    .alarm_runs), and with `events` (they are --json's) how many of them those describe (contact_events' limit)."""
    n = len(alarm_runs(t, statistic)[0])
    said = f"{plural(n, 'stretch', 'stretches')} above its threshold"
    if events is None:
        return said
    return said + (f" (--json's events: the first {len(events)})" if n > len(events) else " (--json's events)")


def monitor_events(t: np.ndarray, combined, momentum, found) -> dict[str, Any] | None:
    """The default detector's alarms as the exported monitor's defaults debounce them into contact events (the same
    counts and level: dynid.detect.t2.debounced_events), for a lab to set beside the monitor's events."""
    from ..export.coefficients import EventSettings

    if combined is not None:
        variant, statistic, level = "combined", combined.statistic, 1.0  # s: the sum over κ, a contact above 1
    elif momentum is not None:
        variant, statistic, level = "momentum", momentum.statistic, 1.0
    elif "calibrated" in found.t2:
        variant, statistic, level = "calibrated", found.t2["calibrated"], found.detectors["calibrated"].threshold
    else:
        return None
    if t.size < 2:
        return None
    settings = EventSettings().at(float(np.median(np.diff(t))))
    events = debounced_events(statistic, level, settings.debounce_on, settings.debounce_off, settings.hysteresis)
    return {"residual": variant, "debounce_on": settings.debounce_on, "debounce_off": settings.debounce_off,
            "hysteresis": settings.hysteresis, "onsets_s": [float(t[k]) for k, _ in events],
            "ends_s": [None if j is None else float(t[j]) for _, j in events]}
