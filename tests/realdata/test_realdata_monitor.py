"""Real runs through the monitor, matched offline (issue 30): for each robot's given run, a model fitted on its own
data and exported (`dynid export`, calibrated on that data), the evaluation run played onto the robot's bus (`dynid
play --stamps nominal`, candump), replayed by `rt_monitor --replay` with every sample's T² on DYNID_RESIDUAL, and
the same samples decoded from the same log by `dynid import` and put through the core alone (`rt_eval --stream`):
T² equal to 1e-9 relative on every sample and the same contact events. (The core predicts what dynid predicts on
every bundled robot: tools/tests/test_rt_robots.py.) The UR10e's collisions are counted against the model-free
episode labels beside the run. One test per robot; each skips, with the reason, without the data.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from dynid.config.robot_config import load_config
from dynid.detect.t2 import debounced_events, episode_peaks
from dynid.export.coefficients import read_coefficients
from dynid.export.known_answers import answers
from dynid.export.monitor_log import read_lcm_log
from dynid.export.rt_eval_io import detector_columns, raw_samples, run_stream
from dynid.identify.model_file import load_model
from dynid.io.load import load_data

from . import cli, convert

REALDATA = convert.REALDATA
ROOT = Path(__file__).resolve().parents[2]
RT_MONITOR = ROOT / "build" / "rt_monitor" / "rt_monitor"
RT_EVAL = ROOT / "build" / "rt_monitor" / "rt_eval"
T0_US = 1_700_000_000_000_000  # dynid play's default first stamp
# measured 4 of 4, no onset outside them (fitted on the 14-harmonic run alone: 3 of 4); the first push is the weakest,
# its peak 1.13 times the level offline: far from rounding, near enough that a refit on other data may lose it
PUSHES_FOUND = 4

UR10E_EXCITATION = tuple(f"ur10e_mamedov/identification/ur-{name}.csv" for name in (
    "20_02_19_14harm50sec", "20_02_12-50sec_12harm", "20_02_10-30sec_12harm", "20_02_05-20sec_8harm"))

# robot: (fit run or runs, their window, evaluation run, its window, URDF, export options)
RUNS = {
    # Fitted on the swing on one foot (14-62.42 s: leg_support.put_down_onset), evaluated to 75 s: the right foot
    # takes weight from 62.42 s and is put down at about 65.6 s (the run's README); the foot's contact must show.
    "icub_right_leg_standing": ("icub_leg_insitu/dumperLeftLegNoIMU", (14, 62.42), "icub_leg_insitu/dumperLeftLegNoIMU",
                                (14, 75), "icub_leg_insitu/iCubGenova02.urdf", ()),
    # The UR10e fitted on its four unloaded excitation runs (shared/realdata/ur10e_mamedov/identification), as a lab
    # fits on the excitation data it has; on the 14-harmonic run alone the pushes give 3 of 4 (docs/detection.md)
    "ur10e_known_gains": (UR10E_EXCITATION, None, "ur10e_mamedov/contact/collision_3link.csv", None,
                          "ur10e_mamedov/ur10e.urdf", ("--residual", "momentum")),
    # The export's default detector (combined) on the same collisions
    "ur10e_known_gains/combined": (UR10E_EXCITATION, None, "ur10e_mamedov/contact/collision_3link.csv", None,
                                   "ur10e_mamedov/ur10e.urdf", ()),
    "ur10e_known_gains/push": (UR10E_EXCITATION, None, "ur10e_mamedov/contact/ur-20_01_22-push_pose_1.csv", None,
                               "ur10e_mamedov/ur10e.urdf", ("--residual", "momentum")),
    # ... and on the pushes, where the arm rests between them: every row resting, the observer's own test alone
    "ur10e_known_gains/push_combined": (UR10E_EXCITATION, None, "ur10e_mamedov/contact/ur-20_01_22-push_pose_1.csv",
                                        None, "ur10e_mamedov/ur10e.urdf", ()),
    # The Panda's and TIAGo's runs are their loggers' folders of files (the configurations' `files:`), played on the
    # window the file is calibrated on: the file's period is its median step, and
    # a window of another median drifts against it by a sample in a few thousand (the sample clock then bridges one).
    # The Panda's log misses a sample 54 times in 21 s; the monitor's filter takes one per period, so the file is
    # calibrated (export --data) on the longest stretch without one, 7.78-9.55 s.
    "panda": ("panda_gaz2019/rbt_log", None, "panda_gaz2019/rbt_log", (7.78, 9.55), None, ("--data", "EVAL")),
    "tiago_wrist": ("tiago_wrist_ft/dynamic", None, "tiago_wrist_ft/dynamic", None,
                    "tiago_wrist_ft/urdf/tiago_48_hey5.urdf", ()),
}


def run(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=900)


def _window(path: Path, span: tuple[float, float] | None) -> str:
    """RUN@FROM:TO in the run's seconds."""
    return str(path) if span is None else f"{path}@{float(span[0])!r}:{float(span[1])!r}"


