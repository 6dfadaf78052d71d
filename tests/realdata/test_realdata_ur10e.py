"""The real UR10e runs (shared/realdata/ur10e_mamedov): the controller's headerless logs read through the bundled
`ur10e` configurations, drive gains from the loaded/unloaded pair, the point-to-point validation against the
source repository's figures, and every command over every file without a traceback. The figures are in
docs/robots/ur10e.md."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from ..hostile.run import run_dynid
from . import cli, convert

UR = convert.REALDATA / "ur10e_mamedov"
pytestmark = pytest.mark.skipif(not UR.is_dir(), reason=f"no real UR10e data at {UR}")

IDENT = UR / "identification"
PAIR = (IDENT / "ur-20_02_19_14harm50sec.csv", IDENT / "ur-20_02_19_14harm50secLoad.csv")
LOAD_KG = 2.805
PTP = UR / "validation" / "ur-20_01_17-ptp_10_points.csv"
# The repository's drive gains (drvGains, Nm/A) and its validation window: samples 700..4200 of the file (1-based).
DRV_GAINS = {"shoulder_pan": 10.0, "shoulder_lift": 10.6956, "elbow": 8.4566, "wrist_1": 9.0029, "wrist_2": 9.48,
             "wrist_3": 10.1232}
FILES = sorted(p for p in UR.rglob("*.csv") if not p.name.endswith(".episodes.csv")) if UR.is_dir() else []


run, dynid = cli.run, cli.dynid


def urdf() -> tuple[str, str]:
    return "--urdf", str(convert.UR10E_URDF)


def ptp_window() -> tuple[str, str, str, str]:
    t = np.loadtxt(PTP, delimiter=",", usecols=0)
    return "--from", repr(float(t[699])), "--to", repr(float(t[4199]))


def test_the_pair_identifies_the_drive_gains(tmp_path: Path) -> None:
    """Only the load's mass is known: the gravity joints' gains are determined, the others are named as not."""
    fit = dynid("fit", "--robot", "ur10e", *urdf(), "--data", str(PAIR[0]), "--data", str(PAIR[1]), "--payload", "0",
                "--payload", str(LOAD_KG), "--out", str(tmp_path / "pair.json"))
    assert fit["estimator"] == "ols"  # IV's instruments do not carry a payload's torques (pipeline.py)
    gains = {name.split(".")[0]: v for name, v in fit["determined"].items() if name.endswith(".phi_m")}
    print("UR10e gains from the pair: " + ", ".join(f"{m} {v['value']:.2f} ± {v['standard_error']:.2f} "
                                                     f"(drvGains {DRV_GAINS[m]})" for m, v in gains.items()))
    assert set(gains) == {"shoulder_lift", "elbow"}
    for m, v in gains.items():  # measured 12.14 ± 0.43 and 9.83 ± 0.33: 13.5 % and 16.1 % above drvGains
        assert abs(v["value"] / DRV_GAINS[m] - 1) < 0.2
    assert {f"{m}.phi_m" for m in ("shoulder_pan", "wrist_3")} <= set(fit["undetermined"])
    # The monitor's Λ is calibrated on the pair's runs with the loaded run's payload as the fit had it. Without it
    # the loaded run's residuals carried the load's torques: shoulder_lift's and elbow's variance 19× and 17× those
    # of the unloaded run alone, and the monitor found 6 of the 11 collisions of collision_3link (11 with it).
    both = dynid("export", "--model", str(tmp_path / "pair.json"), "--out", str(tmp_path / "pair.dcoef"))
    alone = dynid("export", "--model", str(tmp_path / "pair.json"), "--data", str(PAIR[0]),
                  "--out", str(tmp_path / "unloaded.dcoef"))
    for m in ("shoulder_lift", "elbow"):  # measured 1.7× and 1.8×
        ratio = both["residual_variance"][f"current.{m}"] / alone["residual_variance"][f"current.{m}"]
        assert ratio < 3.0, (m, ratio)
    # The gap workflow against the pair's model on another run: its inertias held fix the scale (it was refused,
    # "the scale cannot be identified", a walkthrough); the refit stays near the model's own error there
    other = UR / "identification" / "ur-20_02_12-50sec_12harm.csv"
    gaps = dynid("gaps", "--model", str(tmp_path / "pair.json"), "--data", str(other))
    for g in gaps["gap"]:
        assert g["before_rms"] <= 1.2 * g["given_model_rms"], g


def test_four_unloaded_runs_and_one_loaded_name_the_runs_jackknife(tmp_path: Path) -> None:
    """The five identification runs stacked, one of them loaded: the gains' scale comes from the one pair alone, so
    leaving it out moves every estimate (docs/robots/ur10e.md). The refusal names that, not "a longer run"."""
    runs = sorted(p for p in IDENT.glob("*.csv") if p != PAIR[1]) + [PAIR[1]]
    assert len(runs) == 5
    data = [a for r in runs for a in ("--data", str(r))]
    payloads = [a for kg in (0, 0, 0, 0, LOAD_KG) for a in ("--payload", str(kg))]
    done = run("fit", "--robot", "ur10e", *urdf(), *data, *payloads, "--out", str(tmp_path / "five.json"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "across the runs" in done.stderr and "of the 4 units" in done.stderr and "longer run" not in done.stderr
    assert not (tmp_path / "five.json").exists()


def test_unknown_gains_without_ft_or_payload_is_one_line(tmp_path: Path) -> None:
    done = run("fit", "--robot", "ur10e", *urdf(), "--data", str(PAIR[0]), "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "the scale cannot be identified" in done.stderr and "--payload" in done.stderr
    done = run("fit", "--robot", "ur10e", "--data", str(PAIR[0]), "--out", str(tmp_path / "m.json"),
               keep_urdf_path=False)
    assert done.returncode == 2 and "--urdf PATH" in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_gravity_given_the_wrong_way_is_named_without_an_ft_sensor(tmp_path: Path) -> None:
    """The UR10e's configuration with gravity +z, as a user could write it: the currents fit as well (their torques
    are what the data fix), every body's gravity terms turned. Its fitted gravity torques run against the CAD's
    (measured slope −0.89, correlation −1.00; the right way 0.89 and 1.00), named first among the warnings."""
    import dynid

    bundled = Path(dynid.__file__).parent / "config" / "robots" / "ur10e_known_gains.yaml"
    text = bundled.read_text()
    assert "gravity: [0.0, 0.0, -9.81]" in text
    up = tmp_path / "ur10e_up.yaml"
    up.write_text(text.replace("gravity: [0.0, 0.0, -9.81]", "gravity: [0.0, 0.0, 9.81]"))
    for cfg, wrong in ((up, True), ("ur10e_known_gains", False)):
        done = run("fit", "--robot", cfg, *urdf(), "--data", PAIR[0], "--out", tmp_path / "m.json")
        assert done.returncode == 0, done.stderr
        warned = [line.strip() for line in done.stdout.splitlines() if "gravity torques run against" in line]
        assert len(warned) == wrong, done.stdout
        if wrong:
            assert "gravity's direction in the configuration right" in warned[0]
            assert done.stdout.index(warned[0]) < done.stdout.index("inertia about the centre of mass")


def test_point_to_point_validation_against_the_repositorys_figures(tmp_path: Path) -> None:
    """The repository's published parameters give 6.61 % on samples 700-4200 of ptp_10_points; dynid's model with
    the known gains and the load-dependent friction the gap workflow names gives less."""
    plain, augmented = tmp_path / "plain.json", tmp_path / "augmented.json"
    dynid("fit", "--robot", "ur10e_known_gains", *urdf(), "--data", str(PAIR[0]), "--out", str(plain))
    dynid("gaps", "--robot", "ur10e_known_gains", *urdf(), "--data", str(PAIR[0]), "--out", str(augmented))
    figures = {}
    for name, model in (("plain", plain), ("augmented", augmented)):
        window = dynid("validate", "--model", str(model), "--data", str(PTP), *ptp_window())
        whole = dynid("validate", "--model", str(model), "--data", str(PTP))
        figures[name] = (window["relative_error"]["overall"], whole["relative_error"]["overall"])
        per = ", ".join(f"{c.split('.')[1]} {100 * v['relative']:.1f} %"
                        for c, v in window["relative_error"]["channels"].items())
        print(f"UR10e ptp_10_points, {name}: {100 * figures[name][0]:.2f} % on samples 700-4200 ({per}); "
              f"{100 * figures[name][1]:.2f} % on the whole run")
    assert figures["plain"][0] < 0.07  # measured 6.45 % (the repository's parameters: 6.61 %)
    # measured 6.01 % (docs/robots/ur10e.md); 5.41 % when the load friction's column was the measured current itself
    assert figures["augmented"][0] < figures["plain"][0] - 0.002
    named = json.loads((augmented).read_text())["effects"]
    for effect in named:  # physical: load friction a fraction of the transmitted torque (it took 1.00 on wrist_3)
        if effect["kind"] == "load_friction":
            assert 0.0 < effect["parameters"]["coefficient"] < 0.3, effect


def test_every_command_over_every_file_without_a_traceback(tmp_path: Path) -> None:
    """What a user would try on each log: import, structure, fit on a window, validate, detect, gaps, export, and
    the mistakes (a window past the end, a reversed window, a bad payload). Exit 0 or 2, never a traceback."""
    model = tmp_path / "model.json"
    fit = dynid("fit", "--robot", "ur10e_known_gains", *urdf(), "--data", str(PAIR[0]), "--out", str(model),
                "--noise", "estimate")
    # The estimated noise (each channel's residual RMS on moving rows) replaces the configuration's in the model.
    noise = json.loads(model.read_text())["outputs"]["noise_std"]
    assert noise != [0.17, 0.2, 0.11, 0.03, 0.04, 0.03] and all(0.5 < r / s < 2 for r, s in
                                                               zip(fit["residual_rms"].values(), noise))
    assert len(FILES) == 8
    outcomes: list[tuple[str, int, str]] = []
    tracebacks: list[tuple[str, str]] = []
    # two at a time, a core each; each a process forked from a server that has imported dynid (tests/hostile/run.py)
    with ThreadPoolExecutor(max_workers=2) as pool:
        for path in FILES:
            t = np.loadtxt(path, delimiter=",", usecols=0)
            start, stop = repr(float(t[0] + 2)), repr(float(min(t[0] + 14, t[-1])))
            data = ("--data", str(path))
            calls = [
                ("import", "--robot", "ur10e", *urdf(), *data, "--out", str(tmp_path / f"{path.stem}.npz")),
                ("structure", "--robot", "ur10e", *urdf(), *data),
                ("fit", "--robot", "ur10e_known_gains", *urdf(), *data, "--from", start, "--to", stop, "--out",
                 str(tmp_path / f"{path.stem}.model.json")),
                ("fit", "--robot", "ur10e", *urdf(), *data, "--out", str(tmp_path / "x.json")),  # no scale: exit 2
                ("validate", "--model", str(model), *data),
                ("validate", "--model", str(model), *data, "--from", start, "--to", stop),
                ("detect", "--model", str(model), *data),
                ("gaps", "--robot", "ur10e_known_gains", *urdf(), *data, "--from", start, "--to", stop),
                ("validate", "--model", str(model), *data, "--from", repr(float(t[-1] + 1))),  # past the end
                ("validate", "--model", str(model), *data, "--from", stop, "--to", start),  # reversed
                ("validate", "--model", str(model), *data, "--payload", "heavy"),
                ("fit", "--robot", "ur10e", *urdf(), *data, *data, "--payload", "2.8", "--out",
                 str(tmp_path / "y.json")),
            ]
            finished = list(zip(calls, pool.map(lambda args: run_dynid(list(args), tmp_path, timeout=900), calls)))
            for args, done in finished:
                call = f"{' '.join(args)}"
                if "Traceback" in done.stderr:
                    tracebacks.append((call, done.stderr))
                    continue
                assert done.code in (0, 2), f"{call}: exit {done.code}\n{done.stderr}"
                if done.code == 2:
                    assert len(done.stderr.strip().splitlines()) == 1, f"{call}\n{done.stderr}"
                outcomes.append((f"{args[0]} {path.name}", done.code, done.stderr.strip()))
    # The monitor takes the UR10e (currents, no F/T sensor); the log's stamps jitter (8-16 ms), and its samples are
    # taken one per median step, as the robot's loop sends them.
    done = run("export", "--model", str(model), "--out", str(tmp_path / "ur.dcoef"))
    assert done.returncode == 0 and (tmp_path / "ur.dcoef").stat().st_size > 0, done.stderr
    assert not tracebacks, "\n".join(f"{c}\n{e}" for c, e in tracebacks)
    refused = [(o, e) for o, rc, e in outcomes if rc == 2]
    for o, e in refused:
        print(f"  exit 2: {o}: {e}")
    # The refusals a user meets: no scale, the window past the end, the reversed window, the bad payload, the count
    # of --payload, the gap workflow's minimum length (2000 samples: 20 s of these 100 Hz logs), a window in which
    # the arm holds still (push_pose_1: too few moving rows), and one run given twice.
    expected = ("the scale cannot be identified", "holds no sample", "must come after", "is not MASS",
                "--payload is given", "the gap analysis needs at least", "too few moving samples", "is named twice")
    unexpected = [(o, e) for o, e in refused if not any(x in e for x in expected)]
    assert not unexpected, unexpected
    assert sum("the scale cannot be identified" in e for _, e in refused) == len(FILES)
    assert [o for o, rc, _ in outcomes if rc == 0 and o.startswith(("validate", "detect", "import", "structure"))]
