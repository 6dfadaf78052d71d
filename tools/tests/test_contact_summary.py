"""dynid.export.monitor_log on tiny hand-made cases: the figures scripts/main prints at the end of the mission."""

from __future__ import annotations

import numpy as np
import pytest

from dynid.export.monitor_log import episodes, format_summary, summarize


def test_episodes_are_the_nonzero_runs() -> None:
    assert episodes(np.array([0, 1, 1, 0, 0, 2, 0, 1])) == [(1, 3), (5, 6), (7, 8)]
    assert episodes(np.zeros(4)) == []


def test_tpr_fpr_delay_found_and_false_onsets() -> None:
    # 40 samples: contact on [5, 15) and [25, 30). The monitor: onset at 8, end at 17 (the first episode,
    # 3 samples late), an onset at 20 ended at 22 (contact-free: false), nothing for the second episode.
    contact = np.zeros(40, int)
    contact[5:15] = 1
    contact[25:30] = 1
    events = [(1, 8), (2, 17), (1, 20), (2, 22)]
    side = np.where(np.arange(40) < 20, 1.0, -1.0) * contact
    s = summarize(contact, events, period_s=0.001, slack=3, side=side)
    assert s["episodes_by_side"] == {"distal": {"found": 1, "episodes": 1}, "proximal": {"found": 0, "episodes": 1}}
    assert (s["episodes"], s["episodes_found"], s["onsets"], s["false_onsets"]) == (2, 1, 2, 1)
    # in contact on 8..16 and 20..21: 7 of the 15 contact samples (8..14), 4 of the 25 free ones (15, 16, 20, 21)
    assert s["tpr"] == 7 / 15 and s["fpr"] == 4 / 25
    assert np.isclose(s["delay_median_s"], 0.003)
    text = format_summary(s)
    assert "1 of 2 contact episodes found, 1 false onsets, distal 1 of 1, proximal 0 of 1" in text
    assert "46.7 % of contact samples, 16.00 % of contact-free ones" in text and "T²" not in text


def test_an_onset_within_the_slack_after_the_end_counts_and_an_open_onset_runs_to_the_end() -> None:
    contact = np.zeros(20, int)
    contact[2:4] = 1
    s = summarize(contact, [(1, 6)], period_s=0.001, slack=2)  # two samples after the end: found, never closed
    assert (s["episodes_found"], s["false_onsets"]) == (1, 0)
    assert s["tpr"] == 0.0 and s["fpr"] == 14 / 18
    s = summarize(contact, [(1, 7)], period_s=0.001, slack=2)
    assert (s["episodes_found"], s["false_onsets"]) == (0, 1)


def test_t2_rates_from_the_residual_stream() -> None:
    contact = np.zeros(100, int)
    contact[20:60] = 1
    # every 10th sample: alarms at 30, 40, 50 (contact) and 80 (free); 20 is in contact but below the threshold
    t2 = [(k, 50.0 if k in (30, 40, 50, 80) else 1.0, 10.0) for k in range(0, 100, 10)]
    s = summarize(contact, [], 0.001, 5, t2)
    assert s["t2_tpr"] == 3 / 4 and s["t2_fpr"] == 1 / 6 and s["t2_samples"] == 10
    assert "T² > T²_α per sample (every 10th, no debounce): TPR 75.0 %, FPR 16.67 %" in format_summary(s)


def test_visible_episodes_missed_are_named() -> None:
    # Three episodes; the monitor finds the first; the second is visible (the contact alone reaches T²_α) and
    # missed, the third is not visible and missed.
    contact = np.zeros(60, int)
    contact[5:10] = contact[20:30] = contact[40:50] = 1
    s = summarize(contact, [(1, 7), (2, 12)], 0.001, 2, visible=[True, True, False])
    assert (s["episodes_found"], s["episodes_visible"], s["visible_missed_at"]) == (1, 2, [20])
    assert "visible to the monitor (plant truth): 2, 1 of them found" in format_summary(s)
    # the delays the contact alone allows (noise-free, lag-free): over the episodes it makes visible
    s = summarize(contact, [(1, 7), (2, 12)], 0.001, 2, visible=[True, True, False], earliest=[1, 3, -1])
    assert (s["delay_bound_median_s"], s["delay_bound_p90_s"]) == pytest.approx((0.002, 0.0028))
    assert "the contact alone, without noise or filter lag: median 2 ms, p90 3 ms" in format_summary(s)


def test_monitor_counters_from_the_last_status() -> None:
    from dynid.export.lcm_messages import monitor_status_t
    from dynid.export.monitor_log import monitor_counters

    m = monitor_status_t()
    m.frames, m.samples, m.stale_samples, m.interpolated, m.late, m.filter_restarts = 1400, 100, 2, 3, 92, 1
    m.n_supply, m.supply_ratio = 2, [1.01234, 0.98]
    got = monitor_counters(monitor_status_t.decode(m.encode()))  # as read from a log
    assert got == {"frames": 1400, "samples": 100, "stale_samples": 2, "interpolated": 3, "late": 92,
                   "filter_restarts": 1, "supply_ratio": [1.01234, 0.98]}
    s = summarize(np.zeros(10, int), [], 0.001, 3)
    s["monitor"] = got
    assert format_summary(s).endswith("\n  monitor's last status: frames 1400, samples 100, stale samples 2, "
                                      "interpolated 3, late 92, filter restarts 1; supply ratios 1.0123 0.9800")