def events_of(kinds: np.ndarray) -> list[tuple[int, int]]:
    return [(int(k), int(kinds[k])) for k in np.flatnonzero(kinds)]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory):
    """fitted(FIT ARGS) -> the model `dynid fit FIT ARGS` writes, fitted once for the cases that share it (the
    UR10e's four fit the same four runs alike)."""
    made: dict[tuple[str, ...], Path] = {}

    def fit(*args: object) -> Path:
        key = tuple(map(str, args))
        if key not in made:
            out = tmp_path_factory.mktemp("fit") / "model.json"
            done = cli.run("fit", *key, "--out", out)
            assert done.returncode == 0, f"dynid fit {' '.join(key)}: {done.stderr}"
            made[key] = out
        return made[key]

    return fit


@pytest.mark.parametrize("robot", sorted(RUNS))
def test_a_real_run_through_the_monitor_is_the_core_on_the_decoded_samples(robot: str, fitted,
                                                                           tmp_path: Path) -> None:
    fit_source, fit_span, eval_source, eval_span, urdf, export_options = RUNS[robot]
    robot, _, case = robot.partition("/")
    if not REALDATA.is_dir():
        pytest.skip(f"real robot data not found at {REALDATA} (clone shared/ beside the repository)")
    urdf_args = ("--urdf", REALDATA / urdf) if urdf else ()
    config = load_config(robot, REALDATA / urdf if urdf else None)
    fit_sources = fit_source if isinstance(fit_source, tuple) else (fit_source,)
    paths = {source: REALDATA / source for source in {*fit_sources, eval_source}}
    fit_data = [a for source in fit_sources for a in ("--data", _window(paths[source], fit_span))]
    eval_data = _window(paths[eval_source], eval_span)
    export_options = tuple(eval_data if o == "EVAL" else o for o in export_options)

    coef, log, conf = (tmp_path / n for n in ("model.dcoef", "run.log", "monitor.conf"))
    lcm = tmp_path / "monitor.lcmlog"
    # --consistent off: the figures were measured with the unconstrained fit (the leg's default is now on)
    model = fitted("--robot", robot, *urdf_args, *fit_data, "--bad-rows", "skip", "--consistent", "off")
    steps = [
        ("export", "--model", model, *export_options, "--out", coef),
        ("export", "--robot", robot, *urdf_args, "--monitor-config", conf, "--lcm-url", f"file://{lcm}?mode=w"),
        ("play", "--robot", robot, *urdf_args, "--data", eval_data, "--sink", f"candump:{log}", "--bad-rows", "skip",
         "--stamps", "nominal"),
    ]
    for step in steps:
        done = cli.run(*step)
        assert done.returncode == 0, f"dynid {' '.join(map(str, step))}: {done.stderr}"
    # Every evaluated sample's T² on DYNID_RESIDUAL
    conf.write_text(re.sub(r"^residual_every \d+$", "residual_every 1", conf.read_text(), flags=re.M))
    done = run(RT_MONITOR, "--model", coef, "--config", conf, "--replay", log)
    # A clean run of the robot's own model: no watchdog fault (the leg's put-down is one contact from 62.4 s to the
    # run's end, 12.6 s, over the monitor's default contact_limit_s: its configuration sets its own)
    assert done.returncode == 0 and "fault:" not in done.stderr, done.stderr
    c = read_coefficients(coef)
    imported = load_data(log, config)
    n = imported.n_samples
    assert f"samples {n}, evaluated {n}, stale 0," in done.stdout, done.stdout

    out = run_stream(RT_EVAL, coef, raw_samples(imported, c), tmp_path)
    cols = detector_columns(c)
    period_us = round(c.sample_period * 1e6)
    msgs = read_lcm_log(lcm)
    residual = {round((m.utime - T0_US) / period_us): m.t2 for m in msgs["DYNID_RESIDUAL"]}
    ready = np.flatnonzero(np.isfinite(out[:, cols["t2"]]) & (np.arange(n) >= c.window - 1))
    assert len(residual) >= len(ready) - 1 > 0.9 * n - c.window
    worst = max(abs(residual[k] - out[k, cols["t2"]]) / max(abs(out[k, cols["t2"]]), 1e-12) for k in residual)
    print(f"{robot}: {n} samples through the monitor, T² against the core on the decoded samples: worst relative "
          f"difference {worst:.1e}; {len(msgs.get('DYNID_CONTACT', []))} contact events")
    assert worst <= 1e-9
    monitor_events = [(round((m.utime - T0_US) / period_us), int(m.kind)) for m in msgs.get("DYNID_CONTACT", [])]
    assert monitor_events == events_of(out[:, cols["event"]])
    # The postures the fit saw (the file's fit_range): the samples beyond counted, each event's joints marked
    lower, upper = np.asarray(c.fit_range).T
    beyond = (imported.q < lower) | (imported.q > upper)
    assert msgs["DYNID_STATUS"][-1].beyond_fit == int(beyond.any(axis=1).sum())
    for m in msgs.get("DYNID_CONTACT", []):
        assert list(m.beyond_fit) == beyond[round((m.peak_utime - T0_US) / period_us)].astype(int).tolist()
    print(f"{robot}: {100 * beyond.any(axis=1).mean():.1f} % of the samples beyond the fit's postures, "
          f"{sum(any(m.beyond_fit) for m in msgs.get('DYNID_CONTACT', []))} events marked")
    if c.residual == 2:  # the combined statistic's level is 1: `dynid detect`'s monitor_events debounce it the same way
        evaluated = np.where(out[:, 0] > 0, out[:, cols["t2"]], np.nan)  # column 0: the core ready (it detects)
        debounced = debounced_events(evaluated, 1.0, c.debounce_on, c.debounce_off, c.hysteresis)
        assert [e for k, j in debounced for e in ((k, 1), (j, 2)) if e[0] is not None] == monitor_events
        # An end event describes its contact's strongest sample: monitor_events' peaks_s, the core's T² and sides there
        peaks = episode_peaks(evaluated, debounced)
        ends = [m for m in msgs.get("DYNID_CONTACT", []) if m.kind == 2]
        assert [round((m.peak_utime - T0_US) / period_us) for m in ends] == [p for p, (_, j) in zip(peaks, debounced)
                                                                             if j is not None]
        for m in ends:
            k = round((m.peak_utime - T0_US) / period_us)
            assert m.peak_t2 == pytest.approx(out[k, cols["t2"]], rel=1e-9) and m.peak_t2 > m.threshold
            assert list(m.side) == [int(x) for x in out[k, cols["side"]]]
    if c.residual == 2 and robot == "ur10e_known_gains":
        # The core's combined statistic is dynid's (its Python mirror, dynid.export.known_answers) on every decoded
        # sample: the UR10e has no F/T rows, so where the arm rests every row rests and s is the observer's alone.
        expected, edge = answers(load_model(model), c, imported)
        got = out[:, cols["t2"]]
        both = np.isfinite(expected[:, 0]) & np.isfinite(got) & ~edge
        assert both.sum() > 0.9 * n
        # the tolerance the monitor's own known-answer check takes (rt_monitor/src/known_answers.cpp)
        scale = np.maximum(np.abs(got[both]), np.abs(expected[both, 0]))
        assert np.all(np.abs(got[both] - expected[both, 0]) <= 1e-6 * scale + 1e-9)

    if robot == "icub_right_leg_standing":  # the right foot on the ground from 62.42 s, until the run's end
        t_run = load_data(paths[eval_source], config).t
        t_run = t_run[t_run >= eval_span[0]]
        events = [(float(t_run[round((m.utime - T0_US) / period_us)]), m) for m in msgs.get("DYNID_CONTACT", [])]
        for t, m in events:
            print(f"leg event kind {m.kind} at {t:.2f} s, T² {m.t2:.1f}: " + ", ".join(
                f"{name} side {side} |f| {np.linalg.norm(w[:3]):.1f} N" for name, side, w in zip(m.sensor, m.side,
                                                                                              m.wrench)))
        # Fitted on the swing on one foot alone (to 62.42 s, where the stance foot starts to unload for good:
        # leg_support.put_down_onset, held to it in test_realdata_out_of_sample), measured with the combined detector
        # (the export's default): the foot's contact from 62.53 s, as the right foot takes weight (the event's residual
        # force 14.2 N at the leg's sensor, 4.8 N at the foot's), and never ended (it
        # stays down to the run's end), the put-down's impact at 65.6 s inside it. The swing after the lift-off
        # (the stance foot's load settles by 17 s: docs/detection.md#out-of-sample) has no onset; the lift-off's
        # 14-17 s has four. (Fitted on 14-65 s, the foot's first 2.6 s on the ground in the fit, the onset came
        # 3.3 s late, at the impact, 65.73 s.)
        t_on, foot = events[-1]
        assert foot.kind == 1 and 62.42 <= t_on <= 62.42 + 0.5, events
        assert not [t for t, m in events if 17.0 <= t < t_on]
        sensors = dict(zip(foot.sensor, zip(foot.side, foot.wrench)))
        assert set(sensors) == {"r_leg_ft_sensor", "r_foot_ft_sensor"}
        assert np.linalg.norm(sensors["r_foot_ft_sensor"][1][:3]) >= 2.0
        # The core, sample by sample, through the foot's contact: in contact throughout; the foot's sensor, the
        # nearer, puts the contact distal of it while the foot takes weight (measured 91-100 % of each second from
        # 63 s), the leg's from the impact on (measured 100 % after 66 s; before, below its sensor's share, it
        # says proximal).
        t_eval = t_run[:n]
        side = dict(zip(c.sensor_names, out[:, cols["side"]].T))
        loaded, after = (t_eval >= 63.0), (t_eval >= 66.0)
        assert out[loaded, cols["in_contact"]].all()
        assert (side["r_foot_ft_sensor"][loaded] == 1).mean() >= 0.9
        assert (side["r_leg_ft_sensor"][after] == 1).all()

    if robot == "ur10e_known_gains":  # the collisions (pushes) against the episode labels beside the run
        episodes = np.loadtxt(paths[eval_source].with_suffix(".episodes.csv"), delimiter=",", skiprows=1, ndmin=2)
        t_raw = load_data(paths[eval_source], config, bad_rows="skip").t
        onsets = [t_raw[k] for k, kind in monitor_events if kind == 1]  # sample k: the run's k-th, at its own stamp
        # The labels widened by 0.1 s on each side, as offline (docs/detection.md): found, false onsets and the
        # per-sample false-positive rate outside them.
        found = sum(any(a - 0.1 <= t <= b + 0.1 for t in onsets) for a, b in episodes[:, :2])
        false = [t for t in onsets if not any(a - 0.1 <= t <= b + 0.1 for a, b in episodes[:, :2])]
        outside = np.ones(n, dtype=bool)
        for a, b in episodes[:, :2]:
            outside &= ~((t_raw[:n] >= a - 0.1) & (t_raw[:n] <= b + 0.1))
        evaluated = np.arange(n) >= c.window - 1
        fpr = float(out[outside & evaluated, cols["above"]].mean())
        print(f"UR10e {paths[eval_source].stem} through the monitor ({case or 'momentum'}): {found} of {len(episodes)} episodes, "
              f"{len(false)} onsets outside them, false positives {100 * fpr:.2f} % of the samples outside them")
        if case in ("push", "push_combined"):  # measured: see docs/detection.md#the-monitor
            assert len(episodes) == 4 and found >= PUSHES_FOUND and not false
        elif case == "combined":  # measured 11 of 11, 1.60 % (offline 1.77 %; fitted on 14harm50sec alone 1.75 %)
            assert len(episodes) == 11 and found == 11 and fpr <= 0.02
        else:  # measured 11 of 11, 1.00 % (offline 0.99 %): the observer on the robot's measured q̇, as offline
            assert len(episodes) == 11 and found == 11 and fpr <= 0.02


