"""Event rules for the monitor's T², replayed on its own residual stream: how much of the onset delay is the rule.

    PYTHONPATH=tools python tools/benchmarks/event_rules.py --model out/model.dcoef --contact out/contact \
        --validation out/validation

The default contact and validation runs go through the real-time core sample by sample (`build/rt_monitor/rt_eval
--stream`, the acceleration residuals or, with --residual momentum, the observer), and each rule below turns the
per-sample T² into onsets as the monitor does (an onset once the rule fires; the episode ends after the file's
debounce_off samples below its hysteresis). A rule is a list of (level, n): fire when T² > level · T²_α for n samples
in a row, any of them; or a CUSUM (`cusum`), which fires at once on a large T² and later on a small persistent one.
The first rule is the monitor's own (T²_α for debounce_on samples): its row is the live mission's
(docs/detection.md#the-monitor). Beside them, the delays the contact alone would allow, noise- and lag-free
(dynid.detect.visibility, from the plant's truth), with no debounce and with the file's.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from dynid.config.robot_config import load_config
from dynid.detect.visibility import contact_residuals, episode_visibility
from dynid.export.coefficients import read_coefficients
from dynid.export.rt_eval_io import detector_columns, raw_samples, run_stream
from dynid.io.dataset import beside_run, contact_episodes
from dynid.io.load import load_data
from dynid.robot.model import RobotModel
from dynid.robot.regressors.stack import rows_at_rest

RT_EVAL = Path(__file__).resolve().parents[2] / "build" / "rt_monitor" / "rt_eval"
SLACK = 40  # samples after an episode's end in which an onset still counts as finding it (the summary's slack)
CUSUM_RULES = [(1.0, 40.0, 10.0), (1.5, 20.0, 3.0), (2.0, 10.0, 3.0), (2.0, 5.0, 5.0)]  # (drift, h, cap)


def t2_stream(coef_path: Path, data, residual: str, work: Path) -> tuple[np.ndarray, np.ndarray]:
    """(T² / T²_α, ready) per sample, from the core."""
    c = read_coefficients(coef_path)
    out = run_stream(RT_EVAL, coef_path, raw_samples(data, c), work, "--residual", residual)
    threshold = c.observer_threshold if residual == "momentum" else c.threshold
    return out[:, detector_columns(c)["t2"]] / threshold, out[:, 0] > 0


def onsets(stat: np.ndarray, ready: np.ndarray, rule: list[tuple[float, int]], off: int,
           hysteresis: float) -> list[int]:
    """The samples at which the monitor, firing on `rule`, would report an onset."""
    fire = np.zeros(stat.size, bool)
    for level, n in rule:
        above = ((stat > level) & ready).astype(int)
        fire |= np.convolve(above, np.ones(n, int))[:stat.size] >= n
    return episodes_of(stat, fire, off, hysteresis)


def cusum(stat: np.ndarray, ready: np.ndarray, drift: float, h: float, cap: float) -> np.ndarray:
    """Page's CUSUM on T²/T²_α: S = max(0, S + min(x, cap) − drift), firing at S ≥ h (S held at h, so an episode's
    evidence does not carry past its end). A large T² fires at once, a small one must persist."""
    fire, s = np.zeros(stat.size, bool), 0.0
    for k in range(stat.size):
        s = min(h, max(0.0, s + min(float(stat[k]), cap) - drift)) if ready[k] else 0.0
        fire[k] = s >= h
    return fire


def episodes_of(stat: np.ndarray, fire: np.ndarray, off: int, hysteresis: float) -> list[int]:
    """Onsets where `fire` starts an episode; an episode ends after `off` samples below the hysteresis level."""
    out, inside, below = [], False, 0
    for k in range(stat.size):
        if not inside and fire[k]:
            out.append(k)
            inside, below = True, 0
        elif inside:
            below = below + 1 if stat[k] < hysteresis else 0
            inside = below < off
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", type=Path, required=True, help="the coefficient file (dynid export)")
    ap.add_argument("--contact", type=Path, required=True, help="the simulated contact run (with truth.npz)")
    ap.add_argument("--validation", type=Path, required=True, help="a contact-free run")
    ap.add_argument("--residual", choices=["acceleration", "momentum"], default="acceleration")
    a = ap.parse_args()
    c = read_coefficients(a.model)
    config = load_config(c.robot_name)
    contact, free = load_data(str(a.contact), config), load_data(str(a.validation), config)
    episodes = contact_episodes(np.asarray(contact.contact) != 0)
    ms = 1e3 * float(c.sample_period)  # one sample, in ms
    rules = [[(1.0, int(c.debounce_on))], [(1.0, 5)], [(1.0, 3)], [(1.0, int(c.debounce_on)), (9.0, 1)],
             [(1.0, int(c.debounce_on)), (4.0, 2)], [(1.0, int(c.debounce_on)), (2.0, 5)]]
    with tempfile.TemporaryDirectory() as tmp:
        sc, rc = t2_stream(a.model, contact, a.residual, Path(tmp))
        sv, rv = t2_stream(a.model, free, a.residual, Path(tmp))
    print("| rule: T² above level · T²_α for n samples | episodes found | onset delay median / p90 | "
          "false onsets, contact run / contact-free run |")
    print("|---|---|---|---|")
    off, hysteresis = int(c.debounce_off), float(c.hysteresis)
    rows = [(" or ".join(f"{lv:g}·T²_α × {n}" for lv, n in rule), onsets(sc, rc, rule, off, hysteresis),
             onsets(sv, rv, rule, off, hysteresis)) for rule in rules]
    rows += [(f"CUSUM of min(T²/T²_α, {cap:g}) − {drift:g} ≥ {h:g}",
              episodes_of(sc, cusum(sc, rc, drift, h, cap), off, hysteresis),
              episodes_of(sv, cusum(sv, rv, drift, h, cap), off, hysteresis)) for drift, h, cap in CUSUM_RULES]
    for text, on, free_on in rows:
        delays = [ms * (next(k for k in on if a0 <= k <= e + SLACK) - a0) for a0, e in episodes
                  if any(a0 <= k <= e + SLACK for k in on)]
        false = sum(1 for k in on if not any(a0 <= k <= e + SLACK for a0, e in episodes))
        print(f"| {text} | {len(delays)}/{len(episodes)} | {np.median(delays):.0f} / {np.percentile(delays, 90):.0f} "
              f"ms | {false} / {len(free_on)} |")
    truth = beside_run(str(a.contact), "truth.npz")
    if a.residual == "acceleration" and truth.is_file():
        model = RobotModel(config)
        t = dict(np.load(truth))
        signal = contact_residuals(model, np.asarray(c.divisor, float), t)
        active = ~rows_at_rest(model, np.asarray(t["dq"], float), float(c.min_speed))
        for debounce in (1, int(c.debounce_on)):
            seen = episode_visibility(np.asarray(t["contact"]), signal, active, np.asarray(c.residual_variance, float),
                                      float(c.threshold), debounce)
            bound = [ms * v.earliest for v in seen if v.earliest >= 0]
            print(f"the contact alone, noise- and lag-free, debounce {debounce}: {len(bound)} episodes, onset median "
                  f"{np.median(bound):.0f} ms, p90 {np.percentile(bound, 90):.0f} ms")


if __name__ == "__main__":
    main()