def test_the_whole_panda_log_exports_though_it_misses_samples(tmp_path: Path) -> None:
    """The Panda's log misses a sample 54 times in 21 s and eight in a row once: the export takes it as the monitor
    would (short gaps bridged, the run cut at the long one); it used to refuse the run at its first missing sample."""
    if not REALDATA.is_dir():
        pytest.skip(f"real robot data not found at {REALDATA} (clone shared/ beside the repository)")
    data = REALDATA / "panda_gaz2019" / "rbt_log"  # the logger's folder of files (panda.yaml's `files:`)
    model, coef = tmp_path / "model.json", tmp_path / "model.dcoef"
    for step in (("fit", "--robot", "panda", "--data", data, "--out", model), ("export", "--model", model, "--out", coef)):
        done = cli.run(*step)
        assert done.returncode == 0, f"dynid {' '.join(map(str, step))}: {done.stderr}"
    c = read_coefficients(coef)
    assert c.sample_period == pytest.approx(1e-3, rel=1e-3) and c.calibration_samples > 9000
    # The combined detector too, calibrated on the pieces the monitor takes (its pairing needs uniform samples): the
    # export's default. Before, it was not carried and the export fell back to the acceleration residuals.
    assert c.combined_scale > 0 and c.residual == 2


def test_a_bus_read_in_the_wrong_byte_order_is_a_start_fit_fault_within_seconds(fitted, tmp_path: Path) -> None:
    """A monitor configuration whose current signals are read in the other byte order (a lab's own bus description,
    one word wrong): every value plausible, T² above T²_α from the start. The start-fit fault comes after 4 s of the
    file's samples (400 at the UR10e's 100 Hz); counted as 4000 samples whatever the rate, it came after 40 s (a
    walkthrough's own CAN robot, its bus read in the wrong byte order: in contact from 0.3 s, the fault at 40.3 s)."""
    if not REALDATA.is_dir():
        pytest.skip(f"real robot data not found at {REALDATA} (clone shared/ beside the repository)")
    urdf = ("--urdf", REALDATA / "ur10e_mamedov" / "ur10e.urdf")
    model = fitted("--robot", "ur10e_known_gains", *urdf, *(a for r in UR10E_EXCITATION for a in ("--data", REALDATA / r)),
                   "--bad-rows", "skip", "--consistent", "off")
    coef, log, conf = (tmp_path / n for n in ("model.dcoef", "run.log", "monitor.conf"))
    data = REALDATA / "ur10e_mamedov" / "identification" / "ur-20_02_12-50sec_12harm.csv"
    for step in (("export", "--model", model, "--out", coef),
                 ("export", "--robot", "ur10e_known_gains", *urdf, "--monitor-config", conf, "--lcm-url",
                  f"file://{tmp_path / 'm.lcmlog'}?mode=w"),
                 ("play", "--robot", "ur10e_known_gains", *urdf, "--data", data, "--sink", f"candump:{log}",
                  "--stamps", "nominal")):
        done = cli.run(*step)
        assert done.returncode == 0, done.stderr
    text = conf.read_text()
    # bytes 6-7 of each frame, little-endian from bit 48: the same bytes big-endian start at their first byte's MSB, 55
    swapped = re.sub(r"^(signal \S+ )48 16 le( s \S+ \S+ current\.)", r"\g<1>55 16 be\2", text, flags=re.M)
    assert swapped.count(" 55 16 be s ") == 6, text
    conf.write_text(swapped)
    done = run(RT_MONITOR, "--model", coef, "--config", conf, "--replay", log)
    assert "fault: model does not fit at start: T² above T²_α on" in done.stderr, done.stderr
    assert round(4.0 / read_coefficients(coef).sample_period) == 400
    assert "on 400 of the first 400 samples" in done.stderr, done.stderr


def test_detect_notes_a_bus_without_the_velocity_its_events_took(tmp_path: Path) -> None:
    """The UR10e's own bus description without its dq.J signals (carried, read by nobody): the monitor then estimates
    q̇ from q, while `detect`'s monitor_events take the run's recorded velocity; detect says so (a walkthrough's bus:
    offline 11 of 11 collisions, the monitor far fewer, and nothing said)."""
    if not REALDATA.is_dir():
        pytest.skip(f"real robot data not found at {REALDATA} (clone shared/ beside the repository)")
    import yaml

    import dynid

    config = yaml.safe_load((Path(dynid.__file__).parent / "config/robots/ur10e_known_gains.yaml").read_text())
    config["name"] = "ur10e_without_velocity"
    for frame in config["bus"]["frames"]:
        for signal in frame["signals"]:
            if str(signal.get("target", "")).startswith("dq."):
                del signal["target"]
    robot = tmp_path / "ur10e.yaml"
    robot.write_text(yaml.safe_dump(config, sort_keys=False))
    urdf = ("--urdf", REALDATA / "ur10e_mamedov" / "ur10e.urdf")
    run = REALDATA / "ur10e_mamedov" / "contact" / "collision_3link.csv"
    notes = {}
    for cfg in (robot, "ur10e_known_gains"):
        model = tmp_path / "m.json"
        done = cli.run("fit", "--robot", cfg, *urdf, "--data", REALDATA / UR10E_EXCITATION[0], "--out", model)
        assert done.returncode == 0, done.stderr
        result = cli.run("detect", "--model", model, "--data", run, "--json", tmp_path / "d.json")
        assert result.returncode == 0, result.stderr
        notes[str(cfg)] = ("bus carries none: the monitor estimates q̇ from q" in result.stdout,
                           json.loads((tmp_path / "d.json").read_text())["monitor_events"].get("monitor_velocity"))
    assert notes == {str(robot): (True, "estimated"), "ur10e_known_gains": (False, None)}
